from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import FormatError, InputError, RepairWarning, UnitError
from hrtls.frames import GRAVITY_M_S2, quat_angle_between
from hrtls.io.readers import read_android
from hrtls.io.readers.android import sensor_from_name
from hrtls.recordings import read_any

from ._synth import motion, write_android, zip_folder


@pytest.mark.parametrize("unit", ["ns", "ms"])
def test_roundtrip_ms_and_ns(tmp_path: Path, unit: str) -> None:
    m = motion(300, rate_hz=100.0)
    folder = write_android(tmp_path / "rec", m, unit=unit, t0=1.2e13 if unit == "ns" else 5e4)
    s = read_android(folder)
    assert s.imu is not None and s.imu.gyro is not None and s.imu.mag is not None
    np.testing.assert_allclose(s.imu.accel.t, m.t, atol=1e-6)
    np.testing.assert_allclose(s.imu.accel.values, m.acc, atol=1e-5)
    np.testing.assert_allclose(s.imu.gyro.values, m.gyr, atol=1e-5)
    np.testing.assert_allclose(s.imu.mag.values, m.mag, atol=1e-5)
    assert s.meta.source["time_unit"] == unit
    assert s.meta.source["format"] == "android"
    assert any(f"timestamps in {unit}" in n for n in s.meta.notes)


def test_orientation_documented_reading(tmp_path: Path) -> None:
    m = motion(300)
    s = read_android(write_android(tmp_path / "rec", m, unit="ms", t0=0.0))
    assert s.orientation is not None
    assert np.max(quat_angle_between(s.orientation.q, m.q_nd)) < 1e-4
    assert any("pitch -1, roll -1" in n and "agrees" in n for n in s.meta.notes)


def test_orientation_other_sign_is_detected(tmp_path: Path) -> None:
    m = motion(300)
    folder = write_android(tmp_path / "rec", m, unit="ms", t0=0.0)
    # flip the sign of pitch in the file: the reader must notice and take the other variant
    lines = (folder / "orientation.txt").read_text().splitlines()
    flipped = []
    for ln in lines:
        t, a, p, r = ln.split()
        flipped.append(f"{t} {a} {-float(p):.6f} {r}")
    (folder / "orientation.txt").write_text("\n".join(flipped) + "\n")
    s = read_android(folder)
    assert s.orientation is not None
    assert np.max(quat_angle_between(s.orientation.q, m.q_nd)) < 1e-4
    assert any("disagrees with the recording" in n for n in s.meta.notes)


def test_header_zip_and_single_file(tmp_path: Path) -> None:
    m = motion(200, rate_hz=100.0)
    folder = write_android(tmp_path / "rec", m, unit="ns", header=True, orientation=False)
    z = zip_folder(folder, tmp_path / "rec.zip", prefix="phone/")
    s = read_android(z)
    assert s.imu is not None and len(s.imu.accel) == 200
    one = read_android(folder / "accelerometer.txt")
    assert one.imu is not None and one.imu.gyro is None
    assert read_any(folder).meta.source["format"] == "android"


def test_accel_in_g_converted(tmp_path: Path) -> None:
    m = motion(200, rate_hz=100.0)
    folder = write_android(tmp_path / "rec", m, unit="ms", t0=0.0, orientation=False)
    text = (folder / "accelerometer.txt").read_text().splitlines()
    scaled = []
    for ln in text:
        f = ln.split()
        scaled.append(" ".join([f[0], *(f"{float(v) / GRAVITY_M_S2:.8f}" for v in f[1:])]))
    (folder / "accelerometer.txt").write_text("\n".join(scaled) + "\n")
    s = read_android(folder)
    assert s.imu is not None
    np.testing.assert_allclose(s.imu.accel.values, m.acc, atol=1e-5)
    assert any("converted from g" in n for n in s.meta.notes)
    with pytest.raises(UnitError):
        read_android(folder, accel_unit="m/s^2")


def test_file_names() -> None:
    assert sensor_from_name("accelerometer.txt") == "accelerometer"
    assert sensor_from_name("AccData_01.txt") == "accelerometer"
    assert sensor_from_name("TYPE_GYROSCOPE.txt") == "gyroscope"
    assert sensor_from_name("MagneticField.txt") == "magnetometer"
    assert sensor_from_name("mag.txt") == "magnetometer"
    assert sensor_from_name("Orientation_2016.txt") == "orientation"
    assert sensor_from_name("image.txt") is None
    assert sensor_from_name("data.txt") is None
    with pytest.raises(FormatError, match="several sensors"):
        sensor_from_name("acc_gyro.txt")
    with pytest.raises(FormatError, match="linear acceleration"):
        sensor_from_name("linear_acceleration.txt")


def test_unknown_file_is_refused_clearly(tmp_path: Path) -> None:
    p = tmp_path / "data.txt"
    p.write_text("1000 0 0 9.8\n1010 0 0 9.8\n1020 0 0 9.8\n")
    with pytest.raises(FormatError, match="cannot tell which sensor"):
        read_android(p)
    s = read_android(p, sensors={"data.txt": "accelerometer"})
    assert s.imu is not None and len(s.imu.accel) == 3
    with pytest.raises(InputError, match="unknown sensor"):
        read_android(p, sensors={"data.txt": "thermometer"})


def test_folder_without_accelerometer(tmp_path: Path) -> None:
    (tmp_path / "gyro.txt").write_text("0 0 0 0\n10 0 0 0\n")
    (tmp_path / "notes.md").write_text("hello")
    with pytest.raises(FormatError, match="no accelerometer file"):
        read_android(tmp_path)


@pytest.mark.parametrize(("line", "message"), [
    ("12 1.0 2.0", r"3 field\(s\)"),
    ("12 1.0 2.0 abc", "Z is 'abc'"),
    ("12 1.0 2.0 3.0 4.0", r"5 field\(s\)"),
])
def test_bad_lines(tmp_path: Path, line: str, message: str) -> None:
    p = tmp_path / "acc.txt"
    p.write_text("0 0 0 9.8\n10 0 0 9.8\n" + line + "\n30 0 0 9.8\n")
    with pytest.raises(FormatError, match=message) as exc:
        read_android(p)
    assert "line 3" in str(exc.value)


def test_time_errors_and_repair(tmp_path: Path) -> None:
    p = tmp_path / "acc.txt"
    p.write_text("0 0 0 9.8\n10 0 0 9.8\n10 0 0 9.7\n5 0 0 9.8\n30 0 0 9.8\n")
    with pytest.raises(InputError, match="line 3: time repeats"):
        read_android(p, time_unit="ms")
    with pytest.warns(RepairWarning):
        s = read_android(p, time_unit="ms", repair=True)
    assert s.imu is not None
    np.testing.assert_allclose(s.imu.accel.t, [0.0, 0.005, 0.010, 0.030])
    with pytest.raises(InputError, match="unknown time unit"):
        read_android(p, time_unit="fortnights")


def test_time_unit_disagreement(tmp_path: Path) -> None:
    (tmp_path / "acc.txt").write_text("\n".join(f"{i * 10} 0 0 9.8" for i in range(5)))
    (tmp_path / "gyr.txt").write_text("\n".join(f"{i * 10_000_000} 0 0 0" for i in range(5)))
    with pytest.raises(FormatError, match="disagree on the time unit"):
        read_android(tmp_path)


@settings(max_examples=40, deadline=None)
@given(rate_hz=st.floats(5.0, 1000.0), unit=st.sampled_from(["ms", "ns", "s"]),
       t0=st.floats(0.0, 1e6), jitter=st.floats(0.0, 0.2), seed=st.integers(0, 1000))
def test_time_unit_is_recovered(rate_hz: float, unit: str, t0: float, jitter: float,
                                seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 50
    dt = 1.0 / rate_hz
    t = np.cumsum(np.full(n, dt) * (1.0 + jitter * (rng.random(n) - 0.5)))
    scale = {"s": 1.0, "ms": 1e3, "ns": 1e9}[unit]
    stamps = (t0 + t) * scale
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "acc.txt"
        p.write_text("\n".join(f"{s:.17g} 0.1 0.2 9.8" for s in stamps) + "\n")
        s = read_android(p)
    assert s.meta.source["time_unit"] == unit
    assert s.imu is not None
    np.testing.assert_allclose(s.imu.accel.t, t - t[0], atol=1e-6 + 1e-9 * stamps[-1] / scale)
