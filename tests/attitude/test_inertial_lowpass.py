"""The inertial low-pass filter (``inertial-lp``): reference, physics, robustness, streaming."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.signal import butter

from hrtls.attitude import (
    InertialLowpass,
    InertialLowpassParams,
    make_filter,
)
from hrtls.attitude import _inertial_lowpass_kernel as ILK
from hrtls.errors import InputError
from hrtls.evaluate.orientation import orientation_errors
from hrtls.frames import GRAVITY_M_S2, quat_angle_between, quat_from_euler, quat_rotate

from ._reference_inertial import inertial_lowpass_reference
from .conftest import FIELD_N, make_motion


def _static(n, rate_hz=100.0, roll=0.1, pitch=-0.2, yaw=0.7, bias=(0.0, 0.0, 0.0), seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    q = quat_from_euler(np.full(n, roll), np.full(n, pitch), np.full(n, yaw))
    acc = quat_rotate(q * [1, -1, -1, -1], np.tile([0.0, 0.0, GRAVITY_M_S2], (n, 1)))
    mag = quat_rotate(q * [1, -1, -1, -1], np.tile(FIELD_N, (n, 1)))
    gyr = np.tile(bias, (n, 1)) + rng.normal(size=(n, 3)) * 1e-4
    return t, acc, gyr, mag, q


# ------------------------------------------------------------------------------ reference
@pytest.mark.parametrize("case", ["motion", "bias", "disturbed"])
def test_matches_slow_reference(case):
    m = make_motion(500, seed=7, bias=0.01 if case == "bias" else 0.0, rest_s=2.0)
    mag = m.mag.copy()
    if case == "disturbed":
        mag[250:400] += [15.0, -5.0, 3.0]
    p = InertialLowpassParams(mag_new_min_rate_rad_s=0.0, mag_new_field_s=1.0,
                              mag_max_rejection_s=0.5, rest_s=0.5)
    f = InertialLowpass(p)
    r = f.update(m.t, m.acc, m.gyr, mag)
    q_ref, var_ref, dist_ref, bias_ref, P_ref = inertial_lowpass_reference(
        m.t, m.acc, m.gyr, mag, f._prm)
    np.testing.assert_allclose(r.q, q_ref, atol=1e-9)
    np.testing.assert_allclose(r.var_rpy, var_ref, rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(r.extra["mag_disturbed"], dist_ref)
    np.testing.assert_allclose(f.state.gyro_bias_rad_s, bias_ref, atol=1e-12)
    np.testing.assert_allclose(f.state.P, P_ref, rtol=1e-8, atol=1e-18)
    if case == "disturbed":
        assert dist_ref[260:300].all() and not dist_ref[:250].any()


def test_butterworth_gains_match_scipy():
    for tau, dt in ((3.0, 0.01), (0.5, 1 / 286.0), (10.0, 0.05)):
        prm = InertialLowpassParams(tau_acc_s=tau).kernel_array()
        x = np.zeros(ILK.NX)
        ILK._set_gains.py_func(x, prm, dt)
        b, a = butter(2, math.sqrt(2) / (2 * math.pi * tau), fs=1 / dt)
        np.testing.assert_allclose([x[ILK.CB0], 2 * x[ILK.CB0], x[ILK.CB0]], b, rtol=1e-12)
        np.testing.assert_allclose([1.0, x[ILK.CA1], x[ILK.CA2]], a, rtol=1e-12)
        assert x[ILK.KMAG] == pytest.approx(1 - math.exp(-dt / 9.0))


# ------------------------------------------------------------------------------ physics
def test_static_attitude_is_exact_and_heading_points_north():
    t, acc, gyr, mag, q = _static(500)
    r = InertialLowpass().update(t, acc, gyr, mag)
    assert r.valid.all() and r.acc_used[1:].all() and r.mag_used[1:].all()
    assert np.max(quat_angle_between(r.q, q)) < 1e-4  # gyro noise 1e-4 rad/s


def test_rest_bias_is_learnt_to_the_true_bias():
    bias = (0.004, -0.006, 0.003)
    t, acc, gyr, mag, _ = _static(3000, bias=bias)
    f = InertialLowpass()
    r = f.update(t, acc, gyr, mag)
    assert r.at_rest[-1000:].all()
    np.testing.assert_allclose(f.state.gyro_bias_rad_s, bias, atol=2e-4)


def test_motion_bias_is_learnt_without_rest():
    """No rest at all: the pseudo-measurement of the inclination correction finds the
    horizontal-frame bias; the estimate is closer to the truth than the initial zero."""
    m = make_motion(6000, seed=4, bias=0.01, rest_s=0.0)
    f = InertialLowpass(InertialLowpassParams(rest_s=1e9))
    r = f.update(m.t, m.acc, m.gyr, m.mag)
    assert not r.at_rest.any()
    # the device stays near level: x and y are horizontal, observable from gravity
    err = np.abs(f.state.gyro_bias_rad_s - 0.01)
    assert np.max(err[:2]) < 0.004
    off = InertialLowpass(InertialLowpassParams(estimate_bias=False)).update(
        m.t, m.acc, m.gyr, m.mag)
    e_on = orientation_errors(r.q[3000:], m.q[3000:])
    e_off = orientation_errors(off.q[3000:], m.q[3000:])
    assert e_on.inclination_rms_rad < e_off.inclination_rms_rad


def test_linear_acceleration_does_not_tilt():
    """Accelerations of 3 m/s^2 (no gate would pass them) barely move the inclination: in the
    inertial frame they average out under the low-pass."""
    m = make_motion(3000, seed=1, accel_amp=3.0, noise=False)
    r = InertialLowpass().update(m.t, m.acc, m.gyr, m.mag)
    e = orientation_errors(r.q[500:], m.q[500:])
    assert np.rad2deg(e.inclination_rms_rad) < 0.3
    assert r.acc_used[1:].all()


def test_magnetic_disturbance_is_rejected_then_timed_out():
    """A field of another norm: the heading holds, the flag rises; after the rejection time
    the gain is back (divided by the rejection factor) and the heading follows the new field."""
    t, acc, gyr, mag, q = _static(6000)
    yaw_err = np.deg2rad(40.0)
    c, s = math.cos(yaw_err), math.sin(yaw_err)
    bad = mag.copy()
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    bad[1000:] = 1.3 * bad[1000:] @ rot.T  # stronger and turned: a magnet
    p = InertialLowpassParams(mag_max_rejection_s=20.0)
    r = InertialLowpass(p).update(t, acc, gyr, bad)
    dist = r.extra["mag_disturbed"]
    assert not dist[:1000].any() and dist[1050:].all()
    assert not r.mag_used[1050:3000].any() and r.mag_used[3100:].all()
    ang = np.rad2deg(quat_angle_between(r.q, q))
    assert np.max(ang[:3000]) < 0.1
    assert ang[-1] > 10.0
    # the heading variance grows while rejected and shrinks again when the field is used
    v = r.var_rpy[:, 2]
    assert v[2990] > v[990] > 0 and v[-1] < v[3000]


def test_new_field_becomes_the_reference_while_turning():
    """A different homogeneous field (another building) is learnt after mag_new_field_s of
    stable readings while the device turns, then used again."""
    m = make_motion(4000, seed=2, amp_rad=1.5)
    mag = m.mag.copy()
    mag[500:] *= 0.8
    p = InertialLowpassParams(mag_new_field_s=10.0, mag_new_first_s=10.0,
                              mag_new_min_rate_rad_s=0.0)
    r = InertialLowpass(p).update(m.t, m.acc, m.gyr, mag)
    dist = r.extra["mag_disturbed"]
    assert dist[600:1400].all()
    assert not dist[1700:].any()
    assert r.mag_used[1700:].all()


def test_heading_converges_when_the_magnetometer_starts_late():
    t, acc, gyr, mag, q = _static(2000)
    f = InertialLowpass()
    f.update(t[:500], acc[:500], gyr[:500], None)
    r = f.update(t[500:], acc[500:], gyr[500:], mag[500:])
    assert np.max(quat_angle_between(r.q[5:], q[505:])) < 1e-4


# ------------------------------------------------------------------------------ invariants
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), amp=st.floats(0.0, 3.0), acc_amp=st.floats(0.0, 8.0),
       bias=st.floats(-0.05, 0.05))
def test_unit_quaternion_psd_bias_covariance_and_variances(seed, amp, acc_amp, bias):
    m = make_motion(300, seed=seed, amp_rad=amp, accel_amp=acc_amp, bias=bias)
    f = InertialLowpass()
    r = f.update(m.t, m.acc, m.gyr, m.mag)
    assert np.all(np.isfinite(r.q))
    np.testing.assert_allclose(np.linalg.norm(r.q, axis=1), 1.0, atol=1e-12)
    assert np.all(r.q[:, 0] >= 0)
    P = f.state.P
    np.testing.assert_allclose(P, P.T, atol=1e-18)
    assert np.min(np.linalg.eigvalsh(P)) > -1e-15
    assert np.all((r.var_rpy > 0) & (r.var_rpy <= math.pi ** 2))
    assert np.all(np.abs(f.state.gyro_bias_rad_s) <= f.params.bias_clip_rad_s)


def test_gap_restarts_the_lowpass():
    t, acc, gyr, _, _ = _static(400)
    t = t.copy()
    t[200:] += 5.0  # longer than max_dt_s
    q2 = quat_from_euler(np.full(200, 0.3), np.full(200, 0.1), np.full(200, 0.7))
    acc = acc.copy()
    acc[200:] = quat_rotate(q2 * [1, -1, -1, -1], np.tile([0.0, 0.0, GRAVITY_M_S2], (200, 1)))
    r = InertialLowpass().update(t, acc, gyr, None)
    # after the gap the filtered gravity is the new one at once, not a 3 s blend
    assert np.rad2deg(orientation_errors(r.q[201:], q2[1:], remove_heading_offset=True)
                      .inclination_rms_rad) < 0.05


# ------------------------------------------------------------------------------ streaming
def test_reset_equals_a_fresh_filter_and_var_streams(motion):
    """(Chunks, save/restore: the shared tests of test_attitude_filters.)"""
    f = make_filter("inertial-lp")
    half = f.update(motion.t[:300], motion.acc[:300], motion.gyr[:300], motion.mag[:300])
    rest = f.update(motion.t[300:], motion.acc[300:], motion.gyr[300:], motion.mag[300:])
    fresh = make_filter("inertial-lp").update(motion.t, motion.acc, motion.gyr, motion.mag)
    np.testing.assert_array_equal(np.vstack([half.var_rpy, rest.var_rpy]), fresh.var_rpy)
    f.reset()
    assert not f.state.initialized
    np.testing.assert_array_equal(
        f.update(motion.t, motion.acc, motion.gyr, motion.mag).q, fresh.q)
    with pytest.raises(InputError):
        make_filter("quat-ekf").restore(f.state)


def test_invalid_params_raise():
    for kw in ({"tau_acc_s": 0.0}, {"tau_mag_s": -1.0}, {"bias_vertical_forgetting": 2.0},
               {"mag_new_min_rate_rad_s": -0.1}, {"mag_rejection_factor": math.nan}):
        with pytest.raises(InputError):
            InertialLowpassParams(**kw)
    InertialLowpassParams(tau_mag_s=math.inf, mag_new_min_rate_rad_s=0.0)
