"""`hrtls evaluate` writes evaluation.json beside the result; wrong truth is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.data import GroundTruth, Trajectory
from hrtls.errors import InputError
from hrtls.jobs.evaluate import TruthData, check_overlap

runner = CliRunner()
T04 = "ipin2023/IPIN2023_T3_TrainingTrial04_repetition01.txt"
T23 = "ipin2023/IPIN2023_T3_TrainingTrial23_repetition03.txt"


def _truth(t: np.ndarray) -> TruthData:
    xyz = np.zeros((len(t), 3))
    return TruthData(GroundTruth(t, xyz), None, None, None, {}, 3.0, "truth", None, None)


def test_overlap_hand_computed() -> None:
    estimate = Trajectory.build(t=np.arange(0.0, 100.0), xyz=np.zeros((100, 3)))
    check_overlap(estimate, _truth(np.arange(40.0, 140.0)), result_label="r")  # 59 of 99 s
    with pytest.raises(InputError, match=r"truth spans 60\.000 \.\. 159\.000 s but the result "
                                         r"0\.000 \.\. 99\.000 s"):
        check_overlap(estimate, _truth(np.arange(60.0, 160.0)), result_label="r")  # 39 of 99
    with pytest.raises(InputError, match=r"truth spans 3600\.000"):
        check_overlap(estimate, _truth(np.arange(3600.0, 3700.0)), result_label="r")


@pytest.fixture(scope="module")
def tracked(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    log = shared_data / T04
    if not log.exists():
        pytest.skip("ipin2023 recordings not available")
    out = tmp_path_factory.mktemp("eval") / "t04"
    result = runner.invoke(app, ["track", str(log), "-o", str(out), "-p", "handheld-phone"])
    assert result.exit_code == 0, result.output
    return out


def test_evaluate_writes_evaluation_json_and_keeps_the_track_files(shared_data: Path,
                                                                   tracked: Path) -> None:
    before = {p.name: p.read_bytes() for p in tracked.iterdir()}
    result = runner.invoke(app, ["evaluate", str(tracked), "--truth", str(shared_data / T04)])
    assert result.exit_code == 0, result.output
    for name, data in before.items():
        assert (tracked / name).read_bytes() == data, name
    evaluation = json.loads((tracked / "evaluation.json").read_text())
    assert evaluation["checkpoints"]["mean"] < 10.0
    assert evaluation["floors"]["checkpoints_correct"] == 1.0
    assert evaluation["truth"]["source"].endswith(T04.split("/")[1])


def test_evaluate_refuses_the_truth_of_another_recording(shared_data: Path,
                                                         tracked: Path) -> None:
    result = runner.invoke(app, ["evaluate", str(tracked), "--truth", str(shared_data / T23)])
    assert result.exit_code == 2
    assert "not the recording that was tracked" in result.output
