import io
import json
import warnings
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hrtls.data import (
    Checkpoints,
    GeoreferenceModel,
    GroundTruth,
    ImuStream,
    Landmark,
    OrientationSeries,
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    SensorSeries,
    Session,
    SessionMeta,
    StartPose,
    StepEvents,
    TagDetections,
    Trajectory,
)
from hrtls.errors import DegradedInputWarning, FormatError, InputError, RepairWarning
from hrtls.frames import Georeference
from hrtls.io.session import read_session, write_session
from hrtls.io.tables import read_steps, read_trajectory, write_steps, write_trajectory


def full_session(seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(0, 5, 0.01) + 1.7e9  # Unix-like clock: precision must survive
    n = len(t)
    tg = np.arange(0, 5, 0.005) + 1.7e9
    imu = ImuStream(
        SensorSeries(t, rng.normal([0, 0, 9.81], 0.2, (n, 3)), "acc"),
        SensorSeries(tg, rng.normal(0, 0.3, (len(tg), 3)), "gyro"),
        SensorSeries(t, rng.normal([20, 5, -40], 1, (n, 3)), "mag"),
    )
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return Session(
        meta=SessionMeta(start_pose=StartPose(x=1, y=2, heading=0.5), placement="waist",
                         georeference=GeoreferenceModel(lat_deg=45.0, lon_deg=9.0),
                         notes=["made by a test"], custom_key={"kept": True}),
        imu=imu,
        pressure=SensorSeries(t[::10], rng.normal(101300, 5, len(t[::10])), "p"),
        orientation=OrientationSeries(t, q),
        fixes=PositionFixes(t[::100], rng.normal(size=(5, 3)), np.full(5, 0.3), has_z=True),
        rss=RssReadings(np.repeat(t[::50], 2), np.tile(["b1", "b,2"], 10),
                        rng.uniform(-90, -50, 20)),
        tags=TagDetections(t[[5, 9]], ["tag1", "tag1"]),
        ranges=RangeMeasurements(t[:3], ["n1", "n1", "n1"], [1.0, 2.0, 3.0], [0.1, np.nan, 0.2]),
        landmarks={"b1": Landmark(id="b1", kind="beacon", position=(0, 0, 2)),
                   "b,2": Landmark(id="b,2", kind="beacon", wgs84={"lat": 45.0, "lon": 9.001}),
                   "tag1": Landmark(id="tag1", kind="rfid", position=(3, 4, 0),
                                    bearings_rad=(0.0, np.pi), accuracy_m=2.5,
                                    lobe_orientation_rad=0.3),
                   "n1": Landmark(id="n1", kind="node", position=(5, 5, 1))},
        truth=GroundTruth(t, rng.normal(size=(n, 3)), rng.uniform(-3, 3, n)),
        checkpoints=Checkpoints(t[[0, 100]], np.zeros((2, 3)), ["start", "cp 1"]),
    )


def assert_same(a: Session, b: Session):
    for part in ("accel", "gyro", "mag"):
        sa, sb = getattr(a.imu, part), getattr(b.imu, part)
        assert np.allclose(sa.t, sb.t, rtol=0, atol=2e-6)
        assert np.allclose(sa.values, sb.values, rtol=1e-9)
    assert np.allclose(a.orientation.q, b.orientation.q, atol=1e-9)
    assert np.allclose(a.pressure.values, b.pressure.values)
    assert np.allclose(a.fixes.xyz, b.fixes.xyz) and b.fixes.has_z
    assert list(a.rss.anchor) == list(b.rss.anchor)
    assert np.allclose(a.rss.rss_dbm, b.rss.rss_dbm)
    assert list(a.tags.tag) == list(b.tags.tag)
    assert np.allclose(a.ranges.sigma_m, b.ranges.sigma_m, equal_nan=True)
    assert np.allclose(a.truth.heading_rad, b.truth.heading_rad)
    assert list(a.checkpoints.label) == list(b.checkpoints.label)
    assert a.landmarks == b.landmarks
    assert a.meta.model_dump() == b.meta.model_dump()


@pytest.mark.parametrize("name", ["sess", "sess.zip"])
def test_round_trip_every_file(tmp_path, name):
    s = full_session()
    write_session(s, tmp_path / name)
    back = read_session(tmp_path / name)
    assert_same(s, back)
    # the gyroscope has its own clock, so it lives in gyro.csv
    if name == "sess":
        assert (tmp_path / name / "gyro.csv").exists()
        assert "gx" not in (tmp_path / name / "imu.csv").read_text().splitlines()[0]
    assert back.meta.model_extra["custom_key"] == {"kept": True}


def test_overwrite_rules(tmp_path):
    s = full_session()
    write_session(s, tmp_path / "s")
    with pytest.raises(InputError, match="already holds a session"):
        write_session(s, tmp_path / "s")
    smaller = s.with_parts(rss=None, tags=None)
    write_session(smaller, tmp_path / "s", overwrite=True)
    assert not (tmp_path / "s" / "rss.csv").exists()


def test_zip_in_subfolder_and_traversal_refused(tmp_path):
    s = full_session()
    write_session(s, tmp_path / "flat.zip")
    nested = tmp_path / "nested.zip"
    with zipfile.ZipFile(tmp_path / "flat.zip") as src, zipfile.ZipFile(nested, "w") as dst:
        for info in src.infolist():
            dst.writestr("mission/" + info.filename, src.read(info))
    assert len(read_session(nested).imu.accel) == len(s.imu.accel)
    evil = tmp_path / "evil.zip"
    with zipfile.ZipFile(evil, "w") as zf:
        zf.writestr("imu.csv", "t,ax,ay,az\n0,0,0,9.8\n")
        zf.writestr("../../etc/passwd", "x")
    with pytest.raises(FormatError, match="outside the archive"):
        read_session(evil)


def test_zip_size_limit(tmp_path):
    write_session(full_session(), tmp_path / "s.zip")
    with pytest.raises(FormatError, match="bytes uncompressed"):
        read_session(tmp_path / "s.zip", max_bytes=1000)


def write_imu(tmp_path, text):
    d = tmp_path / "s"
    d.mkdir(exist_ok=True)
    (d / "imu.csv").write_text(text)
    return d


def test_malformed_value_names_line_and_column(tmp_path):
    rows = "\n".join(f"{i * 0.01},0,0,9.8" for i in range(30))
    d = write_imu(tmp_path, "t,ax,ay,az\n" + rows + "\n0.3,0,abc,9.8\n")
    with pytest.raises(FormatError, match=r"imu\.csv line 32: 'ay' is 'abc'; expected a number"):
        read_session(d)


def test_missing_column_and_partial_group(tmp_path):
    d = write_imu(tmp_path, "t,ax,ay\n0,0,0\n")
    with pytest.raises(FormatError, match="missing column"):
        read_session(d)
    d = write_imu(tmp_path, "t,ax,ay,az,gx\n0,0,0,9.8,0\n")
    with pytest.raises(FormatError, match="incomplete column group"):
        read_session(d)


def test_backward_time_error_then_repair(tmp_path):
    rows = [f"{i * 0.01:.2f},0,0,9.8" for i in range(30)]
    rows[10], rows[11] = rows[11], rows[10]
    d = write_imu(tmp_path, "t,ax,ay,az\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match="goes backwards"):
        read_session(d)
    with pytest.warns(RepairWarning, match="sorted"):
        s = read_session(d, repair=True)
    assert len(s.imu.accel) == 30


def test_unknown_landmark_ids_warn(tmp_path):
    d = tmp_path / "s"
    d.mkdir()
    (d / "tags.csv").write_text("t,tag\n1.0,ghost\n")
    with pytest.warns(DegradedInputWarning, match="ghost"):
        read_session(d)


def test_bad_json_named(tmp_path):
    d = write_imu(tmp_path, "t,ax,ay,az\n0,0,0,9.8\n")
    (d / "session.json").write_text('{"placement": "waist",}')
    with pytest.raises(FormatError, match=r"session\.json line 1"):
        read_session(d)
    (d / "session.json").write_text('{"floor_height_m": -1}')
    with pytest.raises(FormatError, match="floor_height_m"):
        read_session(d)
    (d / "session.json").unlink()
    (d / "landmarks.json").write_text(json.dumps([{"id": "a", "kind": "rfid"}]))
    with pytest.raises(FormatError, match=r"landmarks\.json item 0"):
        read_session(d)


line_text = st.text(alphabet=st.sampled_from(list("0123456789.,-eE nanif\"abc\t")), max_size=30)


@settings(max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(line_text, min_size=1, max_size=8))
@example(lines=['""'])  # once read as a blank line and dropped
def test_garbage_lines_give_clean_errors(tmp_path, lines):
    d = tmp_path / "g"
    d.mkdir(exist_ok=True)
    good = [f"{i * 0.01},0,0,9.8" for i in range(25)]
    (d / "imu.csv").write_text("t,ax,ay,az\n" + "\n".join(good + lines) + "\n")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = read_session(d)
    except InputError:
        return
    # accepted: then every line parsed into the stream, nothing silently dropped
    nonblank = [ln for ln in lines if ln.strip()]
    assert len(s.imu.accel) == 25 + len(nonblank)


def test_trajectory_and_steps_tables_round_trip(tmp_path):
    n = 50
    cov = np.zeros((n, 2, 2))
    cov[:, 0, 0], cov[:, 1, 1], cov[:, 0, 1], cov[:, 1, 0] = 1.0, 2.0, 0.5, 0.5
    tr = Trajectory.build(t=np.arange(n) * 0.1, xyz=np.random.default_rng(1).normal(size=(n, 3)),
                          heading_rad=np.linspace(-3, 3, n), cov_xy=cov,
                          var_heading=np.full(n, 0.01), activity=np.ones(n, dtype=int))
    write_trajectory(tr, tmp_path / "trajectory.csv", georeference=Georeference(45, 9))
    back = read_trajectory(tmp_path / "trajectory.csv")
    assert np.allclose(back.xyz, tr.xyz) and np.allclose(back.cov_xy, tr.cov_xy)
    assert "lat,lon" in (tmp_path / "trajectory.csv").read_text().splitlines()[0]
    steps = StepEvents.build(t_start=[0, 0.5], t_end=[0.5, 1.0], length_m=[0.7, 0.72],
                             heading_rad=[0.1, np.nan], dz_m=[0, 0.17],
                             activity=["walking", "upstairs"])
    write_steps(steps, tmp_path / "steps.csv")
    back_steps = read_steps(tmp_path / "steps.csv")
    assert np.allclose(back_steps.heading_rad, steps.heading_rad, equal_nan=True)
    assert list(back_steps.activity) == list(steps.activity)


def test_session_files_are_plain_csv(tmp_path):
    write_session(full_session(), tmp_path / "s")
    header = (tmp_path / "s" / "rss.csv").read_text().splitlines()
    assert header[0] == "t,anchor,rss_dbm"
    assert any('"b,2"' in ln for ln in header[1:])
    assert io.StringIO((tmp_path / "s" / "imu.csv").read_text()).readline().strip() == \
        "t,ax,ay,az,mx,my,mz"
