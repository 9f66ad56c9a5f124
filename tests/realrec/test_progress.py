"""Progress of `hrtls track`: reading then tracking, increasing to the total; same result."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.jobs.track import track_recording
from hrtls.pipeline import preset

runner = CliRunner()


def test_progress_on_a_real_log_and_the_same_track(shared_data: Path) -> None:
    log = shared_data / "ipin2023" / "IPIN2023_T3_TrainingTrial04_repetition01.txt"
    if not log.exists():
        pytest.skip("ipin2023 recordings not available")
    calls: list[tuple[str, float, float | None]] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = preset("default")
        plain = track_recording(log, cfg)
        shown = track_recording(log, cfg, progress=lambda *c: calls.append(c))
    assert calls[0][0].startswith("reading") and calls[0][2] is None
    tracking = [c for c in calls if c[0] == "tracking"]
    done = np.array([c[1] for c in tracking])
    assert len(tracking) >= 3 and np.all(np.diff(done) >= 0)
    assert done[-1] == pytest.approx(tracking[-1][2])
    a, b = plain.result.trajectory, shown.result.trajectory
    assert len(a) == len(b) and len(plain.result.steps) == len(shown.result.steps)
    np.testing.assert_allclose(a.xyz, b.xyz, atol=1e-6)


def test_streamed_session_reports_rows(tmp_path: Path) -> None:
    from hrtls.sim.scenarios import run_scenario, write_result

    folder = write_result(run_scenario("inderst_multifloor", 5), tmp_path / "s")
    calls: list[tuple[str, float, float | None]] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = track_recording(folder, preset("default"), chunk_rows=20000,
                              progress=lambda *c: calls.append(c))
    assert run.streamed
    rows = [c for c in calls if c[0] == "reading and tracking"]
    assert len(rows) >= 2 and rows[-1][1] == rows[-1][2] == run.samples
    res = runner.invoke(app, ["track", str(folder), "-o", str(tmp_path / "o"), "--progress"])
    assert res.exit_code == 0, res.output
