"""Tests that keep the simulator honest (issue 3 item 7)."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.frames import (
    GRAVITY_M_S2,
    quat_angle_between,
    quat_conjugate,
    quat_from_euler,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)
from hrtls.sim.devices import get_device
from hrtls.sim.gait_model import GaitParams, simulate_gait
from hrtls.sim.imu_model import BodyKinematics, body_kinematics, ideal_imu, simulate_imu
from hrtls.sim.motion_truth import Waypoint, simulate_motion
from hrtls.sim.scenarios import mounting_quaternion, run_scenario


def _walk(rate_hz: float = 100.0, seed: int = 0) -> tuple:
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=30.0, y=0.0, corner_radius_m=1.0),
           Waypoint(x=30.0, y=20.0, stop_s=4.0, corner_radius_m=0.0, speed_m_s=1.4),
           Waypoint(x=0.0, y=20.0, run=True, speed_m_s=2.8, corner_radius_m=2.0),
           Waypoint(x=0.0, y=0.0, speed_m_s=1.0, corner_radius_m=0.5),
           Waypoint(x=25.0, y=5.0, speed_m_s=1.2)]
    wps = wps + [Waypoint(x=w.x + 0.5, y=w.y + 0.5, z=w.z, speed_m_s=w.speed_m_s, run=w.run,
                          stop_s=w.stop_s, corner_radius_m=w.corner_radius_m) for w in wps]
    motion = simulate_motion(wps, rate_hz=rate_hz)
    gait = simulate_gait(motion, GaitParams(), np.random.default_rng(seed))
    return motion, gait, body_kinematics(motion, gait)


@pytest.fixture(scope="module")
def walk() -> tuple:
    return _walk()


def _nav_accel(imu, q_nd):
    return quat_rotate(q_nd, imu.specific_force) - np.array([0.0, 0.0, GRAVITY_M_S2])


def test_walk_lasts_minutes(walk):
    motion, _, _ = walk
    assert motion.t[-1] > 180.0
    assert motion.distance_m > 200.0


def test_noiseless_imu_integrates_to_truth_verlet(walk):
    motion, _, kin = walk
    imu = ideal_imu(kin)
    a = _nav_accel(imu, imu.q_nd)
    dt = motion.dt
    p = np.empty_like(kin.position)
    p[:2] = kin.position[:2]
    for k in range(1, len(p) - 1):  # Stormer-Verlet, the rule the simulator differentiates by
        p[k + 1] = 2 * p[k] - p[k - 1] + a[k] * dt * dt
    assert np.max(np.abs(p - kin.position)) < 1e-6


def test_noiseless_imu_integrates_to_truth_trapezoid(walk):
    motion, _, kin = walk
    imu = ideal_imu(kin)
    a = _nav_accel(imu, imu.q_nd)
    dt = motion.dt
    v0 = (kin.position[1] - kin.position[0]) / dt
    v = v0 + np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (a[1:] + a[:-1]) * dt, axis=0)])
    p = kin.position[0] + np.vstack([np.zeros((1, 3)),
                                     np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, axis=0)])
    assert np.max(np.linalg.norm(p - kin.position, axis=1)) < 0.05  # centimetres over minutes


def test_gyroscope_integrates_to_attitude(walk):
    motion, _, kin = walk
    imu = ideal_imu(kin)
    w = imu.angular_rate
    dt = motion.dt
    # rotation increments of the trapezoid rate; composed by a tree-free cumulative product
    inc = quat_from_rotvec(0.5 * (w[1:] + w[:-1]) * dt)
    q = np.empty_like(kin.q_nb)
    q[0] = kin.q_nb[0]
    for k in range(len(inc)):
        q[k + 1] = quat_multiply(q[k], inc[k])
    q = quat_normalize(q)
    assert np.max(quat_angle_between(q, kin.q_nb)) < 0.02
    assert quat_angle_between(q[-1], kin.q_nb[-1]) < 5e-3


def test_specific_force_at_rest_is_gravity(walk):
    motion, _, kin = walk
    imu = ideal_imu(kin, q_bd=mounting_quaternion("rotated", np.random.default_rng(0)))
    rest = motion.speed == 0
    rest[1:-1] &= (motion.speed[:-2] == 0) & (motion.speed[2:] == 0)
    # a stop's last step and closing movement move the standing waist (hrtls.sim.stop_model)
    still = np.all(np.diff(kin.position, axis=0) == 0.0, axis=1)
    rest[1:-1] &= still[:-1] & still[1:]
    norms = np.linalg.norm(imu.specific_force[rest], axis=1)
    assert rest.sum() > 500
    np.testing.assert_allclose(norms, GRAVITY_M_S2, atol=1e-6)
    f_n = quat_rotate(imu.q_nd[rest], imu.specific_force[rest])
    np.testing.assert_allclose(f_n.mean(axis=0), [0, 0, GRAVITY_M_S2], atol=1e-6)


def test_noisy_device_at_rest_averages_to_gravity():
    _, _, kin = _walk(rate_hz=100.0, seed=1)
    sim = simulate_imu(kin, get_device("mpu6150_phone"), np.random.default_rng(2))
    t, acc, _, _ = sim.imu.aligned()
    rest = t < 2.5  # the start pause
    bias = sim.realizations["accelerometer"].bias
    mean_norm = float(np.linalg.norm(acc[rest].mean(axis=0)))
    assert abs(mean_norm - GRAVITY_M_S2) < 3 * np.linalg.norm(bias) + 0.2


def test_true_steps_add_up_to_distance(walk):
    motion, gait, _ = walk
    steps = gait.steps
    assert steps.distance_m == pytest.approx(motion.distance_m, rel=1e-9)
    # steps tile the walking time: each ends where the next starts within a run
    assert np.all(steps.t_end > steps.t_start)
    assert np.all(np.diff(steps.t_start) > 0)
    # lengths follow l = 0.32 + 0.26 v for walking (running: its own law), within variability
    walking = steps.activity == 1
    mid_v = np.interp(0.5 * (steps.t_start + steps.t_end), motion.t, motion.speed)
    expected = 0.32 + 0.26 * mid_v
    inner = walking & (mid_v > 0.9)
    ratio = steps.length_m[inner] / expected[inner]
    assert abs(np.median(ratio) - 1.0) < 0.05
    assert np.all(np.abs(ratio - 1.0) < 0.3)


def test_heel_strikes_are_vertical_acceleration_peaks(walk):
    motion, gait, kin = walk
    imu = ideal_imu(kin)
    up = imu.accel_n[:, 2]
    cruise = (motion.speed > 1.1) & (motion.activity == 1)
    idx = np.flatnonzero(cruise)
    # the bounce is lowest at heel strike (integer phase): the vertical acceleration is highest
    frac = np.mod(gait.phase[idx], 1.0)
    near = (frac < 0.08) | (frac > 0.92)
    mid = np.abs(frac - 0.5) < 0.08
    assert up[idx[near]].mean() > up[idx[mid]].mean() + 1.0


@pytest.mark.parametrize("placement", ["pocket", "rotated", "random"])
def test_mounting_changes_axes_not_physics(walk, placement):
    _, _, kin = walk
    base = ideal_imu(kin)
    q_bd = mounting_quaternion(placement, np.random.default_rng(5))
    other = ideal_imu(kin, q_bd=q_bd)
    if placement != "belt":
        assert np.max(np.abs(other.specific_force - base.specific_force)) > 1.0
    np.testing.assert_allclose(np.linalg.norm(other.specific_force, axis=1),
                               np.linalg.norm(base.specific_force, axis=1), atol=1e-9)
    np.testing.assert_allclose(quat_rotate(q_bd, other.specific_force), base.specific_force,
                               atol=1e-9)
    np.testing.assert_allclose(quat_rotate(q_bd, other.angular_rate), base.angular_rate,
                               atol=1e-9)
    np.testing.assert_allclose(quat_rotate(other.q_nd, other.specific_force),
                               quat_rotate(base.q_nd, base.specific_force), atol=1e-9)


def test_lever_arm_device_track_integrates():
    t = np.arange(0.0, 20.0, 0.01)
    yaw = 0.3 * np.sin(1.1 * t) + 0.2 * t
    pos = np.column_stack([np.cos(0.2 * t) * 3, np.sin(0.2 * t) * 3, 0.01 * np.sin(t)])
    kin = BodyKinematics(t=t, position=pos, q_nb=quat_from_euler(0.1 * np.sin(t), 0.0 * t, yaw))
    arm = np.array([0.1, 0.15, -0.05])
    imu = ideal_imu(kin, lever_arm_b=arm)
    a = _nav_accel(imu, imu.q_nd)
    p = np.empty_like(pos)
    p[:2] = imu.device_position[:2]
    for k in range(1, len(p) - 1):
        p[k + 1] = 2 * p[k] - p[k - 1] + a[k] * 1e-4
    assert np.max(np.abs(p - imu.device_position)) < 1e-6
    np.testing.assert_allclose(imu.device_position - pos, quat_rotate(kin.q_nb, arm), atol=1e-12)


def test_body_rate_of_constant_rotation():
    t = np.arange(0.0, 5.0, 0.02)
    w_true = np.array([0.2, -0.1, 0.5])
    q = quat_from_rotvec(t[:, None] * w_true)
    from hrtls.sim.imu_model import body_rate

    np.testing.assert_allclose(body_rate(t, q), np.broadcast_to(w_true, (len(t), 3)), atol=1e-9)
    # body rate rotated by the attitude is the world rate of a rotation about a fixed axis
    np.testing.assert_allclose(quat_rotate(quat_conjugate(q), w_true),
                               np.broadcast_to(w_true, (len(t), 3)), atol=1e-9)


@pytest.mark.parametrize("name", ["colombo_square", "inderst_ring"])
def test_seeded_runs_are_reproducible(name):
    a = run_scenario(name, 7)
    b = run_scenario(name, 7)
    c = run_scenario(name, 8)
    np.testing.assert_array_equal(a.session.imu.accel.values, b.session.imu.accel.values)
    np.testing.assert_array_equal(a.session.imu.accel.t, b.session.imu.accel.t)
    np.testing.assert_array_equal(a.session.truth.xyz, b.session.truth.xyz)
    np.testing.assert_array_equal(a.true_steps.t_end, b.true_steps.t_end)
    assert not np.array_equal(a.session.imu.accel.values[:1000],
                              c.session.imu.accel.values[:1000])


def test_no_weinberg_constant_fits_the_simulated_person(walk):
    """Raw step peak-to-peak follows no Weinberg K: the fitted K changes with speed."""
    from hrtls.sim.gait_model import fill_step_extremes

    motion, gait, kin = walk
    imu = ideal_imu(kin)
    steps = fill_step_extremes(gait.steps, motion.t, imu.accel_n[:, 2])
    v = np.interp(0.5 * (steps.t_start + steps.t_end), motion.t, motion.speed)
    walking = steps.activity == 1
    k_fit = steps.length_m / (steps.acc_max - steps.acc_min) ** 0.25
    slow = np.median(k_fit[walking & (v > 0.95) & (v < 1.05)])
    fast = np.median(k_fit[walking & (v > 1.35) & (v < 1.45)])
    assert abs(fast / slow - 1.0) > 0.03


def test_persons_differ_and_repeat_with_the_seed():
    base = GaitParams()
    a = base.drawn(np.random.default_rng([3, 16]))
    b = base.drawn(np.random.default_rng([3, 16]))
    c = base.drawn(np.random.default_rng([4, 16]))
    assert a == b and a != c
    assert 0.87 <= a.vertical_pp_1ms_m_s2 / base.vertical_pp_1ms_m_s2 <= 1.13
    assert abs(a.vertical_pp_exponent - base.vertical_pp_exponent) <= 0.12


def test_noiseless_device_streams_equal_ideal_signals(walk):
    from hrtls.sim.magnetic import MagneticEnvironment

    _, _, kin = walk
    dev = get_device("mpu6150_phone")  # magnetometer at 50 Hz, accelerometer at 100 Hz
    sim = simulate_imu(kin, dev, np.random.default_rng(0), noiseless=True,
                       magnetic=MagneticEnvironment(), with_orientation=True,
                       q_bd=mounting_quaternion("pocket", np.random.default_rng(0)))
    np.testing.assert_allclose(sim.imu.accel.values, sim.ideal.specific_force, atol=1e-12)
    np.testing.assert_allclose(sim.imu.gyro.values, sim.ideal.angular_rate, atol=1e-12)
    assert sim.imu.mag.rate_hz == pytest.approx(50.0)
    # the magnetometer sees the Earth field rotated into the device frame
    field = MagneticEnvironment().earth.vector_enu()
    q = sim.orientation.q[::2][: len(sim.imu.mag.t)]
    np.testing.assert_allclose(quat_rotate(q, sim.imu.mag.values), np.broadcast_to(
        field, (len(q), 3)), atol=0.05)
