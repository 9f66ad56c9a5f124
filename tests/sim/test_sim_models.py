"""Unit tests of the motion, error, magnetic and infrastructure models."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, box

from hrtls.errors import InputError
from hrtls.sim._speed_profile import run_profile_kernel
from hrtls.sim.errors import (
    ErrorRealization,
    SensorErrorModel,
    apply_sensor_errors,
    realize_errors,
    sample_times,
)
from hrtls.sim.infrastructure import (
    CameraSystem,
    RangeModel,
    RfidReader,
    RfidTag,
    RssChannel,
    TrackSample,
    camera_fixes,
    disk_links,
    random_wsn,
    range_measurements,
    rfid_detection_probability,
    rfid_detections,
    rss_readings,
)
from hrtls.sim.magnetic import EarthField, MagneticAnomaly, MagneticEnvironment
from hrtls.sim.mission import MissionOptions
from hrtls.sim.motion_truth import (
    Waypoint,
    build_geometry,
    circle_waypoints,
    random_floorplan_walk,
    simulate_motion,
)


# ---------------------------------------------------------------------------------- motion
def _profile_reference(seg_s0, seg_v, length, dt, accel, decel, max_n):
    """Slow pure-Python copy of the compiled speed-profile kernel."""
    s, v = 0.0, 0.0
    out_s, out_v = [0.0], [0.0]
    floor = 0.5 * accel * dt
    while len(out_s) < max_n:
        j = max(i for i in range(len(seg_s0)) if seg_s0[i] <= s or i == 0)
        target = seg_v[j]
        for m in range(j + 1, len(seg_s0)):
            target = min(target, math.sqrt(seg_v[m] ** 2 + 2 * decel * max(seg_s0[m] - s, 0)))
        target = min(target, math.sqrt(2 * decel * max(length - s, 0.0)))
        v = max(v + min(max(target - v, -2 * decel * dt), accel * dt), floor)
        if s + v * dt >= length:
            out_s.append(length)
            out_v.append(0.0)
            break
        s += v * dt
        out_s.append(s)
        out_v.append(v)
    return np.array(out_s), np.array(out_v)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.3, 3.0), min_size=1, max_size=4), st.floats(2.0, 40.0))
def test_profile_kernel_matches_python(speeds, length):
    seg_s0 = np.linspace(0.0, length, len(speeds) + 1)[:-1]
    seg_v = np.asarray(speeds)
    a, b = run_profile_kernel(seg_s0, seg_v, length, 0.02, 1.0, 1.2, 100000)
    c, d = _profile_reference(seg_s0, seg_v, length, 0.02, 1.0, 1.2, 100000)
    np.testing.assert_allclose(a, c, atol=1e-9)
    np.testing.assert_allclose(b, d, atol=1e-9)
    assert a[-1] == pytest.approx(length)
    assert np.all(np.diff(a) >= 0)
    assert np.all(b <= max(speeds) + 1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=2, max_size=7),
       st.floats(0.0, 3.0))
def test_geometry_is_continuous(points, radius):
    pts = [points[0]]
    for p in points[1:]:
        if math.hypot(p[0] - pts[-1][0], p[1] - pts[-1][1]) > 0.5:
            pts.append(p)
    if len(pts) < 2:
        return
    geo = build_geometry([Waypoint(x=x, y=y, corner_radius_m=radius) for x, y in pts])
    polyline = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(pts))
    assert geo.total_length_m <= polyline + 1e-6
    for s in geo.s0[1:]:
        xyz, _, _ = geo.evaluate(np.array([s - 1e-7, s + 1e-7]))
        assert np.linalg.norm(xyz[0] - xyz[1]) < 1e-5
    ends, _, _ = geo.evaluate(np.array([0.0, geo.total_length_m]))
    np.testing.assert_allclose(ends[0, :2], pts[0], atol=1e-9)
    np.testing.assert_allclose(ends[1, :2], pts[-1], atol=1e-6)


def test_circle_waypoints_make_a_circle():
    wps = circle_waypoints(center=(3.0, -2.0), radius_m=4.0, laps=2.0, speed_m_s=1.0)
    geo = build_geometry(wps)
    assert geo.total_length_m == pytest.approx(2 * 2 * np.pi * 4.0, rel=1e-3)
    xyz, _, _ = geo.evaluate(np.linspace(0, geo.total_length_m, 2000))
    r = np.hypot(xyz[:, 0] - 3.0, xyz[:, 1] + 2.0)
    np.testing.assert_allclose(r, 4.0, atol=1e-3)


def test_stops_turns_and_speed_limits():
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=10.0, y=0.0, speed_m_s=1.5, corner_radius_m=0.0),
           Waypoint(x=10.0, y=10.0, speed_m_s=1.0, stop_s=5.0, corner_radius_m=0.0),
           Waypoint(x=0.0, y=10.0, speed_m_s=2.0)]
    m = simulate_motion(wps, rate_hz=50.0, start_pause_s=1.0, end_pause_s=1.0)
    assert m.speed.max() <= 2.0 + 1e-9
    assert m.distance_m == pytest.approx(30.0, rel=1e-9)  # sharp corners: no rounding
    standing = ~m.moving
    # start pause + turn at (10, 0) + 5 s stop and turn at (10, 10) + end pause
    assert standing.sum() * m.dt > 1.0 + 5.0 + 1.0
    still_at_corner = standing & (np.hypot(m.xyz[:, 0] - 10.0, m.xyz[:, 1] - 10.0) < 1e-6)
    assert still_at_corner.sum() * m.dt >= 5.0
    # the heading turns on the spot while standing there, from north to west
    h = m.heading[still_at_corner]
    assert h[0] == pytest.approx(np.pi / 2, abs=0.05)
    assert h[-1] == pytest.approx(np.pi, abs=0.05)
    assert set(np.unique(m.activity)) == {0, 1}


def test_stairs_are_labelled_and_rise():
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=5.0, y=0.0),
           Waypoint(x=8.0, y=0.0, z=1.7, speed_m_s=0.5), Waypoint(x=12.0, y=0.0, z=1.7)]
    m = simulate_motion(wps, rate_hz=50.0)
    assert m.xyz[-1, 2] == pytest.approx(1.7)
    assert 3 in set(np.unique(m.activity))  # upstairs


def test_random_floorplan_walk_stays_inside():
    free = box(0, 0, 30, 3).union(box(0, 0, 3, 20)).union(box(10, 10, 20, 20)).union(
        box(2, 14, 11, 16))
    rng = np.random.default_rng(3)
    wps = random_floorplan_walk(free, rng, distance_m=150.0, margin_m=0.3)
    assert len(wps) > 5
    for a, b in itertools.pairwise(wps):
        assert free.buffer(1e-6).contains(LineString([(a.x, a.y), (b.x, b.y)]))
    assert any(box(10, 10, 20, 20).contains(Point(w.x, w.y)) for w in wps)


def test_bad_waypoints_raise():
    with pytest.raises(InputError):
        build_geometry([Waypoint(x=0.0, y=0.0)])
    with pytest.raises(InputError):
        build_geometry([Waypoint(x=0.0, y=0.0), Waypoint(x=0.0, y=0.0)])
    with pytest.raises(InputError):
        simulate_motion([Waypoint(x=0, y=0), Waypoint(x=1, y=0, speed_m_s=0.0)], rate_hz=50)


# ---------------------------------------------------------------------------------- errors
def test_noise_sigma_from_density():
    m = SensorErrorModel.from_sigma(5.7575e-2, 50.0)
    assert m.noise_sigma(50.0) == pytest.approx(5.7575e-2)
    assert m.noise_density == pytest.approx(5.7575e-2 / 5.0)
    rng = np.random.default_rng(0)
    t = np.arange(200000) / 50.0
    y = apply_sensor_errors(np.zeros((len(t), 3)), t, m, realize_errors(m, rng), rng)
    assert np.std(y) == pytest.approx(5.7575e-2, rel=0.02)


def test_scale_misalignment_bias_quantization_saturation():
    m = SensorErrorModel(resolution=0.01, full_scale=2.0)
    real = ErrorRealization(bias=np.array([0.1, 0.0, 0.0]), scale=np.array([0.0, 0.5, 0.0]),
                            misalignment=np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0],
                                                   [0.0, 0.0, 1.0]]))
    x = np.array([[1.0, 1.0, 3.0], [0.123, 0.0, -5.0]])
    y = apply_sensor_errors(x, np.array([0.0, 0.01]), m, real, np.random.default_rng(0))
    np.testing.assert_allclose(y[0], [1.2, 1.5, 2.0])  # x: 1 + 0.1*1 + 0.1 bias; z saturates
    np.testing.assert_allclose(y[1], [0.22, 0.0, -2.0])  # 0.223 quantized to 0.01
    np.testing.assert_allclose(np.round(y / 0.01) * 0.01, y)


def test_bias_random_walk_grows_with_time():
    m = SensorErrorModel(bias_walk_density=0.01)
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 100.0, 0.1)
    finals = np.array([apply_sensor_errors(np.zeros((len(t), 3)), t, m,
                                           realize_errors(m, rng), rng)[-1] for _ in range(200)])
    # variance K^2 t after t seconds
    assert np.var(finals) == pytest.approx(0.01**2 * t[-1], rel=0.25)


@settings(max_examples=50, deadline=None)
@given(st.floats(10.0, 500.0), st.floats(0.0, 0.01), st.integers(0, 1000))
def test_sample_times_strictly_increasing(rate, jitter, seed):
    t = sample_times(0.0, 10.0, rate, jitter, np.random.default_rng(seed))
    assert np.all(np.diff(t) > 0)
    assert t[0] >= 0.0 and t[-1] <= 10.0 + 1e-9


def test_error_model_validation():
    with pytest.raises(InputError):
        SensorErrorModel(noise_density=-1.0)
    with pytest.raises(InputError):
        SensorErrorModel(full_scale=0.0)


# ---------------------------------------------------------------------------------- magnetic
def test_earth_field_magnitude_and_dip():
    e = EarthField(total_ut=50.0, inclination_rad=np.deg2rad(60), declination_rad=0.0)
    v = e.vector_enu()
    assert np.linalg.norm(v) == pytest.approx(50.0)
    np.testing.assert_allclose(v, [0.0, 25.0, -50.0 * np.sin(np.deg2rad(60))], atol=1e-12)


def test_dipole_on_axis_and_equator():
    m = 100.0  # A m^2 along +z
    env = MagneticEnvironment(earth=EarthField(total_ut=0.0),
                              anomalies=[MagneticAnomaly((0, 0, 0), (0, 0, m), 0.0)])
    b = env.field_at(np.array([[0.0, 0.0, 2.0], [2.0, 0.0, 0.0]]))
    # on axis 2 k m / r^3, on the equator -k m / r^3, k = 1e-7 T m/A = 0.1 uT m^3/(A m^2)
    np.testing.assert_allclose(b[0], [0, 0, 2 * 0.1 * m / 8], atol=1e-12)
    np.testing.assert_allclose(b[1], [0, 0, -0.1 * m / 8], atol=1e-12)


# ---------------------------------------------------------------------------------- infrastructure
def _line_track(speed: float = 1.0, duration: float = 40.0) -> TrackSample:
    t = np.arange(0.0, duration, 0.02)
    x = speed * t
    return TrackSample(t=t, xyz=np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]),
                       heading=np.zeros_like(t), speed=np.full_like(t, speed))


def test_rss_follows_path_loss_without_shadowing():
    ch = RssChannel(a_dbm=-60.0, eta=2.5, sigma_db=1e-9, sensitivity_dbm=-95.0,
                    beacon_rate_hz=1.0)
    assert ch.coverage_radius_m() == pytest.approx(10 ** (35 / 25))  # 25.1 m (Tarrio Sec. IV)
    track = _line_track(duration=60.0)
    rss = rss_readings({"A": (0.0, 3.0, 1.0)}, ch, track, np.random.default_rng(0),
                       receiver_height_m=1.0)
    x = np.interp(rss.t, track.t, track.xyz[:, 0])
    d = np.hypot(x, 3.0)
    np.testing.assert_allclose(rss.rss_dbm, -60.0 - 25.0 * np.log10(d), atol=1e-6)
    assert d.max() <= ch.coverage_radius_m() + 1e-6


def test_rfid_probability_table_points():
    reader = RfidReader()

    def p(d, phi, az=0.0, dh=0.0, v=0.5):
        return float(rfid_detection_probability(np.array([d]), np.array([phi]), np.array([az]),
                                                np.pi / 3, np.array([dh]), np.array([v]),
                                                reader)[0])

    assert p(1.0, 0.0) == pytest.approx(1.0)
    assert p(2.5, 0.0) == pytest.approx(0.8)  # App. B Table 1
    assert p(3.0, 0.0) == pytest.approx(0.0)
    assert p(1.5, np.pi / 4) == pytest.approx(0.475)  # mean of 75 % and 20 %
    assert p(1.5, -np.pi / 4) == pytest.approx(0.475)
    assert p(1.0, np.pi / 2) == pytest.approx(0.0)
    assert p(1.0, 0.0, az=np.deg2rad(70)) == 0.0  # outside the +-60 deg lobe
    assert p(1.0, 0.0, dh=0.8) == pytest.approx(1 - 0.3 * 0.7)
    assert p(1.0, 0.0, v=2.0) == pytest.approx(0.85)


def test_rfid_reads_only_near_the_tag():
    tag = RfidTag(id="T1", position=(20.0, 1.0, 1.5), lobe_orientation_rad=np.pi)
    track = _line_track(duration=40.0)
    counts = []
    for seed in range(20):
        det = rfid_detections([tag], RfidReader(height_m=1.4), track,
                              np.random.default_rng(seed))
        counts.append(0 if det is None else len(det))
    # a pass at 1 m/s gives a few reads, as App. B Tables 2-3 report (0 to 9 per pass)
    assert 1.0 <= np.mean(counts) <= 10.0
    det = rfid_detections([tag], RfidReader(height_m=1.4), track, np.random.default_rng(0))
    assert det is not None
    x = np.interp(det.t, track.t, track.xyz[:, 0])
    assert np.all(np.hypot(x - 20.0, 1.0) <= 3.0)
    assert np.all(x < 20.0)  # facing the tag while approaching it (lobe towards -x)


def test_camera_only_while_moving_and_in_coverage():
    t = np.arange(0.0, 60.0, 0.02)
    speed = np.where((t > 20) & (t < 30), 0.0, 1.0)
    x = np.cumsum(speed) * 0.02
    track = TrackSample(t=t, xyz=np.column_stack([x, 0 * t, 0 * t]), heading=0 * t,
                        speed=speed)
    cam = CameraSystem(period_s=1.0, sigma_m=0.01, only_while_moving=True,
                       coverage=box(0, -1, 40, 1))
    fixes = camera_fixes(cam, track, np.random.default_rng(0))
    assert fixes is not None
    assert not np.any((fixes.t > 20.05) & (fixes.t < 29.95))
    assert np.all(fixes.xyz[:, 0] < 40.1)


def test_ranges_max_range_and_nlos_bias():
    track = _line_track(duration=30.0)
    wall = LineString([(10.0, 0.5), (20.0, 0.5)])
    model = RangeModel(rate_hz=5.0, sigma_m=1e-9, max_range_m=5.0, nlos_bias_mean_m=2.0,
                       walls=wall, dropout_probability=0.0, agent_height_m=0.0)
    r = range_measurements({"N": (15.0, 2.0, 0.0)}, model, track, np.random.default_rng(0))
    x = np.interp(r.t, track.t, track.xyz[:, 0])
    d = np.hypot(x - 15.0, 2.0)
    assert np.all(d <= 5.0)
    assert np.all(r.range_m >= d - 1e-6)
    assert np.any(r.range_m > d + 0.1)  # blocked by the wall somewhere
    assert np.all(np.isfinite(r.sigma_m))


def test_proportional_range_noise_grows_with_distance_and_is_reported() -> None:
    """2 % noise: the spread of (range - distance) / distance is 0.02 at every distance."""
    t = np.arange(0.0, 2000.0, 0.01)
    x = np.where(t < 1000.0, 1.0, 9.0)
    track = TrackSample(t, np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]),
                        np.zeros_like(t), np.zeros_like(t))
    model = RangeModel(rate_hz=20.0, sigma_m=0.0, sigma_fraction=0.02, max_range_m=20.0,
                       dropout_probability=0.0, agent_height_m=0.0)
    r = range_measurements({"N": (0.0, 0.0, 0.0)}, model, track, np.random.default_rng(3))
    d = np.where(r.t < 1000.0, 1.0, 9.0)
    for near in (True, False):
        m = (d == 1.0) if near else (d == 9.0)
        assert m.sum() > 10_000
        assert abs(np.std((r.range_m[m] - d[m]) / d[m]) - 0.02) < 0.001
    np.testing.assert_allclose(r.sigma_m, 0.02 * r.range_m)
    with pytest.raises(InputError, match="fraction"):
        MissionOptions(range_sigma_fraction=-0.1)


def test_random_wsn_links_and_json():
    wsn = random_wsn(np.random.default_rng(0), n_nodes=50, region=box(0, 0, 1, 1), radius=0.2,
                     n_anchors=4)
    a, b = wsn.links.T
    assert np.all(a < b)
    d_true = np.linalg.norm(wsn.positions[a] - wsn.positions[b], axis=1)
    np.testing.assert_allclose(wsn.distance, d_true)
    assert np.all(d_true <= 0.2)
    links, _ = disk_links(wsn.positions, 0.2)
    assert len(links) == len(wsn.links)
    corner = np.hypot(*wsn.positions.T)
    assert set(np.flatnonzero(wsn.anchor)) == set(np.argsort(corner)[:4])
    js = wsn.to_json()
    assert set(js) == {"radius", "nodes", "links"}
    assert sum(n["position"] is not None for n in js["nodes"]) == 4
    assert all(n["position"] is not None for n in wsn.to_json(truth=True)["nodes"])
    assert set(js["links"][0]) == {"a", "b", "distance"}
