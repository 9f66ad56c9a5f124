from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.io.readers import read_phyphox
from hrtls.io.readers.phyphox import classify_column
from hrtls.recordings import detect_format, read_any

from ._synth import motion, write_phyphox, zip_folder


def _check(s, m) -> None:  # type: ignore[no-untyped-def]
    assert s.imu is not None and s.imu.gyro is not None and s.imu.mag is not None
    np.testing.assert_allclose(s.imu.accel.t, m.t, atol=1e-8)
    np.testing.assert_allclose(s.imu.accel.values, m.acc, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(s.imu.gyro.values, m.gyr, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(s.imu.mag.values, m.mag, rtol=1e-8, atol=1e-8)
    assert s.pressure is not None
    np.testing.assert_allclose(s.pressure.values[:, 0], m.pressure_pa, rtol=1e-8)


@pytest.mark.parametrize("sep", [",", "\t", ";"])
def test_export_roundtrip(tmp_path: Path, sep: str) -> None:
    m = motion(200)
    folder = write_phyphox(tmp_path / "exp", m, sep=sep)
    s = read_phyphox(folder)
    _check(s, m)
    assert s.meta.time_origin_unix_s == pytest.approx(1.7e9)
    assert s.meta.source["format"] == "phyphox"
    assert detect_format(folder) == "phyphox"


def test_zip_and_units_from_names(tmp_path: Path) -> None:
    m = motion(200)
    folder = write_phyphox(tmp_path / "exp", m, gyro_unit="deg/s", mag_unit="mT")
    z = zip_folder(folder, tmp_path / "Experiment 2023.zip")
    s = read_any(z)
    _check(s, m)
    assert any("gyroscope converted from deg/s (stated)" in n for n in s.meta.notes)
    assert any("magnetometer converted from mT (stated)" in n for n in s.meta.notes)
    assert any("hPa" in n or "pressure converted" in n for n in s.meta.notes)


def test_single_raw_data_csv(tmp_path: Path) -> None:
    m = motion(100)
    folder = write_phyphox(tmp_path / "exp", m)
    raw = folder / "Accelerometer.csv"
    target = tmp_path / "Raw Data.csv"
    target.write_text(raw.read_text())
    s = read_phyphox(target)
    assert s.imu is not None and s.imu.gyro is None
    np.testing.assert_allclose(s.imu.accel.values, m.acc, rtol=1e-8)


def test_linear_acceleration_only(tmp_path: Path) -> None:
    p = tmp_path / "Raw Data.csv"
    rows = ['"Time (s)","Linear Acceleration x (m/s^2)","Linear Acceleration y (m/s^2)",'
            '"Linear Acceleration z (m/s^2)"']
    rows += [f"{i / 100},0.1,0.2,0.3" for i in range(30)]
    p.write_text("\n".join(rows) + "\n")
    with pytest.raises(FormatError, match="without g"):
        read_phyphox(p)


def test_classify_column() -> None:
    assert classify_column("Acceleration x (m/s^2)") == ("accel", "x", "m/s^2")
    assert classify_column("Gyroscope z (rad/s)") == ("gyro", "z", "rad/s")
    assert classify_column("Magnetic field y (µT)") == ("mag", "y", "µT")
    assert classify_column("Linear Acceleration x (m/s^2)") == ("linear", "x", "m/s^2")
    assert classify_column("Pressure (hPa)") == ("pressure", None, "hPa")
    assert classify_column("Time (s)") == ("time", None, "s")
    assert classify_column("Absolute acceleration (m/s^2)") is None
    assert classify_column("Illuminance (lx)") is None


def test_bad_cells(tmp_path: Path) -> None:
    m = motion(30)
    folder = write_phyphox(tmp_path / "exp", m)
    p = folder / "Gyroscope.csv"
    lines = p.read_text().splitlines()
    lines[3] = lines[3].replace(",", ",zz", 1)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=r"Gyroscope.csv line 4: Gyroscope x \(rad/s\) is"):
        read_phyphox(folder)


def test_empty_cells_need_repair(tmp_path: Path) -> None:
    m = motion(30)
    folder = write_phyphox(tmp_path / "exp", m)
    p = folder / "Accelerometer.csv"
    lines = p.read_text().splitlines()
    f = lines[5].split(",")
    f[2] = ""
    lines[5] = ",".join(f)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"Accelerometer.csv line 6: 1 row\(s\) with a non-finite"):
        read_phyphox(folder)
    with pytest.warns(RepairWarning):
        s = read_phyphox(folder, repair=True)
    assert s.imu is not None and len(s.imu.accel) == 29


def test_unknown_unit(tmp_path: Path) -> None:
    m = motion(30)
    folder = write_phyphox(tmp_path / "exp", m, gyro_unit="furlong/s")
    with pytest.raises(InputError, match="unknown gyroscope unit 'furlong/s'"):
        read_phyphox(folder)
