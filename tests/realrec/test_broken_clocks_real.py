"""Broken clocks and cut lines on a real IPIN log, through `read_any` and `hrtls track`."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.recordings import read_any

runner = CliRunner()
LOG = "ipin2023/IPIN2023_T3_TrainingTrial04_repetition01.txt"
ALL_TYPES = {"ACCE", "GYRO", "MAGN", "PRES", "AHRS", "POSI", "BLE4", "WIFI", "LIGH", "SOUN",
             "GNSS"}


@pytest.fixture(scope="module")
def log_text(shared_data: Path) -> str:
    path = shared_data / LOG
    if not path.exists():
        pytest.skip("ipin2023 recordings not available")
    return path.read_text(encoding="utf-8", errors="replace")


def shifted(text: str, types: set[str], after_s: float, by_s: float) -> str:
    """Shift the app and sensor timestamps of ``types`` records after ``after_s`` by ``by_s``."""
    out = []
    for line in text.splitlines(keepends=True):
        fields = line.split(";")
        if fields[0] in types and len(fields) > 3:
            try:
                if float(fields[1]) > after_s:
                    fields[1] = f"{float(fields[1]) + by_s:.3f}"
                    if fields[0] != "POSI":
                        fields[2] = f"{float(fields[2]) + by_s:.3f}"
            except ValueError:
                pass
        out.append(";".join(fields))
    return "".join(out)


def test_hour_jump_in_accelerometer_only_is_refused_then_repaired(log_text: str,
                                                                   tmp_path: Path) -> None:
    path = tmp_path / "acc_jump.txt"
    path.write_text(shifted(log_text, {"ACCE"}, 80.0, 3600.0), encoding="utf-8")
    with pytest.raises(InputError, match=r"ACCE sample \d+ .*clock jumps forward by 3600"):
        read_any(path)
    with pytest.warns(RepairWarning, match="shifted by -3600"):
        session = read_any(path, repair=True)
    assert session.imu is not None
    assert session.imu.accel.t[-1] - session.imu.accel.t[0] < 200.0
    result = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "--repair" in result.output and "repair=True" not in result.output


def test_hour_jump_in_every_stream_is_announced(log_text: str, tmp_path: Path) -> None:
    path = tmp_path / "all_jump.txt"
    path.write_text(shifted(log_text, ALL_TYPES, 80.0, 3600.0), encoding="utf-8")
    out = tmp_path / "out"
    result = runner.invoke(app, ["track", str(path), "-o", str(out), "-p", "handheld-phone"])
    assert result.exit_code == 0, result.output
    assert "kept as gaps" in result.output
    report = json.loads((out / "report.json").read_text())
    assert report["input"]["format"] == "ipin"
    assert any("no samples for 3600" in r for r in report["input"]["repairs"])
    assert any("PRES converted" in n for n in report["input"]["notes"])


def test_cut_last_accelerometer_line(log_text: str, tmp_path: Path) -> None:
    last_acce = [ln for ln in log_text.splitlines() if ln.startswith("ACCE")][-1]
    path = tmp_path / "cut.txt"
    path.write_text(log_text.rstrip("\n") + "\n" + last_acce[:20], encoding="utf-8")
    line = log_text.rstrip("\n").count("\n") + 2
    with pytest.raises(FormatError, match=rf"line {line}: last line cut short"):
        read_any(path)
    with pytest.warns(RepairWarning, match="dropped it"):
        session = read_any(path, repair=True)
    assert session.imu is not None and len(session.imu.accel) > 1000


def test_cut_last_line_of_an_unused_record_is_dropped_with_a_warning(log_text: str,
                                                                      tmp_path: Path) -> None:
    path = tmp_path / "cut_light.txt"
    path.write_text(log_text.rstrip("\n") + "\nLIGH;161.", encoding="utf-8")
    with pytest.warns(RepairWarning, match="last line cut short"):
        read_any(path)


def test_clean_log_reads_without_clock_warnings(log_text: str, tmp_path: Path) -> None:
    path = tmp_path / "clean.txt"
    path.write_text(log_text, encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RepairWarning)
        read_any(path)


def test_phone_log_with_a_body_worn_preset_gets_the_hint(shared_data: Path, tmp_path: Path
                                                         ) -> None:
    log = shared_data / LOG
    if not log.exists():
        pytest.skip("ipin2023 recordings not available")
    # default takes the hand-held mounting from the reader's placement: no hint needed
    out0 = tmp_path / "default"
    result = runner.invoke(app, ["track", str(log), "-o", str(out0)])
    assert result.exit_code == 0, result.output
    assert "--preset handheld-phone" not in result.output
    report = json.loads((out0 / "report.json").read_text())
    assert any(n.startswith("mounting: hand-held") for n in report["notes"])
    # a configuration that insists on the session's (unknown) mounting gets the hint
    cfg = tmp_path / "body.toml"
    cfg.write_text('[attitude]\nmounting = "session"\n')
    out = tmp_path / "body"
    result = runner.invoke(app, ["track", str(log), "-o", str(out), "--config", str(cfg)])
    assert result.exit_code == 0, result.output
    assert "--preset handheld-phone" in result.output
    report = json.loads((out / "report.json").read_text())
    assert any("hand-held phone recording" in n for n in report["notes"])
    out2 = tmp_path / "handheld"
    result = runner.invoke(app, ["track", str(log), "-o", str(out2), "-p", "handheld-phone"])
    assert result.exit_code == 0 and "--preset handheld-phone" not in result.output


def test_gap_in_every_stream_grows_the_uncertainty(log_text: str, tmp_path: Path) -> None:
    from hrtls.io.tables import read_trajectory

    path = tmp_path / "gap.txt"
    # a 60 s pause: POSI landmarks and BLE after it move with the data
    path.write_text(shifted(log_text, ALL_TYPES - {"BLE4", "WIFI"}, 100.0, 60.0),
                    encoding="utf-8")
    out = tmp_path / "out"
    res = runner.invoke(app, ["track", str(path), "-o", str(out), "-p", "handheld-phone"])
    assert res.exit_code == 0, res.output
    report = json.loads((out / "report.json").read_text())
    assert [round(g["duration_s"]) for g in report["gaps"]] == [60]
    # the log's BLE beacons re-anchor the track after the pause: left to the filter
    assert "re-anchor" in report["gaps_note"]
    assert len(read_trajectory(out / "trajectory.csv")) > 100


def test_gap_of_a_dead_reckoning_track_hand_computed() -> None:
    import numpy as np

    from hrtls.data import ImuStream, SensorSeries, Session, StepEvents, Trajectory
    from hrtls.pipeline.gap_uncertainty import widen_over_gaps
    from hrtls.pipeline.tracker import TrackResult

    t = np.concatenate([np.arange(0.0, 10.0, 0.01), 40.0 + np.arange(0.0, 10.0, 0.01)])
    session = Session(imu=ImuStream(SensorSeries(t, np.tile([0.0, 0.0, 9.81], (len(t), 1)),
                                                 "acc")))
    rows = np.array([1.0, 5.0, 9.99, 40.0, 45.0])
    tr = Trajectory.build(t=rows, xyz=np.zeros((5, 3)), cov_xy=np.tile(np.eye(2), (5, 1, 1)))
    out = widen_over_gaps(TrackResult(tr, StepEvents.empty(), None, [], {}), session)
    gap = 40.0 - 9.99
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 0, 0],
                               [1.0, 1.0, 1.0, 1.0 + (1.5 * gap) ** 2 / 4,
                                1.0 + (1.5 * gap) ** 2 / 4])
    assert out.report["gaps"][0]["duration_s"] == pytest.approx(gap)
