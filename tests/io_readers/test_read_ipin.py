from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.frames import Georeference, quat_angle_between
from hrtls.io.readers import ipin_beacon_id, read_beacons_csv, read_ipin
from hrtls.recordings import read_any

from ._synth import LAT0, LON0, motion, write_beacons, write_ipin, zip_folder

IPIN_FILES = ("IPIN2023_T3_TrainingTrial04_repetition01.txt",
              "IPIN2023_T3_TrainingTrial23_repetition03.txt")


@pytest.fixture
def log(tmp_path: Path) -> tuple[Path, object]:
    m = motion(400)
    (tmp_path / "log").mkdir()
    path = write_ipin(tmp_path / "log" / "trial.txt", m)
    write_beacons(tmp_path / "log" / "BLE_Locations.csv")
    return path, m


def test_streams_times_and_units(log: tuple[Path, object]) -> None:
    path, m = log
    s = read_ipin(path)
    assert s.imu is not None and s.imu.gyro is not None and s.imu.mag is not None
    # sensor time + median(app - sensor) = true time + 3 ms delivery delay
    np.testing.assert_allclose(s.imu.accel.t, m.t + 0.003, atol=2e-4)
    np.testing.assert_allclose(s.imu.accel.values, m.acc, atol=1e-5)
    np.testing.assert_allclose(s.imu.mag.values, m.mag, atol=1e-5)
    assert s.pressure is not None
    np.testing.assert_allclose(s.pressure.values[:, 0], m.pressure_pa[::5], atol=1e-2)
    assert s.meta.source["format"] == "ipin"
    assert s.meta.source["sensor_clock_offset_s"] == pytest.approx(-4999.997, abs=2e-4)
    assert any("mbar to Pa" in n for n in s.meta.notes)
    assert s.meta.source["device"]["model"] == "TEST-1"


def test_orientation_is_q_nd(log: tuple[Path, object]) -> None:
    path, m = log
    s = read_ipin(path)
    assert s.orientation is not None
    ang = quat_angle_between(s.orientation.q, m.q_nd)
    assert np.max(ang) < 1e-5
    assert any("agrees with the recording" in n for n in s.meta.notes)


def test_posi_start_pose_georeference_checkpoints(log: tuple[Path, object]) -> None:
    path, m = log
    s = read_ipin(path, floor_height_m=4.0)
    assert s.meta.georeference is not None
    assert s.meta.georeference.lat_deg == pytest.approx(LAT0)
    assert s.meta.start_pose is not None and s.meta.start_pose.x == 0.0
    assert s.meta.source["start_pose_t_s"] == pytest.approx(m.t[10], abs=1e-4)
    cp = s.checkpoints
    assert cp is not None and list(cp.label) == ["2", "3"]
    # 1e-4 deg of latitude north is about 11.1 m; floor 1 -> z = 4 m
    assert cp.xyz[0, 1] == pytest.approx(11.12, abs=0.05)
    assert abs(cp.xyz[0, 0]) < 1e-6 and cp.xyz[0, 2] == 4.0
    assert cp.xyz[1, 0] == pytest.approx(7.24, abs=0.05) and cp.xyz[1, 2] == 0.0
    geo = Georeference(LAT0, LON0)
    back = geo.to_wgs84(np.array([[cp.xyz[1, 0], cp.xyz[1, 1], 0.0]]))[0]
    assert back[1] == pytest.approx(LON0 + 1e-4, abs=1e-9)


def test_trim_to_start(log: tuple[Path, object]) -> None:
    path, m = log
    s = read_ipin(path, trim_to_start=True)
    assert s.imu is not None
    assert s.imu.accel.t[0] >= m.t[10]
    assert s.rss is not None and s.rss.t[0] >= m.t[10]


def test_beacons_mapping_and_unknown(log: tuple[Path, object]) -> None:
    path, _ = log
    s = read_ipin(path)
    assert s.rss is not None
    ids = set(s.rss.anchor.tolist())
    # minors 1, 2 are in the landmark file; minor 3 is not and keeps its MAC
    assert ids == {"BLE1", "BLE2", "BE:AC:20:23:00:03"}
    assert any("BE:AC:20:23:00:03" in n and "keep their MAC" in n for n in s.meta.notes)
    assert set(s.landmarks) == {"BLE1", "BLE2", "BLE9"}
    lm = s.landmarks["BLE9"]
    assert lm.kind == "beacon" and lm.floor == -2 and lm.position is not None
    assert lm.position[2] == pytest.approx(-6.0)
    assert s.unknown_ids() == {"rss": ["BE:AC:20:23:00:03"]}


def test_beacon_rule_override(log: tuple[Path, object]) -> None:
    path, _ = log
    s = read_ipin(path, beacon_ids={"be:ac:20:23:00:03": "BLE9"})
    assert s.rss is not None and "BLE9" in set(s.rss.anchor.tolist())
    s2 = read_ipin(path, beacon_ids=lambda mac, minor: None)
    assert s2.rss is not None and all(a.startswith("BE:AC") for a in s2.rss.anchor)
    assert ipin_beacon_id("x", 4) == "BLE4" and ipin_beacon_id("x", None) is None


def test_no_beacon_file(tmp_path: Path) -> None:
    path = write_ipin(tmp_path / "trial.txt", motion(200))
    s = read_ipin(path)
    assert s.landmarks == {}
    assert s.rss is not None and all(a.startswith("BE:AC") for a in s.rss.anchor)
    s2 = read_ipin(path, beacons=write_beacons(tmp_path / "other.csv"), find_beacons=False)
    assert "BLE1" in s2.landmarks


def test_wifi_opt_in(log: tuple[Path, object]) -> None:
    path, _ = log
    s = read_ipin(path)
    assert s.rss is not None and "20:23:00:00:00:12" not in set(s.rss.anchor.tolist())
    s2 = read_ipin(path, include_wifi=True)
    assert s2.rss is not None and "20:23:00:00:00:12" in set(s2.rss.anchor.tolist())
    assert np.all(np.diff(s2.rss.t) >= 0)
    assert set(s2.rss.rss_dbm[s2.rss.anchor == "20:23:00:00:00:12"]) == {-63.0}


def test_gyro_own_rate(tmp_path: Path) -> None:
    m = motion(300)
    s = read_ipin(write_ipin(tmp_path / "t.txt", m, gyro_every=2))
    assert s.imu is not None and s.imu.gyro is not None
    assert len(s.imu.gyro) == 150 and len(s.imu.accel) == 300


def test_zip_and_folder(log: tuple[Path, object], tmp_path: Path) -> None:
    path, _ = log
    out = tmp_path / "out"
    out.mkdir()
    z = zip_folder(path.parent, out / "bundle.zip", prefix="IPIN/")
    s = read_ipin(z)
    assert "BLE1" in s.landmarks and s.imu is not None
    s2 = read_any(path.parent)
    assert s2.meta.source["format"] == "ipin"


@pytest.mark.parametrize(("bad", "where"), [
    ("ACCE;0.5;x;1;2;3;3", "sensor_t is 'x'"),
    ("ACCE;0.5;1.0", "field(s)"),
    ("garbage line here", "is not a record"),
    ("POSI;70;9;95.0;11.0;0;100", "latitude is 95"),
    ("BLE4;1.0;iBeacon;BE:AC:20:23:00:01;-500;0;1;1;U", "RSS -500"),
    ("AHRS;9.0;5010.0;1;2;3;0.9;0.9;0.9;3", "|(q2, q3, q4)|"),
])
def test_malformed_lines_name_the_line(tmp_path: Path, bad: str, where: str) -> None:
    m = motion(100)
    path = write_ipin(tmp_path / "t.txt", m, extra=bad + "\n")
    n_lines = len(path.read_text().splitlines())
    with pytest.raises(InputError) as exc:
        read_ipin(path)
    assert where in str(exc.value)
    assert f"line {n_lines}" in str(exc.value)


def test_backward_time_error_and_repair(tmp_path: Path) -> None:
    m = motion(100)
    path = write_ipin(tmp_path / "t.txt", m, extra="ACCE;0.5;5000.111;1;2;9.8;3\n")
    with pytest.raises(InputError, match=r"time goes backwards.*; expected strictly"):
        read_ipin(path)
    with pytest.warns(RepairWarning):
        s = read_ipin(path, repair=True)
    assert s.imu is not None and np.all(np.diff(s.imu.accel.t) > 0)
    assert len(s.imu.accel) == 101


def test_nan_rows(tmp_path: Path) -> None:
    path = write_ipin(tmp_path / "t.txt", motion(100), extra="MAGN;9.9;5009.9;nan;1;2;3\n")
    with pytest.raises(InputError, match="non-finite"):
        read_ipin(path)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        s = read_ipin(path, repair=True)
    assert any(issubclass(w.category, RepairWarning) for w in rec)
    assert s.imu is not None and s.imu.mag is not None and len(s.imu.mag) == 100


def test_not_a_logfile(tmp_path: Path) -> None:
    p = tmp_path / "x.txt"
    p.write_text("hello\nworld\n")
    with pytest.raises(FormatError):
        read_ipin(p)
    with pytest.raises(InputError, match="no such file"):
        read_ipin(tmp_path / "missing.txt")


def test_beacons_csv_errors() -> None:
    with pytest.raises(FormatError, match="no lat column"):
        read_beacons_csv(b"id,x,y\nA,1,2\n", where="b.csv")
    with pytest.raises(FormatError, match="line 3"):
        read_beacons_csv(b"id,lat,lon\nA,1,2\nB,north,2\n", where="b.csv")
    with pytest.raises(FormatError, match="appears twice"):
        read_beacons_csv(b"id,lat,lon\nA,1,2\nA,1,2\n", where="b.csv")
    with pytest.raises(FormatError, match="line 2"):
        read_beacons_csv(b"id,lat,lon\nA,100,2\n", where="b.csv")
    lms = read_beacons_csv(b'"bleID","Lat","Lon","floor"\n"B1",1.5,2.5,-1\n', where="b.csv")
    assert lms[0].id == "B1" and lms[0].floor == -1 and lms[0].wgs84 is not None


def test_large_file_parses(tmp_path: Path) -> None:
    # 40 k lines: exercises the vectorized path (timing lives in benchmarks, not here)
    m = motion(8000, rate_hz=100.0)
    s = read_ipin(write_ipin(tmp_path / "big.txt", m))
    assert s.imu is not None and len(s.imu.accel) == 8000


# ------------------------------------------------------------------------------------------
# real files
# ------------------------------------------------------------------------------------------


@pytest.mark.realdata
@pytest.mark.parametrize("name", IPIN_FILES)
def test_real_ipin_logfiles(shared_data: Path, name: str) -> None:
    path = shared_data / "ipin2023" / name
    if not path.is_file():
        pytest.skip(f"{name} not present")
    s = read_ipin(path)
    assert s.imu is not None and s.imu.gyro is not None and s.imu.mag is not None
    assert 48.0 < s.imu.accel.rate_hz < 52.0
    acc_norm = np.median(np.linalg.norm(s.imu.accel.values, axis=1))
    assert 9.5 < acc_norm < 10.1
    assert s.pressure is not None and 90000 < np.median(s.pressure.values) < 105000
    assert s.orientation is not None
    assert any("agrees with the recording" in n for n in s.meta.notes)
    assert s.checkpoints is not None and len(s.checkpoints) in (11, 13)
    assert s.meta.source["start_pose_t_s"] == pytest.approx(61.0, abs=0.5)
    # the last POSI repeats the first: back at the origin
    np.testing.assert_allclose(s.checkpoints.xyz[-1, :2], [0.0, 0.0], atol=1e-6)
    assert set(s.landmarks) == {f"BLE{i}" for i in range(1, 7)}
    assert s.rss is not None and s.unknown_ids() == {}
    # landmarks lie within ~100 m of the start
    for lm in s.landmarks.values():
        assert lm.position is not None and np.hypot(*lm.position[:2]) < 100.0


@pytest.mark.realdata
def test_real_ipin_gyro_rate(shared_data: Path) -> None:
    path = shared_data / "ipin2023" / IPIN_FILES[0]
    if not path.is_file():
        pytest.skip("not present")
    s = read_ipin(path)
    assert s.imu is not None and s.imu.gyro is not None
    assert 98.0 < s.imu.gyro.rate_hz < 102.0  # SM-A520F: gyroscope at 100 Hz


@pytest.mark.realdata
def test_real_ipin_roundtrip_through_session(shared_data: Path, tmp_path: Path) -> None:
    path = shared_data / "ipin2023" / IPIN_FILES[1]
    if not path.is_file():
        pytest.skip("not present")
    from hrtls.io.session import read_session, write_session

    s = read_ipin(path)
    out = write_session(s, tmp_path / "sess")
    back = read_session(out)
    assert back.imu is not None and s.imu is not None
    np.testing.assert_allclose(back.imu.accel.values, s.imu.accel.values, rtol=1e-8)
    assert back.checkpoints is not None and s.checkpoints is not None
    np.testing.assert_allclose(back.checkpoints.xyz, s.checkpoints.xyz, atol=1e-6)
    assert back.rss is not None and s.rss is not None
    assert back.rss.anchor.tolist() == s.rss.anchor.tolist()
    assert back.meta.georeference == s.meta.georeference
    assert set(back.landmarks) == set(s.landmarks)
    read_any_back = read_any(out)
    assert read_any_back.meta.source["format"] == "ipin"


def test_variants_crlf_eddystone_magn_gap(tmp_path: Path) -> None:
    m = motion(100)
    path = write_ipin(tmp_path / "t.txt", m, ble=False)
    text = path.read_text()
    # the header's documented MAGN layout with an empty field after Mag_X
    text = "\n".join(
        ln.replace(";", ";;", 4).replace(";;", ";", 3) if ln.startswith("MAGN") else ln
        for ln in text.splitlines())
    text += "\nBLE4;1.5;Eddystone;AA:BB:CC:DD:EE:FF;-80;abcd;3.1;20;100;5\n"
    path.write_bytes(text.replace("\n", "\r\n").encode())
    raw = path.read_bytes()
    assert b"\r\n" in raw
    assert all(b";;" in ln for ln in raw.splitlines() if ln.startswith(b"MAGN"))
    s = read_ipin(path)
    assert s.imu is not None and s.imu.mag is not None
    np.testing.assert_allclose(s.imu.mag.values, m.mag, atol=1e-5)
    assert s.rss is not None and s.rss.anchor.tolist() == ["AA:BB:CC:DD:EE:FF"]


@pytest.mark.filterwarnings("ignore::hrtls.errors.DegradedInputWarning")
def test_synthetic_roundtrip_through_session(log: tuple[Path, object], tmp_path: Path) -> None:
    from hrtls.io.session import read_session, write_session

    path, _ = log
    s = read_ipin(path, include_wifi=True)
    back = read_session(write_session(s, tmp_path / "out.zip"))
    assert back.imu is not None and back.imu.gyro is not None and s.imu is not None
    np.testing.assert_allclose(back.imu.accel.t, s.imu.accel.t, atol=1e-9)
    assert back.pressure is not None and s.pressure is not None
    np.testing.assert_allclose(back.pressure.values, s.pressure.values)
    assert back.orientation is not None and s.orientation is not None
    np.testing.assert_allclose(back.orientation.q, s.orientation.q, atol=1e-9)
    assert back.rss is not None and s.rss is not None
    assert back.rss.anchor.tolist() == s.rss.anchor.tolist()
    assert back.checkpoints is not None and s.checkpoints is not None
    assert back.checkpoints.label.tolist() == s.checkpoints.label.tolist()
    assert back.meta.start_pose == s.meta.start_pose
    assert back.meta.source == s.meta.source


@pytest.mark.realdata
def test_real_ipin_wifi_and_trim(shared_data: Path) -> None:
    folder = shared_data / "ipin2023"
    path = folder / IPIN_FILES[0]
    if not path.is_file():
        pytest.skip("not present")
    s = read_ipin(path, include_wifi=True, trim_to_start=True)
    assert s.imu is not None and s.rss is not None
    t0 = s.meta.source["start_pose_t_s"]
    assert s.imu.accel.t[0] >= t0 and s.rss.t[0] >= t0
    wifi = [a for a in s.rss.anchor.tolist() if not a.startswith("BLE")]
    assert len(set(wifi)) > 10
    with pytest.raises(FormatError, match="logfiles"):
        read_ipin(folder)
    assert read_any(path).meta.source["format"] == "ipin"


def test_per_type_sensor_clocks(tmp_path: Path) -> None:
    m = motion(200)
    path = write_ipin(tmp_path / "t.txt", m)
    out = []
    for ln in path.read_text().splitlines():
        if ln.startswith("GYRO"):
            f = ln.split(";")
            f[2] = f"{float(f[2]) + 250.0:.4f}"
            ln = ";".join(f)
        out.append(ln)
    path.write_text("\n".join(out) + "\n")
    s = read_ipin(path)
    assert s.imu is not None and s.imu.gyro is not None
    np.testing.assert_allclose(s.imu.gyro.t, s.imu.accel.t, atol=2e-4)
    assert any("sensor clocks differ" in n for n in s.meta.notes)
    assert "sensor_clock_offsets_s" in s.meta.source


def test_all_times_nan_is_an_error(tmp_path: Path) -> None:
    m = motion(30)
    path = write_ipin(tmp_path / "t.txt", m)
    out = []
    for ln in path.read_text().splitlines():
        if ln.startswith("GYRO"):
            f = ln.split(";")
            f[1] = f[2] = "nan"
            ln = ";".join(f)
        out.append(ln)
    path.write_text("\n".join(out) + "\n")
    with pytest.raises(InputError, match="non-finite"):
        read_ipin(path)
    with pytest.warns(RepairWarning):
        s = read_ipin(path, repair=True)
    assert s.imu is not None and s.imu.gyro is None
