"""`hrtls info` and `hrtls convert` on every format, and clean failures on bad input."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import read_session, write_session

runner = CliRunner()

REAL = [
    ("ipin2023/IPIN2023_T3_TrainingTrial04_repetition01.txt", "ipin"),
    ("ipin2023/IPIN2023_T3_TrainingTrial23_repetition03.txt", "ipin"),
    ("mobgap_lab/HA/001", "mobgap"),
    ("mobgap_lab/MS/001/data.mat", "mobgap"),
    ("oxford_step/user1_frontpocket_1506422223341.csv", "oxford-step"),
    ("oxford_step/user1_armband_1506423438471.csv", "oxford-step"),
    ("broad/30_disturbed_stationary_magnet_C.hdf5", "broad"),
    ("ble_rssi/trk/rectangular_with_rotation_all_sensors.mbd", "ble-rssi"),
]


def small_session(tmp_path):
    t = np.arange(300) * 0.01
    acc = np.tile([0.0, 0.0, 9.81], (300, 1))
    path = tmp_path / "s"
    write_session(Session(imu=ImuStream(SensorSeries(t, acc, "acc"))), path)
    return path


@pytest.mark.realdata
@pytest.mark.parametrize(("relative", "fmt"), REAL)
def test_info_and_convert_real_files(shared_data, tmp_path, relative, fmt):
    path = shared_data / relative
    info = runner.invoke(app, ["info", str(path)])
    assert info.exit_code == 0, info.output
    assert f"format {fmt}" in " ".join(info.output.split())
    out = tmp_path / "converted"
    conv = runner.invoke(app, ["convert", str(path), "-o", str(out), "--repair"])
    assert conv.exit_code == 0, conv.output
    session = read_session(out)
    assert session.imu is not None or session.rss is not None


@pytest.mark.realdata
def test_convert_without_repair_names_the_defect(shared_data, tmp_path):
    path = shared_data / "oxford_step/user1_armband_1506423438471.csv"
    result = runner.invoke(app, ["convert", str(path), "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output  # an exact copy of a row: dropped, warned
    assert "repaired:" in result.output and "line(s) 13345" in " ".join(result.output.split())
    lines = path.read_text().splitlines(keepends=True)
    row = lines[13343].split(",")
    row[1] = str(float(row[1]) + 0.5)  # the same time with other values: needs --repair
    bad = tmp_path / path.name
    bad.write_text("".join([*lines[:13344], ",".join(row), *lines[13344:]]))
    result = runner.invoke(app, ["convert", str(bad), "-o", str(tmp_path / "o2")])
    assert result.exit_code == 2
    assert "line 13345" in " ".join(result.output.split()) and "--repair" in result.output
    assert "Traceback" not in result.output


def test_info_on_session_folder(tmp_path):
    result = runner.invoke(app, ["info", str(small_session(tmp_path))])
    assert result.exit_code == 0, result.output
    assert "hrtls-session" in result.output and "accelerometer" in result.output


def test_missing_path_is_one_clean_line(tmp_path):
    result = runner.invoke(app, ["info", str(tmp_path / "nope")])
    assert result.exit_code == 2
    assert "no such file or folder" in result.output
    assert "Traceback" not in result.output


def test_malformed_session_names_file_and_line(tmp_path):
    path = small_session(tmp_path)
    text = (path / "imu.csv").read_text().splitlines()
    text[5] = "0.04,0,zz,9.81"
    (path / "imu.csv").write_text("\n".join(text) + "\n")
    result = runner.invoke(app, ["convert", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    flat = " ".join(result.output.split())
    assert "imu.csv line 6" in flat and "expected a number" in flat
    assert "Traceback" not in result.output


def test_unknown_format_is_reported(tmp_path):
    junk = tmp_path / "notes.bin"
    junk.write_bytes(b"\x00\x01 nothing here")
    result = runner.invoke(app, ["info", str(junk)])
    assert result.exit_code == 2
    assert "format not recognized" in result.output


def test_g_units_caught_on_convert(tmp_path):
    path = small_session(tmp_path)
    text = (path / "imu.csv").read_text().replace("9.81", "1.0")
    (path / "imu.csv").write_text(text)
    result = runner.invoke(app, ["convert", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert "multiply by 9.80665" in " ".join(result.output.split())
    info = runner.invoke(app, ["info", str(path)])
    assert info.exit_code == 0 and "unit problem" in info.output
