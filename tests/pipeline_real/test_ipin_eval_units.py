"""Unit and property tests of hrtls.jobs.ipin_eval (no real data needed)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import (
    Checkpoints,
    ImuStream,
    Landmark,
    OrientationSeries,
    RssReadings,
    SensorSeries,
    Session,
    SessionMeta,
    StartPose,
    Trajectory,
)
from hrtls.errors import InputError
from hrtls.frames import quat_rotate
from hrtls.jobs.ipin_eval import (
    FLOOR_PENALTY_M,
    average_rss,
    calibrate_channel,
    handheld_mounting_q_bd,
    landmark_errors,
    landmark_path_length_m,
    make_config,
    prepare_session,
    standard_cases,
    weinberg_k_of,
)


def _acc_tilted(pitch_rad: float, roll_rad: float = 0.0, n: int = 50) -> np.ndarray:
    """Specific force of a still phone pitched (top edge up) by ``pitch_rad``, rolled by roll."""
    g = 9.81
    up_d = np.array([-np.sin(roll_rad), np.sin(pitch_rad) * np.cos(roll_rad),
                     np.cos(pitch_rad) * np.cos(roll_rad)])
    up_d /= np.linalg.norm(up_d)
    return np.tile(g * up_d, (n, 1))


def test_flat_phone_forward_is_device_y() -> None:
    q = handheld_mounting_q_bd(_acc_tilted(0.0))
    # q_bd rotates device vectors into the body frame: device y -> body x, device z -> body z
    np.testing.assert_allclose(quat_rotate(q, np.array([0.0, 1.0, 0.0])), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(quat_rotate(q, np.array([0.0, 0.0, 1.0])), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(quat_rotate(q, np.array([1.0, 0.0, 0.0])), [0, -1, 0], atol=1e-12)


def test_pitched_phone_hand_computed() -> None:
    # pitched by 60 deg: up in device coordinates is (0, sin60, cos60); forward = (0, cos60, -sin60)
    p = np.radians(60.0)
    q = handheld_mounting_q_bd(_acc_tilted(p))
    np.testing.assert_allclose(quat_rotate(q, np.array([0.0, np.sin(p), np.cos(p)])), [0, 0, 1],
                               atol=1e-12)
    np.testing.assert_allclose(quat_rotate(q, np.array([0.0, np.cos(p), -np.sin(p)])),
                               [1, 0, 0], atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.floats(-1.2, 1.2), st.floats(-0.6, 0.6))
def test_mounting_properties(pitch: float, roll: float) -> None:
    acc = _acc_tilted(pitch, roll)
    q = handheld_mounting_q_bd(acc)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    up_b = quat_rotate(q, acc[0] / np.linalg.norm(acc[0]))
    np.testing.assert_allclose(up_b, [0, 0, 1], atol=1e-9)
    y_b = quat_rotate(q, np.array([0.0, 1.0, 0.0]))
    assert abs(y_b[1]) < 1e-9 and y_b[0] > 0  # device top edge: forward, in the x-z plane


def test_mounting_rejects_bad_input() -> None:
    with pytest.raises(InputError):
        handheld_mounting_q_bd(np.zeros((0, 3)))
    with pytest.raises(InputError):
        handheld_mounting_q_bd(np.full((3, 3), np.nan))
    with pytest.raises(InputError):
        handheld_mounting_q_bd(np.zeros((10, 3)))
    with pytest.raises(InputError):  # phone upright: device y is vertical
        handheld_mounting_q_bd(np.tile([0.0, 9.81, 0.0], (5, 1)))


def _session() -> Session:
    t = np.arange(0.0, 10.0, 0.02)
    acc = SensorSeries(t, np.tile([0.0, 8.0, 5.7], (len(t), 1)), "acc")
    lms = {"A": Landmark(id="A", kind="beacon", position=(5.0, 0.0, 0.0), floor=0),
           "B": Landmark(id="B", kind="beacon", position=(0.0, 5.0, -6.0), floor=-2)}
    rss = RssReadings(np.array([1.0, 2.0, 3.0]), np.array(["A", "B", "X"]),
                      np.array([-70.0, -80.0, -90.0]))
    cps = Checkpoints(np.array([5.0, 9.0]), np.array([[3.0, 4.0, 0.0], [3.0, 0.0, 0.0]]),
                      np.array(["2", "3"]))
    meta = SessionMeta(start_pose=StartPose(x=0.0, y=0.0, z=0.0))
    return Session(meta=meta, imu=ImuStream(acc), rss=rss, landmarks=lms, checkpoints=cps)


def test_prepare_session_floors_and_mounting() -> None:
    s = _session()
    same = prepare_session(s)
    assert same.rss is not None and same.rss.anchor.tolist() == ["A"]
    assert same.meta.mounting_q_bd is not None
    every = prepare_session(s, mounting="unknown", rss_floors="all")
    assert every.rss is not None and len(every.rss) == 3
    assert every.meta.mounting_q_bd is None
    assert s.meta.mounting_q_bd is None and s.rss is not None and len(s.rss) == 3  # untouched
    with pytest.raises(InputError):
        prepare_session(s, mounting="waist")  # type: ignore[arg-type]


def test_landmark_errors_hand_computed() -> None:
    s = _session()
    assert s.checkpoints is not None
    traj = Trajectory.build(t=np.array([0.0, 4.0, 6.0]),
                            xyz=np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [6.0, 8.0, 3.2]]))
    e = landmark_errors(traj, s.checkpoints, floor_height_m=3.0)
    # t = 5: halfway (3, 4, 1.6) -> error 0, floor round(0.53) = 1 (missed);
    # t = 9: held at the end (6, 8, 3.2) -> |(3, 8)|, floor 1 (missed)
    np.testing.assert_allclose(e.horizontal_m, [0.0, np.hypot(3.0, 8.0)], atol=1e-12)
    assert e.floor_estimated.tolist() == [1, 1] and e.floor_hits == 0
    np.testing.assert_allclose(e.ipin_errors_m, e.horizontal_m + FLOOR_PENALTY_M)
    assert e.stats.n == 2 and e.stats.max == pytest.approx(np.hypot(3.0, 8.0))
    assert landmark_path_length_m(s) == pytest.approx(5.0 + 4.0)
    with pytest.raises(InputError):
        landmark_errors(traj, s.checkpoints, floor_height_m=0.0)


def test_cases_and_configs() -> None:
    cases = standard_cases(0.5)
    assert len({c.name for c in cases}) == len(cases)
    assert all(weinberg_k_of(c.config) == 0.5 for c in cases)
    assert weinberg_k_of(make_config()) == pytest.approx(0.45)
    assert make_config(rss="tight").rss.mode == "tight"


def test_declination_turns_the_orientation() -> None:
    t = np.array([0.0, 1.0])
    q = np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))  # device axes = ENU
    s = _session()
    s = Session(meta=s.meta, imu=s.imu, orientation=OrientationSeries(t, q), rss=s.rss,
                landmarks=s.landmarks, checkpoints=s.checkpoints)
    out = prepare_session(s, declination_rad=np.radians(10.0))
    assert out.orientation is not None
    # device y points to magnetic north = 10 deg east of true north: ENU yaw 80 deg
    y_n = quat_rotate(out.orientation.q, np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(np.degrees(np.arctan2(y_n[:, 1], y_n[:, 0])), 80.0, atol=1e-9)
    with pytest.raises(InputError):
        prepare_session(s, declination_rad=float("nan"))


def test_average_rss_hand_computed() -> None:
    rss = RssReadings(np.array([0.0, 0.5, 1.0, 2.5, 3.9, 4.1]),
                      np.array(["A", "B", "A", "A", "B", "A"]),
                      np.array([-70.0, -80.0, -74.0, -60.0, -90.0, -50.0]))
    out = average_rss(rss, 2.0)
    # windows [0, 2), [2, 4), [4, 6): A -> -72 @ 1.0, -60 @ 2.5, -50 @ 4.1; B -> -80 @ 0.5,
    # -90 @ 3.9
    got = sorted(zip(out.t.tolist(), out.anchor.tolist(), out.rss_dbm.tolist(), strict=True))
    assert got == [(0.5, "B", -80.0), (1.0, "A", -72.0), (2.5, "A", -60.0),
                   (3.9, "B", -90.0), (4.1, "A", -50.0)]
    assert np.all(np.diff(out.t) >= 0)
    with pytest.raises(InputError):
        average_rss(rss, 0.0)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.5, 5.0), st.integers(1, 40), st.integers(0, 2**31 - 1))
def test_average_rss_properties(window: float, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 20, n))
    rss = RssReadings(t, rng.choice(np.array(["A", "B", "C"]), n), rng.uniform(-100, -40, n))
    out = average_rss(rss, window)
    assert 1 <= len(out) <= n
    assert out.rss_dbm.min() >= rss.rss_dbm.min() - 1e-9
    assert out.rss_dbm.max() <= rss.rss_dbm.max() + 1e-9
    assert set(out.t.tolist()) <= set(t.tolist())  # stamped with a real reading time


def test_calibrate_channel_recovers_a_synthetic_law() -> None:
    rng = np.random.default_rng(3)
    base = _session()
    # walk start (0, 0) -> (3, 4) at t = 5 -> (3, 0) at t = 9; beacon A at (5, 0)
    t = np.sort(rng.uniform(0.0, 9.0, 400))
    xy = np.column_stack([np.interp(t, [0, 5, 9], [0, 3, 3]), np.interp(t, [0, 5, 9], [0, 4, 0])])
    d = np.linalg.norm(xy - [5.0, 0.0], axis=1)
    rss = -65.0 - 10.0 * 2.2 * np.log10(d) + rng.normal(0.0, 1.0, t.size)
    meta = base.meta.model_copy(update={"source": {"start_pose_t_s": 0.0}})
    s = Session(meta=meta, imu=base.imu, rss=RssReadings(t, np.full(t.size, "A"), rss),
                landmarks=base.landmarks, checkpoints=base.checkpoints)
    ch = calibrate_channel(s)
    assert ch.a_dbm == pytest.approx(-65.0, abs=0.5)
    assert ch.eta == pytest.approx(2.2, abs=0.1)
    assert ch.sigma_db == pytest.approx(1.0, abs=0.2)
    # a law without distance dependence is clamped at eta = 1 with A refitted
    flat = Session(meta=meta, imu=base.imu,
                   rss=RssReadings(t, np.full(t.size, "A"), np.full(t.size, -80.0)),
                   landmarks=base.landmarks, checkpoints=base.checkpoints)
    ch2 = calibrate_channel(flat)
    assert ch2.eta == 1.0
    assert ch2.a_dbm == pytest.approx(-80.0 + 10.0 * np.mean(np.log10(d)), abs=1e-6)
    s2 = prepare_session(s, rss_window_s=1.0, channel=ch)
    assert s2.meta.channel == ch and s2.rss is not None and len(s2.rss) < t.size
    with pytest.raises(InputError):
        prepare_session(s, rss_window_s=-1.0)
