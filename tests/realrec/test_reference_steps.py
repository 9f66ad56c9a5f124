"""`hrtls track` prints the dataset's reference step count beside ours (mobgap, Oxford)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app

runner = CliRunner()


@pytest.mark.parametrize(("relative", "extra", "reference"), [
    ("oxford_step/user1_frontpocket_1506422223341.csv", [], 327),
    ("mobgap_lab/HA/001", ["--trial", "Test5/Trial1"], None),
])
def test_reference_steps_are_printed_and_reported(shared_data: Path, tmp_path: Path,
                                                  relative: str, extra: list[str],
                                                  reference: int | None) -> None:
    path = shared_data / relative
    if not path.exists():
        pytest.skip(f"{relative} not available")
    out = tmp_path / "out"
    res = runner.invoke(app, ["track", str(path), "-o", str(out), *extra])
    assert res.exit_code == 0, res.output
    assert "reference" in res.output and "ours" in res.output
    report = json.loads((out / "report.json").read_text())["reference_steps"]
    assert report["ours"] == len((out / "steps.csv").read_text().splitlines()) - 1
    if reference is not None:
        assert report["reference"] == reference  # 6th column: last minus first value
    else:
        assert "ours_in_reference_bouts" in report and report["reference"] > 0
