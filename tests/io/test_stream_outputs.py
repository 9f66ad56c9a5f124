"""`hrtls track` streamed in chunks writes what the whole-session run writes (to 1e-9).

The whole-session run is the path `hrtls track` takes for recordings it cannot stream:
:func:`read_session`, :meth:`Tracker.run`, :func:`finish_track`. The streamed run reads the IMU
chunk by chunk; the writers encode the long arrays piece by piece.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hrtls.io import jsonstream
from hrtls.io.geojson import LOCAL_TYPE, geojson_document, write_local_geojson
from hrtls.io.session import read_session, write_session
from hrtls.io.tables import read_steps, read_trajectory, trajectory_table, write_trajectory
from hrtls.jobs.track import (
    LOCAL_GEOJSON,
    TrackRun,
    evaluate_track,
    stream_fingerprint,
    track_recording,
    write_track_outputs,
)
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.finish import finish_track
from hrtls.sim.scenarios import run_scenario

TOL = 1e-9


def _whole(path: Path) -> TrackRun:
    cfg = preset("default")
    session = read_session(path)
    result = finish_track(Tracker(cfg).run(session), session, cfg)
    return TrackRun(result, session, len(session.imu.accel), 0.0, streamed=False)


def _outputs(run: TrackRun, out: Path) -> Path:
    write_track_outputs(run.result, run.session, out,
                        evaluation=evaluate_track(run.result, run.session))
    return out


def _close(a: Any, b: Any, where: str = "") -> None:
    """Equal JSON values, numbers to TOL (absolute, or relative for large ones)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for k in a:
            _close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=TOL, abs_tol=TOL), (where, a, b)
    else:
        assert a == b, (where, a, b)


def _same_outputs(whole: Path, streamed: Path) -> None:
    a, b = read_trajectory(whole / "trajectory.csv"), read_trajectory(streamed / "trajectory.csv")
    assert len(a) == len(b) > 100
    for name in ("t", "xyz", "heading_rad", "cov_xy", "var_heading"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=0, atol=TOL,
                                   err_msg=name)
    assert np.array_equal(a.activity, b.activity)
    sa, sb = read_steps(whole / "steps.csv"), read_steps(streamed / "steps.csv")
    assert len(sa) == len(sb) > 10
    for name in ("t_start", "t_end", "length_m", "heading_rad", "dz_m"):
        np.testing.assert_allclose(getattr(sb, name), getattr(sa, name), rtol=0, atol=TOL,
                                   err_msg=name)
    _close(json.loads((whole / LOCAL_GEOJSON).read_text()),
           json.loads((streamed / LOCAL_GEOJSON).read_text()))
    ra, rb = (json.loads((d / "report.json").read_text()) for d in (whole, streamed))
    assert rb.pop("input")["format"] == "hrtls-session"  # what track_recording read
    _close(ra, rb)


def _check_input(whole: TrackRun, streamed: TrackRun) -> None:
    assert streamed.streamed and streamed.samples == whole.samples
    assert streamed.result.report["input"]["imu"] == stream_fingerprint(whole.session.imu.accel.t)


@pytest.fixture(scope="module")
def walk(tmp_path_factory: pytest.TempPathFactory) -> Path:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = run_scenario("office_random_walk", 5, duration_s=240.0)
    root = tmp_path_factory.mktemp("walk")
    write_session(sim.session, root / "csv")
    write_session(sim.session, root / "pq.zip", table_format="parquet")
    return root


@pytest.mark.parametrize("name", ["csv", "pq.zip"])
def test_streamed_track_writes_the_whole_run_outputs(walk: Path, tmp_path: Path,
                                                     name: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = _whole(walk / name)
        streamed = track_recording(walk / name, preset("default"), chunk_rows=1000)
        _check_input(whole, streamed)
        assert whole.session.truth is not None
        _same_outputs(_outputs(whole, tmp_path / "whole"), _outputs(streamed, tmp_path / "s"))


def test_real_recording_streams_like_whole(shared_data: Path, tmp_path: Path) -> None:
    from hrtls.recordings import read_any

    path = shared_data / "oxford_step" / "user1_armband_1506423438471.csv"
    if not path.exists():
        pytest.skip(f"{path.name} not available")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = tmp_path / "session"
        write_session(read_any(path, repair=True), folder)  # one repeated timestamp
        whole = _whole(folder)
        streamed = track_recording(folder, preset("default"), chunk_rows=4000)
        _check_input(whole, streamed)
        assert whole.samples > 10_000
        _same_outputs(_outputs(whole, tmp_path / "whole"), _outputs(streamed, tmp_path / "s"))


def test_piecewise_writers_give_the_whole_text(walk: Path, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(jsonstream, "SLICE", 256)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = _whole(walk / "csv")
    traj, steps = run.result.trajectory, run.result.steps
    assert len(traj) > 4 * jsonstream.SLICE and len(steps) > jsonstream.SLICE
    doc = geojson_document(traj, steps=steps, landmarks=run.session.landmarks,
                           time_origin_unix_s=1.7e9)
    doc["type"] = LOCAL_TYPE
    target = write_local_geojson(traj, tmp_path / "t.json", steps=steps,
                                 landmarks=run.session.landmarks, time_origin_unix_s=1.7e9)
    assert target.read_text() == json.dumps(doc, allow_nan=False) + "\n"
    assert write_trajectory(traj, tmp_path / "t.csv").read_text() == trajectory_table(traj)
