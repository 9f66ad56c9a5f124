"""The sensor-fusion filters: reference agreement, invariants, robustness, streaming.

``ALL`` tests run for every registered filter; ``METHODS`` ones need the accelerometer gate of
the three gated filters (``inertial-lp`` has its own tests in ``test_inertial_lowpass``).
"""

from __future__ import annotations

import itertools
import json
import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hrtls.attitude import (
    AttitudeResult,
    AttitudeState,
    ComplementaryFilter,
    ComplementaryParams,
    EulerEkf,
    EulerEkfParams,
    QuatEkf,
    QuatEkfParams,
    make_filter,
)
from hrtls.attitude import _kernels as K
from hrtls.attitude import _quaternion as Q
from hrtls.data import ImuStream, SensorSeries
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import quat_angle_between, quat_from_euler, quat_to_rotation

from . import _reference as ref
from .conftest import make_motion

METHODS = ["euler-ekf", "quat-ekf", "complementary"]
ALL = [*METHODS, "inertial-lp"]


def run(method, m, params=None, **kw):
    f = make_filter(method, params)
    return f, f.update(m.t, m.acc, m.gyr, m.mag, **kw)


# ------------------------------------------------------------------------------ reference
@pytest.mark.parametrize("mode", ["horizontal", "vector"])
@pytest.mark.parametrize("bias_state", [True, False])
@pytest.mark.parametrize("dyn_s", [0.0, 0.1])
def test_quat_ekf_matches_reference(motion, mode, bias_state, dyn_s):
    p = QuatEkfParams(mag_mode=mode, bias_in_state=bias_state, acc_gate_m_s2=1.5,
                      dyn_acc_corr_s=dyn_s)
    n = 400
    f = QuatEkf(p)
    r = f.update(motion.t[:n], motion.acc[:n], motion.gyr[:n], motion.mag[:n])
    q_ref, flags, P_ref, aux_ref = ref.quat_ekf_reference(
        motion.t[:n], motion.acc[:n], motion.gyr[:n], motion.mag[:n], f._prm)
    np.testing.assert_array_equal(r.flags, flags)
    np.testing.assert_allclose(r.q, q_ref, atol=1e-9)
    np.testing.assert_allclose(f.state.P, P_ref, atol=1e-9)
    keep = np.r_[0:K.AUX_N_ACC_REJ, K.AUX_N + 1:K.AUX_SIZE]  # the reference does not count
    np.testing.assert_allclose(f.state.aux[keep], aux_ref[keep], atol=1e-9)


@pytest.mark.parametrize("exact", [True, False])
@pytest.mark.parametrize("dyn_s", [0.0, 0.1])
def test_euler_ekf_matches_reference(motion, exact, dyn_s):
    n = 400
    yaw = np.full(n, np.nan)
    yaw[150::50] = 0.3
    f = EulerEkf(EulerEkfParams(acc_gate_m_s2=1.5, exact_propagation=exact,
                                dyn_acc_corr_s=dyn_s))
    r = f.update(motion.t[:n], motion.acc[:n], motion.gyr[:n], motion.mag[:n], yaw_rad=yaw)
    th_ref, var_ref = ref.euler_ekf_reference(
        motion.t[:n], motion.acc[:n], motion.gyr[:n], motion.mag[:n], f._prm, yaw=yaw)
    np.testing.assert_allclose(np.column_stack(r.euler), th_ref, atol=1e-9)
    np.testing.assert_allclose(r.var_rpy, var_ref, atol=1e-12)


def test_complementary_matches_reference(motion):
    n = 400
    f = ComplementaryFilter(ComplementaryParams(acc_gate_m_s2=1.5))
    r = f.update(motion.t[:n], motion.acc[:n], motion.gyr[:n], motion.mag[:n])
    q_ref = ref.complementary_reference(motion.t[:n], motion.acc[:n], motion.gyr[:n],
                                        motion.mag[:n], f._prm)
    np.testing.assert_allclose(r.q, q_ref, atol=1e-9)


# ------------------------------------------------------------------------------ accuracy
@pytest.mark.parametrize("method", ALL)
def test_static_initialisation_matches_truth(method):
    m = make_motion(50, seed=5, noise=False, rest_s=10.0)
    _, r = run(method, m)
    ang = quat_angle_between(r.q, m.q)
    assert r.valid.all()
    assert np.max(ang) < 1e-6


@pytest.mark.parametrize("method", METHODS)
def test_gyro_integration_matches_scipy(method):
    """Noise-free gyro with all corrections gated out: the product of scipy rotations."""
    m = make_motion(300, seed=2, noise=False, rest_s=0.05)
    p = make_filter(method).params_type(acc_gate_m_s2=1e-12, estimate_bias=False)
    # initialise on a clean first sample, then gate everything
    acc = m.acc.copy()
    acc[1:] *= 1.5
    f = make_filter(method, p)
    r = f.update(m.t, acc, m.gyr, None)
    rot = quat_to_rotation(r.q[0])  # heading of the shortest-arc initialisation
    expected = [rot]
    for i in range(1, len(m.t)):
        rot = rot * Rotation.from_rotvec(m.gyr[i] * (m.t[i] - m.t[i - 1]))
        expected.append(rot)
    q_exp = np.array([(e.as_quat()[[3, 0, 1, 2]]) for e in expected])
    tol = 1e-7  # arccos resolution near 0 is ~3e-8
    assert np.max(quat_angle_between(r.q, q_exp)) < tol


def test_euler_ekf_first_order_step_is_close():
    """Colombo eq. 5 integrates the angles to first order: an O(dt) drift from exact."""
    m = make_motion(300, seed=2, noise=False, rest_s=0.05)
    acc = m.acc.copy()
    acc[1:] *= 1.5
    p = {"acc_gate_m_s2": 1e-12, "estimate_bias": False}
    a = EulerEkf(EulerEkfParams(**p)).update(m.t, acc, m.gyr, None)
    b = EulerEkf(EulerEkfParams(exact_propagation=False, **p)).update(m.t, acc, m.gyr, None)
    ang = quat_angle_between(a.q, b.q)
    assert 1e-4 < np.max(ang) < 2e-2


@pytest.mark.parametrize("method", ALL)
def test_tracks_noisy_motion(method, motion):
    _, r = run(method, motion)
    ang = np.rad2deg(quat_angle_between(r.q, motion.q))
    assert np.sqrt(np.mean(ang[100:] ** 2)) < 3.0


@pytest.mark.parametrize("method", ["quat-ekf", "complementary"])
def test_gyro_bias_is_learnt(method):
    m = make_motion(3000, seed=4, bias=0.02, rest_s=3.0)
    f, r = run(method, m)
    assert np.all(np.abs(f.state.gyro_bias_rad_s - 0.02) < 0.01)
    ang = np.rad2deg(quat_angle_between(r.q, m.q))
    assert np.sqrt(np.mean(ang[-1000:] ** 2)) < 3.0


def test_yaw_pseudo_measurement_pulls_yaw(motion):
    """Without a magnetometer the heading starts wrong; true yaw readings correct it."""
    from hrtls.frames import euler_from_quat, wrap_angle

    n = 400
    true_yaw = euler_from_quat(motion.q[:n])[2]
    yaw = np.full(n, np.nan)
    yaw[200::10] = true_yaw[200::10]
    p = EulerEkfParams(yaw_var_rad2=1e-3)
    r = EulerEkf(p).update(motion.t[:n], motion.acc[:n], motion.gyr[:n], None, yaw_rad=yaw)
    assert abs(wrap_angle(r.yaw[150] - true_yaw[150])) > 0.1
    assert np.all(np.abs(wrap_angle(r.yaw[-50:] - true_yaw[-50:])) < 0.05)


# ------------------------------------------------------------------------------ invariants
finite = st.floats(-50, 50, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), method=st.sampled_from(ALL),
       amp=st.floats(0.0, 3.0), acc_amp=st.floats(0.0, 8.0))
def test_unit_quaternion_and_psd_covariance(seed, method, amp, acc_amp):
    m = make_motion(200, seed=seed, amp_rad=amp, accel_amp=acc_amp)
    f, r = run(method, m)
    assert np.all(np.isfinite(r.q))
    np.testing.assert_allclose(np.linalg.norm(r.q, axis=1), 1.0, atol=1e-12)
    assert np.all(r.q[:, 0] >= 0)
    P = f.state.P
    if P.size:
        np.testing.assert_allclose(P, P.T, atol=1e-15)
        assert np.min(np.linalg.eigvalsh(P)) > -1e-12
        assert np.all(r.var_rpy >= -1e-12)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), method=st.sampled_from(ALL),
       data=st.data())
def test_no_nan_leaves_with_bad_samples(seed, method, data):
    m = make_motion(150, seed=seed)
    rng = np.random.default_rng(seed)
    acc, gyr, mag = m.acc.copy(), m.gyr.copy(), m.mag.copy()
    bad = data.draw(st.lists(st.sampled_from([np.nan, np.inf, -np.inf, 1e6, 0.0]),
                             min_size=1, max_size=30))
    for v in bad:
        arr = [acc, gyr, mag][rng.integers(3)]
        arr[rng.integers(len(arr)), rng.integers(3)] = v
    _f, r = run(method, type(m)(m.t, acc, gyr, mag, m.q))
    assert np.all(np.isfinite(r.q))
    if r.var_rpy is not None:
        assert np.all(np.isfinite(r.var_rpy))
    assert all(np.all(np.isfinite(v)) for v in r.extra.values())
    n_bad = int(np.sum(~np.isfinite(acc).all(1) | ~np.isfinite(gyr).all(1)
                       | ~np.isfinite(mag).all(1) | (np.abs(gyr) >= 35).any(1)
                       | (np.linalg.norm(acc, axis=1) >= 16 * 9.80665)
                       | (np.linalg.norm(acc, axis=1) <= 1e-6)))
    assert r.rejected["bad"] == n_bad
    # every non-finite accelerometer sample is counted as rejected
    assert r.rejected["acc"] >= int(np.sum(~np.isfinite(acc).all(1)))


@pytest.mark.parametrize("method", ALL)
def test_all_nan_input_gives_identity_and_counts(method):
    n = 20
    t = np.arange(n) * 0.01
    nan = np.full((n, 3), np.nan)
    r = make_filter(method).update(t, nan, nan, nan)
    np.testing.assert_array_equal(r.q, np.tile([1.0, 0, 0, 0], (n, 1)))
    assert not r.valid.any()
    assert r.rejected == {"acc": n, "mag": n, "gyro": 0, "bad": n}


# ------------------------------------------------------------------------------ streaming
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(method=st.sampled_from(ALL),
       cuts=st.lists(st.integers(1, 299), max_size=6, unique=True))
def test_chunked_update_equals_batch(method, cuts):
    m = make_motion(300, seed=11)
    batch = make_filter(method).update(m.t, m.acc, m.gyr, m.mag)
    f = make_filter(method)
    edges = [0, *sorted(cuts), 300]
    parts = [f.update(m.t[a:b], m.acc[a:b], m.gyr[a:b], m.mag[a:b])
             for a, b in itertools.pairwise(edges) if b > a]
    joined = AttitudeResult.concatenate(parts)
    np.testing.assert_array_equal(joined.q, batch.q)
    np.testing.assert_array_equal(joined.flags, batch.flags)
    assert joined.rejected == batch.rejected


@pytest.mark.parametrize("method", ALL)
def test_state_save_restore_continues_identically(method, motion):
    f = make_filter(method)
    f.update(motion.t[:300], motion.acc[:300], motion.gyr[:300], motion.mag[:300])
    saved = json.loads(json.dumps(f.state.to_dict()))
    rest = f.update(motion.t[300:], motion.acc[300:], motion.gyr[300:], motion.mag[300:])
    g = make_filter(method)
    g.restore(AttitudeState.from_dict(saved))
    again = g.update(motion.t[300:], motion.acc[300:], motion.gyr[300:], motion.mag[300:])
    np.testing.assert_array_equal(rest.q, again.q)
    g.reset()
    assert not g.state.initialized
    assert np.isnan(g.state.t_last_s)


def test_restore_rejects_other_method(motion):
    s = QuatEkf().state
    with pytest.raises(InputError):
        EulerEkf().restore(s)
    with pytest.raises(InputError):
        AttitudeState.from_dict({"method": "quat-ekf"})


@pytest.mark.parametrize("method", ALL)
def test_run_equals_update_on_stream(method, motion):
    imu = ImuStream(SensorSeries(motion.t, motion.acc), SensorSeries(motion.t, motion.gyr),
                    SensorSeries(motion.t, motion.mag))
    f = make_filter(method)
    a = f.run(imu)
    b = make_filter(method).update(motion.t, motion.acc, motion.gyr, motion.mag)
    np.testing.assert_array_equal(a.q, b.q)


# ------------------------------------------------------------------------------ interface
def test_mounting_gives_body_frame(motion):
    q_bd = quat_from_euler(0.0, 0.0, np.pi / 2)[None][0]
    p = QuatEkfParams(mounting_q_bd=tuple(q_bd))
    r_b = QuatEkf(p).update(motion.t, motion.acc, motion.gyr, motion.mag)
    r_d = QuatEkf().update(motion.t, motion.acc, motion.gyr, motion.mag)
    assert r_b.frame == "nb" and r_d.frame == "nd"
    expected = quat_to_rotation(r_d.q) * quat_to_rotation(q_bd).inv()
    np.testing.assert_allclose(quat_angle_between(r_b.q, expected.as_quat()[:, [3, 0, 1, 2]]),
                               0.0, atol=1e-7)


@pytest.mark.parametrize("method", ALL)
def test_bad_time_and_shapes_raise(method, motion):
    f = make_filter(method)
    with pytest.raises(InputError):
        f.update(motion.t[::-1], motion.acc, motion.gyr, motion.mag)
    with pytest.raises(InputError):
        f.update(motion.t, motion.acc[:, :2], motion.gyr, motion.mag)
    t = motion.t.copy()
    t[3] = np.nan
    with pytest.raises(InputError):
        f.update(t, motion.acc, motion.gyr, motion.mag)
    f.update(motion.t[:10], motion.acc[:10], motion.gyr[:10], motion.mag[:10])
    with pytest.raises(InputError, match="time order"):
        f.update(motion.t[:10], motion.acc[:10], motion.gyr[:10], motion.mag[:10])


def test_without_gyro_warns_and_follows_static_sensors(motion):
    with pytest.warns(DegradedInputWarning):
        r = QuatEkf().update(motion.t[:50], motion.acc[:50], None, motion.mag[:50])
    assert r.rejected["gyro"] == 0
    assert not r.gyro_used.any()


def test_invalid_params_raise():
    with pytest.raises(InputError):
        QuatEkfParams(acc_noise=-1.0)
    with pytest.raises(InputError):
        EulerEkfParams(acc_gate_m_s2=0.0)
    with pytest.raises(InputError):
        ComplementaryParams(tau_acc_s=float("nan"))
    with pytest.raises(InputError):
        QuatEkfParams(mounting_q_bd=(2.0, 0.0, 0.0, 0.0))
    with pytest.raises(InputError):
        make_filter("nope")
    with pytest.raises(InputError):
        QuatEkf(EulerEkfParams())


def test_kernel_helpers():
    """Jacobian by complex step, transition by expm, shortest arc, mag heading."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.normal(size=4)
        v = rng.normal(size=3)
        jac = np.empty((3, 4))
        Q.rot_t_jacobian(*q, *v, jac)
        np.testing.assert_allclose(
            jac, ref.complex_step_jacobian(lambda qq, v=v: ref.rot_h(qq).T @ v, q), atol=1e-12)
        w = rng.normal(size=3)
        phi = np.empty((4, 4))
        Q.transition(*w, 0.01, phi)
        from scipy.linalg import expm
        np.testing.assert_allclose(phi, expm(ref.omega(w) * 0.01), atol=1e-14)
        a = rng.normal(size=3)
        a /= np.linalg.norm(a)
        q0 = np.array(Q.shortest_arc_to_up(*a))
        np.testing.assert_allclose(ref.rot_h(q0) @ a, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(Q.shortest_arc_to_up(0.0, 0.0, -1.0), [0, 1, 0, 0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(Q.heading_from_mag(1, 0, 0, 0, 0.0, 0.0, 5.0), [1, 0, 0, 0])


@pytest.mark.parametrize("method", ALL)
def test_unknown_inputs_and_param_layout(method, motion):
    f = make_filter(method)
    with pytest.raises(InputError, match="unexpected inputs"):
        f.update(motion.t[:5], motion.acc[:5], motion.gyr[:5], motion.mag[:5],
                 speed=np.zeros(5))
    assert not f.state.initialized  # nothing was processed
    p = f.params
    prm = p.kernel_array()
    assert prm.shape == (K.PRM_SPECIFIC + len(p.specific_values()),)
    np.testing.assert_array_equal(prm[: K.PRM_SPECIFIC], p.common_array())


def test_param_positivity_rules():
    QuatEkfParams(rate_ref_rad_s=float("inf"))  # inf: constant accelerometer variance
    ComplementaryParams(tau_bias_s=float("inf"))  # inf: no in-motion bias term
    with pytest.raises(InputError, match="gyro_noise_rad_s"):
        QuatEkfParams(gyro_noise_rad_s=float("inf"))
    with pytest.raises(InputError, match="north_var"):
        EulerEkfParams(north_var=0.0)
    with pytest.raises(InputError, match="mag_jump_gate_uT"):
        ComplementaryParams(mag_jump_gate_uT=-1.0)


def test_gyro_quat_step_matches_transition():
    rng = np.random.default_rng(5)
    phi = np.empty((4, 4))
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q *= np.sign(q[0])
        w = rng.normal(size=3) * rng.choice([1e-4, 1.0, 20.0])
        Q.transition(*w, 0.01, phi)
        expected = phi @ q
        expected /= np.linalg.norm(expected) * np.sign(expected[0])
        np.testing.assert_allclose(Q.gyro_quat_step(*q, *w, 0.01), expected, atol=1e-14)
        np.testing.assert_allclose(Q.gyro_quat_step.py_func(*q, *w, 0.01), expected,
                                   atol=1e-14)


def _steady_turn(n: int = 2500, rate: float = 1.9, a_c: float = 3.0):
    """Level device turning at ``rate`` with a constant sideways (centripetal) specific force."""
    t = np.arange(n) / 250.0
    acc = np.tile([0.0, a_c, 9.81], (n, 1))
    gyr = np.tile([0.0, 0.0, rate], (n, 1))
    return t, acc, gyr


def test_euler_ekf_rate_adaptive_acc_variance_limits_turn_tilt():
    # the true roll is 0; the specific force says atan(3 / 9.81) ~ 17 deg
    t, acc, gyr = _steady_turn()
    paper = EulerEkf(EulerEkfParams(rate_ref_rad_s=math.inf, acc_gate_m_s2=math.inf,
                                    dyn_acc_corr_s=0.0))
    ours = EulerEkf(EulerEkfParams(acc_gate_m_s2=math.inf, dyn_acc_corr_s=0.0))
    roll_paper = np.abs(paper.update(t, acc, gyr, None).roll[-1])
    roll_ours = np.abs(ours.update(t, acc, gyr, None).roll[-1])
    assert roll_ours < 0.5 * roll_paper


def test_euler_ekf_rate_ref_inf_is_constant_variance():
    t, acc, gyr = _steady_turn(n=300)
    a = EulerEkf(EulerEkfParams(rate_ref_rad_s=math.inf)).update(t, acc, gyr, None)
    b = EulerEkf(EulerEkfParams(rate_ref_rad_s=1e12)).update(t, acc, gyr, None)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    with pytest.raises(InputError):
        EulerEkfParams(rate_ref_rad_s=0.0)


# ------------------------------------------------------------------------------ walking start
@pytest.mark.parametrize("method", ["euler-ekf"])
def test_walking_start_is_not_pitch(method):
    """Colombo Case A start: the ~1 m/s^2 forward acceleration must stay acceleration.

    With the papers' constant accelerometer noise the Euler EKF turned half of it into pitch
    (levelled forward acceleration ~0.55 of the truth); the variance of the body's
    acceleration added to the noise (``dyn_acc_corr_s``) keeps it at ~0.85-1.0.
    """
    from hrtls.frames import GRAVITY_M_S2, quat_rotate
    from hrtls.sim.scenarios import run_scenario

    sim = run_scenario("colombo_circle", 0)
    t, acc, gyr, mag = sim.session.imu.aligned()
    heading = np.interp(t, sim.motion.t, np.unwrap(sim.motion.heading))
    speed = np.interp(t, sim.motion.t, sim.motion.speed)
    ramp = (np.gradient(speed, t) > 0.5) & (t < t[0] + 10.0)
    assert ramp.sum() > 100

    def forward(params):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DegradedInputWarning)
            q = make_filter(method, params).update(t, acc, gyr, mag).q
        a_n = quat_rotate(q[ramp], acc[ramp]) - [0.0, 0.0, GRAVITY_M_S2]
        fwd = a_n[:, 0] * np.cos(heading[ramp]) + a_n[:, 1] * np.sin(heading[ramp])
        return float(np.mean(fwd))

    q_true = sim.imu.ideal.q_nd
    idx = np.searchsorted(sim.imu.ideal.t, t[ramp]).clip(0, len(q_true) - 1)
    a_true = quat_rotate(q_true[idx], acc[ramp]) - [0.0, 0.0, GRAVITY_M_S2]
    true_fwd = float(np.mean(a_true[:, 0] * np.cos(heading[ramp])
                             + a_true[:, 1] * np.sin(heading[ramp])))
    params = make_filter(method).params_type
    assert forward(params()) > 0.75 * true_fwd
    assert forward(params(dyn_acc_corr_s=0.0)) < 0.7 * true_fwd


def test_state_of_the_older_aux_layout_loads(motion):
    """States saved before the body-acceleration variance (27 aux values) still load."""
    f = EulerEkf()
    f.update(motion.t[:200], motion.acc[:200], motion.gyr[:200], motion.mag[:200])
    d = f.state.to_dict()
    d["aux"] = d["aux"][:K.AUX_DYN_MEAN]
    state = AttitudeState.from_dict(json.loads(json.dumps(d)))
    assert state.aux.shape == (K.AUX_SIZE,)
    g = EulerEkf()
    g.restore(state)
    r = g.update(motion.t[200:400], motion.acc[200:400], motion.gyr[200:400],
                 motion.mag[200:400])
    assert np.all(np.isfinite(r.q))


@pytest.mark.parametrize("at_rest", [True, False])
def test_quat_ekf_bias_variance_at_rest_matches_reference(at_rest):
    """A 3 s rest with a gyro bias: the rest update shrinks the bias variances (reference)."""
    m = make_motion(500, seed=4, rest_s=3.0, bias=0.01)
    f = QuatEkf(QuatEkfParams(acc_gate_m_s2=1.5, bias_var_at_rest=at_rest))
    r = f.update(m.t, m.acc, m.gyr, m.mag)
    assert np.count_nonzero(r.flags & K.FLAG_REST) > 100
    q_ref, flags, P_ref, _ = ref.quat_ekf_reference(m.t, m.acc, m.gyr, m.mag, f._prm)
    np.testing.assert_array_equal(r.flags, flags)
    np.testing.assert_allclose(r.q, q_ref, atol=1e-9)
    np.testing.assert_allclose(f.state.P, P_ref, atol=1e-12)
    P = f.state.P
    assert np.all(np.linalg.eigvalsh(0.5 * (P + P.T)) > -1e-12)
    if at_rest:
        # ~ sigma_g^2 dt / (2 tau) after the rest, not the initial (0.01 rad/s)^2
        assert np.max(np.diag(P)[4:]) < 1e-5


def test_quat_ekf_walking_start_is_not_pitch():
    """Colombo Case A start, quaternion EKF: with ``bias_var_at_rest`` the bias states do not
    take up the tilt the start-up acceleration suggests (the default still does)."""
    from hrtls.frames import GRAVITY_M_S2, quat_rotate
    from hrtls.sim.scenarios import run_scenario

    sim = run_scenario("colombo_circle", 1)
    t, acc, gyr, mag = sim.session.imu.aligned()
    heading = np.interp(t, sim.motion.t, np.unwrap(sim.motion.heading))
    speed = np.interp(t, sim.motion.t, sim.motion.speed)
    ramp = (np.gradient(speed, t) > 0.5) & (t < t[0] + 10.0)
    c, s = np.cos(heading[ramp]), np.sin(heading[ramp])
    q_true = sim.imu.ideal.q_nd
    idx = np.searchsorted(sim.imu.ideal.t, t[ramp]).clip(0, len(q_true) - 1)
    a_true = quat_rotate(q_true[idx], acc[ramp]) - [0.0, 0.0, GRAVITY_M_S2]
    true_fwd = float(np.mean(a_true[:, 0] * c + a_true[:, 1] * s))

    def forward(**kw):
        q = QuatEkf(QuatEkfParams(**kw)).update(t, acc, gyr, mag).q
        a_n = quat_rotate(q[ramp], acc[ramp]) - [0.0, 0.0, GRAVITY_M_S2]
        return float(np.mean(a_n[:, 0] * c + a_n[:, 1] * s))

    assert forward(bias_var_at_rest=True) > 0.75 * true_fwd
    assert forward() < 0.7 * true_fwd
