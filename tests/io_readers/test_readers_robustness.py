"""Malformed input: every reader either returns a session or raises a clean InputError."""

from __future__ import annotations

import contextlib
import tempfile
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.data import Session
from hrtls.errors import FormatError, InputError
from hrtls.io.readers import read_android, read_ipin, read_phyphox, read_sensorlogger
from hrtls.recordings import FORMATS, detect_format, read_any

from ._synth import (
    motion,
    write_android,
    write_beacons,
    write_ipin,
    write_phyphox,
    write_sensorlogger,
    zip_folder,
)

M = motion(60)

# text that looks like data: numbers, separators, record types, junk
_tokens = st.sampled_from(["ACCE", "GYRO", "POSI", "BLE4", "AHRS", "PRES", "WIFI", ";", ",",
                           " ", "\t", "nan", "inf", "-", "1e309", "0", "12.5", "-3", "%", '"',
                           "iBeacon", "BE:AC:20:23:00:01", "\x00", "é", "\ufeff", "1,5",
                           "99999999999999999999", ".", "e", "time"])
garbage = st.one_of(st.text(max_size=60), st.lists(_tokens, max_size=14).map("".join))


def _mutate(path: Path, index: int, new: str, mode: str) -> None:
    lines = path.read_text(encoding="utf-8").splitlines()
    i = index % max(len(lines), 1)
    if mode == "replace" and lines:
        lines[i] = new
    elif mode == "insert":
        lines.insert(i, new)
    else:
        lines = lines[:i]
    path.write_bytes(("\n".join(lines) + "\n").encode("utf-8", errors="surrogatepass"))


def _attempt(read: Callable[[], Session]) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            s = read()
        except InputError as exc:
            text = str(exc)
            assert text and "\n" not in text.strip()
            return
    assert isinstance(s, Session)
    if s.imu is not None:
        assert np.all(np.isfinite(s.imu.accel.values))
        assert np.all(np.diff(s.imu.accel.t) > 0)


_settings = settings(max_examples=60, deadline=None,
                     suppress_health_check=[HealthCheck.too_slow])
_mode = st.sampled_from(["replace", "insert", "truncate"])


@_settings
@given(index=st.integers(0, 10_000), new=garbage, mode=_mode, repair=st.booleans(),
       beacons=st.booleans())
def test_ipin_malformed(index: int, new: str, mode: str, repair: bool, beacons: bool) -> None:
    with tempfile.TemporaryDirectory() as d:
        path = write_ipin(Path(d) / "log.txt", M)
        csv_path = write_beacons(Path(d) / "BLE_Locations.csv")
        _mutate(csv_path if beacons else path, index, new, mode)
        _attempt(lambda: read_ipin(path, repair=repair))


@_settings
@given(index=st.integers(0, 10_000), new=garbage, mode=_mode, repair=st.booleans(),
       target=st.sampled_from(["accelerometer.txt", "gyroscope.txt", "orientation.txt"]))
def test_android_malformed(index: int, new: str, mode: str, repair: bool, target: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = write_android(Path(d) / "rec", M, unit="ms", t0=0.0)
        _mutate(folder / target, index, new, mode)
        _attempt(lambda: read_android(folder, repair=repair))


@_settings
@given(index=st.integers(0, 10_000), new=garbage, mode=_mode, repair=st.booleans(),
       target=st.sampled_from(["TotalAcceleration.csv", "Orientation.csv", "Metadata.csv",
                               "Barometer.csv"]))
def test_sensorlogger_malformed(index: int, new: str, mode: str, repair: bool,
                                target: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = write_sensorlogger(Path(d) / "rec", M)
        _mutate(folder / target, index, new, mode)
        _attempt(lambda: read_sensorlogger(folder, repair=repair))


@_settings
@given(index=st.integers(0, 10_000), new=garbage, mode=_mode, repair=st.booleans(),
       target=st.sampled_from(["Accelerometer.csv", "Gyroscope.csv", "meta/time.csv"]))
def test_phyphox_malformed(index: int, new: str, mode: str, repair: bool, target: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        folder = write_phyphox(Path(d) / "exp", M)
        _mutate(folder / target, index, new, mode)
        _attempt(lambda: read_phyphox(folder, repair=repair))


@settings(max_examples=60, deadline=None)
@given(data=st.binary(max_size=400), name=st.sampled_from(
    ["log.txt", "acc.txt", "Raw Data.csv", "TotalAcceleration.csv", "x.bin"]))
def test_random_bytes_any_format(data: bytes, name: str) -> None:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / name
        p.write_bytes(data)
        for fmt in FORMATS:
            _attempt(lambda fmt=fmt: read_any(p, fmt=fmt))
        with contextlib.suppress(InputError):
            detect_format(p)


# ------------------------------------------------------------------------------------------
# zip safety
# ------------------------------------------------------------------------------------------


def _zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


@pytest.mark.parametrize("member", ["../evil.txt", "/abs/acc.txt", "a/../../b.txt",
                                    "C:/x/acc.txt", "dir\\acc.txt"])
def test_zip_unsafe_members(tmp_path: Path, member: str) -> None:
    z = _zip(tmp_path / "bad.zip", {member: b"0 0 0 9.8\n"})
    with pytest.raises(FormatError, match="points outside the archive"):
        read_android(z)


def test_zip_size_limit(tmp_path: Path) -> None:
    folder = write_sensorlogger(tmp_path / "rec", M)
    z = zip_folder(folder, tmp_path / "rec.zip")
    with pytest.raises(FormatError, match="bytes uncompressed"):
        read_sensorlogger(z, max_bytes=1000)
    with pytest.raises(FormatError, match="at most 1000 bytes"):
        read_sensorlogger(folder, max_bytes=1000)
    with pytest.raises(InputError, match="max_bytes"):
        read_sensorlogger(folder, max_bytes=0)


def test_corrupt_zip(tmp_path: Path) -> None:
    z = _zip(tmp_path / "ok.zip", {"acc.txt": b"0 0 0 9.8\n" * 100})
    data = bytearray(z.read_bytes())
    data[40:60] = b"\xff" * 20  # inside the compressed stream of the member
    bad = tmp_path / "bad.zip"
    bad.write_bytes(bytes(data))
    with pytest.raises(InputError):
        read_android(bad)


def test_detect_unknown_and_ambiguous(tmp_path: Path) -> None:
    (tmp_path / "readme.md").write_text("nothing")
    with pytest.raises(FormatError, match="not recognized"):
        detect_format(tmp_path)
    write_ipin(tmp_path / "log.txt", M)
    write_phyphox(tmp_path / "exp", M)
    with pytest.raises(FormatError, match="several formats"):
        detect_format(tmp_path)
    with pytest.raises(InputError, match="no such file"):
        detect_format(tmp_path / "missing")
    with pytest.raises(InputError, match="unknown format"):
        read_any(tmp_path / "log.txt", fmt="excel")


def test_detect_each_format(tmp_path: Path) -> None:
    assert detect_format(write_ipin(tmp_path / "log.txt", M)) == "ipin"
    assert detect_format(write_android(tmp_path / "and", M, unit="ms", t0=0.0)) == "android"
    assert detect_format(write_sensorlogger(tmp_path / "sl", M)) == "sensorlogger"
    assert detect_format(write_phyphox(tmp_path / "ph", M)) == "phyphox"


def test_hrtls_session_through_read_any(tmp_path: Path) -> None:
    from hrtls.io.session import write_session

    s = read_sensorlogger(write_sensorlogger(tmp_path / "sl", M))
    out = write_session(s, tmp_path / "session")
    assert detect_format(out) == "hrtls-session"
    back = read_any(out)
    assert back.imu is not None and s.imu is not None
    np.testing.assert_allclose(back.imu.accel.values, s.imu.accel.values, rtol=1e-8)
    assert back.orientation is not None and s.orientation is not None
    np.testing.assert_allclose(back.orientation.q, s.orientation.q, atol=1e-8)
    assert back.meta.notes == s.meta.notes
    zipped = write_session(s, tmp_path / "session.zip")
    assert detect_format(zipped) == "hrtls-session"
