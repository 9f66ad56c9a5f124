"""Findings of the new-user audit (docs/real-data.md): each one as the CLI shows it.

Real recordings are copied into ``tmp_path`` and broken there the way real files go wrong (a
line cut short, a missing value, a header-only table); every case must end in a clear message
naming the file, line and the flag that repairs it (exit 2, no traceback), or in a repair that
says what it did.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.cli.errors import cli_text
from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import write_session

runner = CliRunner()

IPIN_T04 = "ipin2023/IPIN2023_T3_TrainingTrial04_repetition01.txt"
OXFORD_FRONT = "oxford_step/user1_frontpocket_1506422223341.csv"


def _flat(output: str) -> str:
    return " ".join(output.split())


def _session(tmp_path: Path, *, gyro: bool = True) -> Path:
    t = np.arange(600) * 0.01
    acc = np.tile([0.0, 0.0, 9.81], (len(t), 1))
    gyr = SensorSeries(t, np.zeros((len(t), 3)), "gyr") if gyro else None
    path = tmp_path / "s"
    write_session(Session(imu=ImuStream(SensorSeries(t, acc, "acc"), gyr)), path)
    return path


def _refused(result: object, *words: str) -> str:
    output = _flat(result.output)  # type: ignore[attr-defined]
    assert result.exit_code == 2, output  # type: ignore[attr-defined]
    assert "Traceback" not in output and "internal error" not in output
    for word in words:
        assert word in output, (word, output)
    return output


# ------------------------------------------------------------------------------------------
# Output paths are checked before the work, in CLI words
# ------------------------------------------------------------------------------------------
def test_output_under_a_file_is_refused_before_any_work(tmp_path: Path) -> None:
    session = _session(tmp_path)
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    target = blocker / "sub"
    for args in (["track", str(session), "-o", str(target)],
                 ["convert", str(session), "-o", str(target)]):
        output = _refused(runner.invoke(app, args), "--output", "is a file, not a folder")
        assert "Errno" not in output and "steps" not in output
    done = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "r")])
    assert done.exit_code == 0, done.output
    _refused(runner.invoke(app, ["export", str(tmp_path / "r"), "--to", "csv", "-o",
                                 str(target / "t.csv")]), "--output")
    assert not (tmp_path / "r" / "t.csv").exists()


def test_batch_output_under_a_file_is_refused_before_any_work(tmp_path: Path) -> None:
    _session(tmp_path)
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    _refused(runner.invoke(app, ["track", str(tmp_path / "*"), "-o", str(blocker / "sub")]),
             "--output", "is a file, not a folder")


def test_output_on_a_file_system_that_cannot_be_written(tmp_path: Path) -> None:
    if not Path("/proc/self").is_dir():
        pytest.skip("needs /proc (a file system where no folder can be made)")
    session = _session(tmp_path)
    output = _refused(runner.invoke(app, ["track", str(session), "-o", "/proc/hrtls-out"]),
                      "--output /proc/hrtls-out", "cannot write in /proc")
    assert "Errno" not in output


# ------------------------------------------------------------------------------------------
# Session folders broken on the way (header only, cut last line, missing values)
# ------------------------------------------------------------------------------------------
def test_header_only_imu_table_is_named_not_an_internal_error(tmp_path: Path) -> None:
    session = _session(tmp_path)
    path = session / "imu.csv"
    path.write_text(path.read_text().splitlines()[0] + "\n")
    _refused(runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")]),
             "imu.csv line 2", "no rows after the header")


def test_header_only_gyro_file_is_named(tmp_path: Path) -> None:
    session = _session(tmp_path, gyro=False)
    (session / "gyro.csv").write_text("t,gx,gy,gz\n")
    _refused(runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")]),
             "gyro.csv line 2", "no rows after the header")


def test_cut_last_line_of_a_session_table_needs_repair(tmp_path: Path) -> None:
    session = _session(tmp_path)
    imu = session / "imu.csv"
    text = imu.read_text()
    imu.write_text(text + "6.0,0.1")  # a copy stopped mid-line
    _refused(runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")]),
             "imu.csv line 602", "last line cut short (2 of", "--repair")
    fixed = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o"), "--repair"])
    assert fixed.exit_code == 0, fixed.output
    assert "repaired: imu.csv line 602: last line cut short" in _flat(fixed.output)


@pytest.mark.parametrize("value", ["nan", ""])
def test_missing_value_in_a_session_table_names_repair_and_repair_drops_it(
        tmp_path: Path, value: str) -> None:
    session = _session(tmp_path)
    imu = session / "imu.csv"
    lines = imu.read_text().splitlines(keepends=True)
    row = lines[300].split(",")
    row[1] = value
    imu.write_text("".join([*lines[:300], ",".join(row), *lines[301:]]))
    _refused(runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")]),
             "imu.csv line 301", "--repair")
    fixed = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o"), "--repair"])
    assert fixed.exit_code == 0, fixed.output
    assert "dropped 1 row(s) with non-finite values" in _flat(fixed.output)


def test_session_without_session_json_says_what_is_missing(tmp_path: Path) -> None:
    session = _session(tmp_path)
    (session / "session.json").unlink()
    result = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    assert "no session.json: no start pose, georeference" in _flat(result.output)


def test_empty_file_says_so(tmp_path: Path) -> None:
    empty = tmp_path / "walk.csv"
    empty.write_text("")
    _refused(runner.invoke(app, ["track", str(empty), "-o", str(tmp_path / "o")]),
             "file is empty")


# ------------------------------------------------------------------------------------------
# Messages speak CLI
# ------------------------------------------------------------------------------------------
def test_reader_options_without_a_cli_flag_are_not_offered() -> None:
    unit = cli_text("median |a| = 1.01, which is gravity in g, not m/s^2; multiply by 9.80665 "
                    "(readers: accel_unit='g')")
    assert unit.endswith("multiply by 9.80665")
    wifi = cli_text("WIFI: 684 records not used (no access-point positions; pass "
                    "include_wifi=True to keep them as RSS readings)")
    assert wifi == "WIFI: 684 records not used (no access-point positions)"
    for text in ("rename it or pass sensors={'file': 'accelerometer'}",
                 "pass sensors={'file': 'accelerometer'} if the name does not say it",
                 "one file per sensor; pass sensors= to choose",
                 "pass time_unit='s'|'ms'|'us'|'ns'", "pass time_unit='ms' or 'ns'",
                 "Android assumed; pass platform='ios' for an iPhone export"):
        assert "=" not in cli_text(text), cli_text(text)


@pytest.mark.realdata
def test_info_notes_name_flags(shared_data: Path) -> None:
    mobgap = runner.invoke(app, ["info", str(shared_data / "mobgap_lab/HA/001")])
    assert mobgap.exit_code == 0, mobgap.output
    assert "(choose with --trial)" in _flat(mobgap.output) and "trial=" not in mobgap.output
    ipin = runner.invoke(app, ["info", str(shared_data / IPIN_T04)])
    assert ipin.exit_code == 0, ipin.output
    assert "WIFI: 684 records not used" in _flat(ipin.output)
    assert "include_wifi" not in ipin.output


@pytest.mark.realdata
def test_accelerometer_in_g_is_refused_without_python_options(shared_data: Path,
                                                              tmp_path: Path) -> None:
    rows = np.loadtxt(shared_data / OXFORD_FRONT, delimiter=",")
    rows[:, 1:4] /= 9.80665
    path = tmp_path / "user1_frontpocket_1.csv"
    np.savetxt(path, rows, delimiter=",", fmt=["%d", "%.8g", "%.8g", "%.8g", "%d", "%d", "%d"])
    output = _refused(runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")]),
                      "gravity in g", "multiply by 9.80665")
    assert "accel_unit" not in output


# ------------------------------------------------------------------------------------------
# Real recordings, unchanged and broken
# ------------------------------------------------------------------------------------------
@pytest.mark.realdata
def test_every_ble_rssi_track_runs_without_flags(shared_data: Path, tmp_path: Path) -> None:
    """4 of the 5 published tracks have one sub-ms backward step: sorted, with a warning."""
    path = shared_data / "ble_rssi/trk/rectangular_without_rotation_all_sensors.mbd"
    result = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    assert "repaired:" in result.output and "line(s) 613" in _flat(result.output)


@pytest.mark.realdata
@pytest.mark.parametrize(("name", "said"), [
    ("user1_hand_1506421989895.csv", "dropped 1 all-zero row(s)"),
    ("user1_neckpouch_1506422851785.csv", "dropped 2 exact duplicate row(s)")])
def test_oxford_files_run_without_flags(shared_data: Path, tmp_path: Path, name: str,
                                        said: str) -> None:
    result = runner.invoke(app, ["track", str(shared_data / "oxford_step" / name), "-o",
                                 str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    assert "repaired:" in result.output and said in _flat(result.output)


@pytest.mark.realdata
def test_oxford_cut_last_line_is_named_and_repaired(shared_data: Path, tmp_path: Path) -> None:
    text = (shared_data / OXFORD_FRONT).read_text()
    path = tmp_path / "user1_frontpocket_2.csv"
    path.write_text(text[: len(text) - 30])  # cut inside the last line
    _refused(runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")]),
             "line 19311", "last line cut short", "--repair")
    fixed = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o"), "--repair"])
    assert fixed.exit_code == 0, fixed.output
    output = _flat(fixed.output)
    assert "dropped 1 malformed line(s): line 19311" in output
    assert "reference 327" in output


@pytest.mark.realdata
def test_ble_rssi_nan_reading_is_named_and_repaired(shared_data: Path, tmp_path: Path) -> None:
    root = tmp_path / "ble_rssi"
    shutil.copytree(shared_data / "ble_rssi/cnf", root / "cnf")
    (root / "trk").mkdir()
    lines = (shared_data / "ble_rssi/trk/straight_01_all_sensors.mbd").read_text().splitlines()
    row = lines[681].split(",")
    row[3] = "nan"
    lines[681] = ",".join(row)
    path = root / "trk" / "straight_01_all_sensors.mbd"
    path.write_text("\n".join(lines) + "\n")
    _refused(runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")]),
             "line 682", "non-finite", "--repair")
    fixed = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o"), "--repair"])
    assert fixed.exit_code == 0, fixed.output
    assert "dropped 1 malformed line(s): line 682" in _flat(fixed.output)


@pytest.mark.realdata
def test_ipin_partial_line_in_the_middle_is_named_and_repaired(shared_data: Path,
                                                               tmp_path: Path) -> None:
    lines = (shared_data / IPIN_T04).read_text().splitlines(keepends=True)
    k = 22202  # an ACCE line
    assert lines[k].startswith("ACCE;")
    lines[k] = lines[k][:20] + "\n"
    path = tmp_path / "t04.txt"
    path.write_text("".join(lines))
    _refused(runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")]),
             "line 22203", "3 field(s)", "--repair")
    fixed = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o"), "--repair"])
    assert fixed.exit_code == 0, fixed.output
    output = _flat(fixed.output)
    assert "1 malformed row(s) read as missing values (line 22203" in output
    assert "ACCE: dropped 1 row(s) with non-finite values" in output


@pytest.mark.realdata
def test_mobgap_trial_without_reference_bouts_is_not_reference_zero(shared_data: Path,
                                                                     tmp_path: Path) -> None:
    result = runner.invoke(app, ["track", str(shared_data / "mobgap_lab/HA/002"), "--trial",
                                 "Test5/Trial1", "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    output = _flat(result.output)
    assert "reference none (no walking bout in the INDIP or Stereophoto reference" in output
    assert "reference 0" not in output


@pytest.mark.realdata
def test_evaluate_refuses_another_rss_track_as_truth(shared_data: Path, tmp_path: Path) -> None:
    """Both tracks start at t = 0 and overlap in time: only the readings tell them apart."""
    tracks = shared_data / "ble_rssi/trk"
    out = tmp_path / "o"
    done = runner.invoke(app, ["track", str(tracks / "straight_01_all_sensors.mbd"), "-o",
                               str(out)])
    assert done.exit_code == 0, done.output
    _refused(runner.invoke(app, ["evaluate", str(out), "--no-plots", "--truth",
                                 str(tracks / "rectangular_with_rotation_all_sensors.mbd")]),
             "not the recording that was tracked", "1365 RSS readings", "1935 over")
    same = runner.invoke(app, ["evaluate", str(out), "--no-plots", "--truth",
                               str(tracks / "straight_01_all_sensors.mbd")])
    assert same.exit_code == 0, same.output


@pytest.mark.realdata
def test_broad_trial_says_it_is_not_a_walk(shared_data: Path, tmp_path: Path) -> None:
    path = shared_data / "broad/14_undisturbed_slow_translation_with_breaks_B.hdf5"
    result = runner.invoke(app, ["track", str(path), "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    assert "not a walk: steps and positions tracked from it mean nothing" in _flat(result.output)
