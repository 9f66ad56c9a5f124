from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.frames import quat_angle_between
from hrtls.io.readers import read_sensorlogger
from hrtls.recordings import detect_format, read_any

from ._synth import motion, write_sensorlogger, zip_folder


def _check(s, m, *, atol: float = 1e-5) -> None:  # type: ignore[no-untyped-def]
    assert s.imu is not None and s.imu.gyro is not None and s.imu.mag is not None
    np.testing.assert_allclose(s.imu.accel.t, m.t, atol=1e-6)
    np.testing.assert_allclose(s.imu.accel.values, m.acc, atol=atol)
    np.testing.assert_allclose(s.imu.gyro.values, m.gyr, atol=1e-6)
    np.testing.assert_allclose(s.imu.mag.values, m.mag, atol=1e-6)
    assert s.pressure is not None
    np.testing.assert_allclose(s.pressure.values[:, 0], m.pressure_pa, rtol=1e-8)
    assert s.orientation is not None
    assert np.max(quat_angle_between(s.orientation.q, m.q_nd)) < 1e-6
    assert s.meta.time_origin_unix_s == pytest.approx(1.7e9)


def test_android_folder_and_zip(tmp_path: Path) -> None:
    m = motion(300)
    folder = write_sensorlogger(tmp_path / "rec", m)
    s = read_sensorlogger(folder)
    _check(s, m)
    assert any("TotalAcceleration.csv" in n for n in s.meta.notes)
    assert any("'enu: device->ENU'" in n and "agrees" in n for n in s.meta.notes)
    assert s.meta.source["platform"] == "android"
    assert "device id" not in s.meta.source["metadata"]
    z = zip_folder(folder, tmp_path / "rec.zip", prefix="2023-11-14_22-13-20/")
    _check(read_sensorlogger(z), m)
    assert detect_format(z) == "sensorlogger"
    assert detect_format(folder) == "sensorlogger"


def test_ios_accelerometer_plus_gravity_negated(tmp_path: Path) -> None:
    m = motion(300)
    folder = write_sensorlogger(tmp_path / "rec", m, platform="ios", total=False)
    s = read_sensorlogger(folder)
    _check(s, m)
    assert any("Accelerometer.csv + Gravity.csv" in n for n in s.meta.notes)
    assert any("negated" in n for n in s.meta.notes)
    assert any("'nwu: device->NWU'" in n and "agrees" in n for n in s.meta.notes)


def test_ios_standardised_not_negated(tmp_path: Path) -> None:
    m = motion(300)
    folder = write_sensorlogger(tmp_path / "rec", m, platform="ios", standardisation=True,
                                total=False)
    s = read_sensorlogger(folder)
    _check(s, m)
    assert not any("negated" in n for n in s.meta.notes)


def test_acceleration_in_g(tmp_path: Path) -> None:
    m = motion(300)
    folder = write_sensorlogger(tmp_path / "rec", m, platform="ios", total=False,
                                accel_in_g=True)
    s = read_sensorlogger(folder)
    _check(s, m)
    assert any("converted from g" in n for n in s.meta.notes)


def test_orientation_frame_chosen_from_data(tmp_path: Path) -> None:
    m = motion(300)
    # an Android export whose quaternions are in north-west-up: the reader must notice
    folder = write_sensorlogger(tmp_path / "rec", m, frame="nwu")
    s = read_sensorlogger(folder)
    assert s.orientation is not None
    assert np.max(quat_angle_between(s.orientation.q, m.q_nd)) < 1e-6
    assert any("disagrees with the recording" in n and "'nwu: device->NWU'" in n
               for n in s.meta.notes)
    forced = read_sensorlogger(folder, orientation="enu")
    assert forced.orientation is not None
    assert np.max(quat_angle_between(forced.orientation.q, m.q_nd)) > 0.5
    assert any("NOT confirmed" in n for n in forced.meta.notes)
    assert read_sensorlogger(folder, orientation="none").orientation is None
    with pytest.raises(InputError, match="orientation"):
        read_sensorlogger(folder, orientation="sideways")


def test_without_metadata(tmp_path: Path) -> None:
    m = motion(200)
    folder = write_sensorlogger(tmp_path / "rec", m, metadata=False)
    s = read_sensorlogger(folder)
    _check(s, m)
    assert any("TotalAcceleration.csv present" in n for n in s.meta.notes)


def test_linear_only_is_refused(tmp_path: Path) -> None:
    m = motion(200)
    folder = write_sensorlogger(tmp_path / "rec", m, total=False)
    (folder / "Gravity.csv").unlink()
    with pytest.raises(FormatError, match="without gravity"):
        read_sensorlogger(folder)


def test_errors_name_file_and_line(tmp_path: Path) -> None:
    m = motion(50)
    folder = write_sensorlogger(tmp_path / "rec", m)
    p = folder / "Gyroscope.csv"
    lines = p.read_text().splitlines()
    lines[4] = lines[4].rsplit(",", 1)[0] + ",oops"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"Gyroscope.csv line 5: x is 'oops'"):
        read_sensorlogger(folder)
    lines[4] = lines[3]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"Gyroscope.csv line 5: time repeats"):
        read_sensorlogger(folder)
    with pytest.warns(RepairWarning):
        s = read_sensorlogger(folder, repair=True)
    assert s.imu is not None and s.imu.gyro is not None and len(s.imu.gyro) == 49


def test_missing_columns(tmp_path: Path) -> None:
    m = motion(50)
    folder = write_sensorlogger(tmp_path / "rec", m)
    (folder / "Magnetometer.csv").write_text("time,seconds_elapsed,z,y\n1,0,1,2\n")
    with pytest.raises(FormatError, match=r"Magnetometer.csv line 1: missing column\(s\) x"):
        read_sensorlogger(folder)


def test_two_recordings_in_one_zip(tmp_path: Path) -> None:
    m = motion(50)
    a = write_sensorlogger(tmp_path / "all" / "a", m)
    write_sensorlogger(tmp_path / "all" / "b", m)
    del a
    z = zip_folder(tmp_path / "all", tmp_path / "two.zip")
    with pytest.raises(FormatError, match="files named"):
        read_sensorlogger(z)


def test_read_any_options(tmp_path: Path) -> None:
    m = motion(100)
    folder = write_sensorlogger(tmp_path / "rec", m)
    s = read_any(folder, platform="android")
    assert s.meta.source["format"] == "sensorlogger"
    with pytest.raises(InputError, match="unknown option"):
        read_any(folder, time_unit="ms")
    with pytest.raises(InputError, match="beacons"):
        read_any(folder, beacons=tmp_path / "b.csv")
