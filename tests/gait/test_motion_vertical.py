"""Motion detector (Basso II-B) running sums and the levelling of accelerations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2, quat_from_euler, quat_rotate
from hrtls.gait.motion_detector import RUN, STILL, WALK, MotionDetector, MotionParams, RunningStd
from hrtls.gait.vertical import (
    GravityLevelling,
    LevelledAcceleration,
    from_orientation,
    heading_of,
    rotate,
)


def slow_window_std(t: np.ndarray, x: np.ndarray, window: float) -> tuple[np.ndarray, np.ndarray]:
    mean = np.empty_like(x)
    std = np.empty_like(x)
    for i in range(len(t)):
        sel = x[: i + 1][t[: i + 1] >= t[i] - window]
        mean[i] = sel.mean()
        std[i] = sel.std()
    return mean, std


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 300), seed=st.integers(0, 10_000), split=st.integers(0, 300))
def test_running_std_matches_slow_reference_and_chunks(n: int, seed: int, split: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.03, n))
    x = 9.81 + rng.normal(0, 2, n)
    ref_m, ref_s = slow_window_std(t, x, 0.5)
    rs = RunningStd(window_s=0.5)
    m, s = rs.update(t, x)
    np.testing.assert_allclose(m, ref_m, atol=1e-9)
    np.testing.assert_allclose(s, ref_s, atol=1e-7)
    rs.reset()
    k = min(split, n)
    _m1, s1 = rs.update(t[:k], x[:k])
    state = rs.state.to_dict()
    rs2 = RunningStd(window_s=0.5)
    rs2.state = type(rs.state).from_dict(state)
    _m2, s2 = rs2.update(t[k:], x[k:])
    np.testing.assert_allclose(np.concatenate([s1, s2]), s, atol=1e-12)


def test_motion_states_follow_thresholds() -> None:
    t = np.arange(0, 30, 0.01)
    amp = np.where(t < 10, 0.1, np.where(t < 20, 3.0, 10.0))
    x = GRAVITY_M_S2 + amp * np.sin(2 * np.pi * 2.0 * t)
    res = MotionDetector().process(t, x)
    assert np.all(res.state[(t > 2) & (t < 10)] == STILL)
    assert np.all(res.state[(t > 12) & (t < 20)] == WALK)  # std = 3/sqrt(2) = 2.1
    assert np.all(res.state[(t > 22)] == RUN)  # std = 7.1 > 5
    assert res.moving[(t > 12)].all()


def test_motion_rejects_bad_thresholds_and_time() -> None:
    with pytest.raises(InputError):
        MotionDetector(MotionParams(still_threshold_m_s2=6.0, run_threshold_m_s2=5.0))
    det = MotionDetector()
    with pytest.raises(InputError):
        det.update(np.array([0.0, 0.0]), np.array([1.0, 2.0]))
    with pytest.raises(InputError):
        det.update(np.array([0.0, 1.0]), np.array([1.0, np.nan]))


@settings(max_examples=50, deadline=None)
@given(r=st.floats(-3, 3), p=st.floats(-1.5, 1.5), y=st.floats(-3, 3))
def test_from_orientation_static_device_reads_zero(r: float, p: float, y: float) -> None:
    q = np.repeat(quat_from_euler(r, p, y)[None, :], 5, axis=0)
    f_n = np.array([0.3, -0.2, GRAVITY_M_S2 + 0.5])
    f_d = quat_rotate(q * np.array([1, -1, -1, -1]), np.repeat(f_n[None], 5, axis=0))
    lev = from_orientation(np.arange(5.0), f_d, q)
    assert isinstance(lev, LevelledAcceleration)
    np.testing.assert_allclose(lev.vertical_m_s2, 0.5, atol=1e-9)
    np.testing.assert_allclose(lev.horizontal_m_s2, [[0.3, -0.2]] * 5, atol=1e-9)


def test_rotate_kernel_matches_frames() -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    v = rng.normal(size=(50, 3))
    np.testing.assert_allclose(rotate(q, v), quat_rotate(q, v), atol=1e-12)
    np.testing.assert_allclose(rotate(q, v[0]), quat_rotate(q, v[0]), atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), spin=st.floats(0.0, 2.0))
def test_heading_kernel_equals_unwrapped_arctan2_of_rotate(seed: int, spin: float) -> None:
    # a yaw that keeps turning (several wraps) with tilt and noise; any device-frame vector
    rng = np.random.default_rng(seed)
    n = 3000
    yaw = np.cumsum(rng.normal(spin, 0.3, n)) * 0.05
    q = quat_from_euler(rng.normal(0.0, 0.2, n), rng.normal(0.0, 0.2, n), yaw)
    v = rng.normal(size=3)
    v[2] *= 0.2   # mostly horizontal, so the heading is defined
    ref = np.unwrap(np.arctan2(*rotate(q, v)[:, 1::-1].T))
    np.testing.assert_allclose(heading_of(q, v), ref, atol=1e-9, rtol=0)


def test_from_orientation_rejects_non_unit() -> None:
    with pytest.raises(InputError, match="row 1"):
        from_orientation(np.arange(2.0), np.zeros((2, 3)), np.array([[1.0, 0, 0, 0], [2, 0, 0, 0]]))


def test_gravity_levelling_tilted_device_and_chunks() -> None:
    q = quat_from_euler(0.4, -0.7, 1.0)
    t = np.arange(0, 20, 0.01)
    vert_true = 1.5 * np.sin(2 * np.pi * 1.8 * t)
    f_n = np.column_stack([0.5 * np.sin(2 * np.pi * 0.9 * t), 0 * t, GRAVITY_M_S2 + vert_true])
    f_d = quat_rotate(np.array(q) * np.array([1, -1, -1, -1]), f_n)
    lev = GravityLevelling()
    out = lev.process(t, f_d)
    late = t > 10
    assert np.max(np.abs(out.vertical_m_s2[late] - vert_true[late])) < 0.3
    # horizontal magnitude is preserved
    np.testing.assert_allclose(np.hypot(*out.horizontal_m_s2[late].T),
                               np.abs(f_n[late, 0]), atol=0.25)
    lev.reset()
    a = lev.update(t[:700], f_d[:700])
    saved = lev.state.to_dict()
    lev2 = GravityLevelling()
    lev2.state = type(lev.state).from_dict(saved)
    b = lev2.update(t[700:], f_d[700:])
    np.testing.assert_allclose(np.concatenate([a.vertical_m_s2, b.vertical_m_s2]),
                               out.vertical_m_s2, atol=1e-12)
