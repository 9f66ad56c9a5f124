"""FQA, device pass-through, gyro bias at rest, error metrics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hrtls.attitude import (
    DeviceOrientation,
    DeviceParams,
    estimate_gyro_bias,
    fqa,
    frame_to_enu,
    orientation_errors,
)
from hrtls.attitude.device import rotate_to_navigation
from hrtls.data import OrientationSeries
from hrtls.errors import InputError
from hrtls.frames import (
    GRAVITY_M_S2,
    quat_angle_between,
    quat_from_euler,
    quat_from_rotation,
    quat_multiply,
    quat_rotate,
)

from . import _reference as ref
from .conftest import FIELD_N, make_motion

angles = st.tuples(st.floats(-3.1, 3.1), st.floats(-1.5, 1.5), st.floats(-3.1, 3.1))


@settings(max_examples=100, deadline=None)
@given(angles)
def test_fqa_recovers_attitude(rpy):
    q = quat_from_euler(*rpy)
    rot = Rotation.from_quat(q[[1, 2, 3, 0]])
    a = rot.inv().apply([0.0, 0.0, GRAVITY_M_S2])
    m = rot.inv().apply(FIELD_N)
    q_fqa = fqa(a[None], m[None])[0]
    assert quat_angle_between(q_fqa, q) < 1e-6
    q_ref = ref.fqa_reference(a, m)
    assert quat_angle_between(q_fqa, q_ref) < 1e-6


def test_fqa_degenerate_inputs():
    # no horizontal field: heading 0 kept; no gravity: identity
    q = fqa(np.array([[0.0, 0.0, 9.8], [0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 5.0], [1, 2, 3.0]]))
    np.testing.assert_allclose(q, [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-12)
    with pytest.raises(InputError):
        fqa(np.array([[np.nan, 0, 9.8]]), np.array([[1.0, 0, 0]]))


def test_frame_to_enu_conversions():
    # a device lying flat, x pointing north: in ENU that is yaw +90 deg
    expected = quat_from_euler(0.0, 0.0, np.pi / 2)
    # NED reference: x north, z down -> the same device has identity attitude w.r.t. NED
    # after flipping z: R_ned_d maps device x -> north, device z (up) -> -down
    q_ned_d = quat_from_rotation(Rotation.from_matrix([[1, 0, 0], [0, -1, 0], [0, 0, -1]]))
    assert quat_angle_between(frame_to_enu(q_ned_d, "ned"), expected) < 1e-12
    q_nwu_d = np.array([1.0, 0, 0, 0])  # device axes = north, west, up
    assert quat_angle_between(frame_to_enu(q_nwu_d, "nwu"), expected) < 1e-12
    assert quat_angle_between(frame_to_enu(expected, "enu"), expected) < 1e-12
    with pytest.raises(InputError):
        frame_to_enu(expected, "xyz")  # type: ignore[arg-type]


def test_device_pass_through_resamples_and_mounts():
    t = np.linspace(0.0, 2.0, 21)
    q = quat_from_euler(0.1 * t, 0.0, 0.5 * t)
    series = OrientationSeries(t, q)
    r = DeviceOrientation().run(series)
    np.testing.assert_allclose(r.q, q, atol=1e-12)
    tq = np.array([-0.5, 0.05, 1.0, 2.5])
    r2 = DeviceOrientation().run(series, tq)
    np.testing.assert_array_equal(r2.valid, [False, True, True, False])
    assert quat_angle_between(r2.q[1], quat_from_euler(0.005, 0.0, 0.025)) < 1e-3
    q_bd = quat_from_euler(0.0, 0.0, 0.3)
    r3 = DeviceOrientation(DeviceParams(mounting_q_bd=tuple(q_bd))).update(t, q)
    assert r3.frame == "nb"
    np.testing.assert_allclose(quat_multiply(r3.q, q_bd), r.q, atol=1e-12)
    v = rotate_to_navigation(r.q, np.tile([1.0, 0, 0], (len(t), 1)))
    np.testing.assert_allclose(v, quat_rotate(q, np.array([1.0, 0, 0])), atol=1e-12)
    with pytest.raises(InputError):
        DeviceParams(reference_frame="abc")  # type: ignore[arg-type]


def test_gyro_bias_from_rest():
    m = make_motion(1000, seed=1, rest_s=3.0, bias=0.01)
    est = estimate_gyro_bias(m.t, m.gyr, m.acc)
    assert est.found
    np.testing.assert_allclose(est.bias_rad_s, 0.01, atol=1e-3)
    assert est.rest[:200].all() and not est.rest[400:].any()
    moving = make_motion(500, seed=1, rest_s=0.0)
    est2 = estimate_gyro_bias(moving.t, moving.gyr, moving.acc)
    assert not est2.found and np.all(est2.bias_rad_s == 0)


def test_orientation_errors_split_heading_and_inclination():
    n = 50
    q_ref = quat_from_euler(np.zeros(n), np.zeros(n), np.linspace(0, 3, n))
    yaw_err = quat_from_euler(0.0, 0.0, 0.1)
    tilt_err = quat_from_euler(0.05, 0.0, 0.0)
    q_est = quat_multiply(yaw_err, quat_multiply(tilt_err, q_ref))
    e = orientation_errors(q_est, q_ref, remove_heading_offset=False)
    np.testing.assert_allclose(e.heading_rad, 0.1, atol=1e-3)
    np.testing.assert_allclose(e.inclination_rad, 0.05, atol=1e-3)
    e2 = orientation_errors(q_est, q_ref)
    assert abs(e2.offset_rad - 0.1) < 1e-3 and e2.heading_rms_rad < 1e-3
    q_ref2 = q_ref.copy()
    q_ref2[:10] = np.nan
    mask = np.ones(n, dtype=bool)
    mask[-5:] = False
    e3 = orientation_errors(q_est, q_ref2, mask)
    assert len(e3.index) == n - 15
    with pytest.raises(InputError):
        orientation_errors(q_est[:3], q_ref)


# ------------------------------------------------------------------------------ body acceleration
def _sample(dt, a):
    from hrtls.attitude import _kernels as K

    return K.Sample(dt, a[0], a[1], a[2], float(np.linalg.norm(a)), True, 0.0, 0.0, 0.0, 0.0,
                    True, 0.0, 0.0, 0.0, False)


def test_dynamic_acc_var_hand_computed():
    """First sample starts the mean; then ``k = dt / (tau + dt)``,
    ``var = (1 - k) (var + k d^2 / 3)``."""
    from hrtls.attitude import _kernels as K

    f = K.dynamic_acc_var.py_func
    aux = K.new_aux(np.zeros(3))
    # q = 90 deg about z: device x -> ENU y
    c = np.sqrt(0.5)
    assert f(aux, _sample(0.0, (1.0, 0.0, 9.0)), c, 0.0, 0.0, c, 1.0) == 0.0
    np.testing.assert_allclose(aux[K.AUX_DYN_MEAN:K.AUX_DYN_MEAN + 3], [0.0, 1.0, 9.0],
                               atol=1e-12)
    # second sample: ENU (0, 4, 9) -> d = (0, 3, 0), k = 0.5
    v = f(aux, _sample(1.0, (4.0, 0.0, 9.0)), c, 0.0, 0.0, c, 1.0)
    assert v == pytest.approx(0.5 * 0.5 * 9.0 / 3.0)
    np.testing.assert_allclose(aux[K.AUX_DYN_MEAN:K.AUX_DYN_MEAN + 3], [0.0, 2.5, 9.0],
                               atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-20, 20)),
                min_size=2, max_size=40),
       st.floats(1e-3, 0.1), st.floats(0.05, 5.0))
def test_dynamic_acc_var_properties(values, dt, tau):
    """Never negative, compiled = Python, and a rotated device gives the same variance."""
    from hrtls.attitude import _kernels as K

    aux_c = K.new_aux(np.zeros(3))
    aux_p = K.new_aux(np.zeros(3))
    aux_r = K.new_aux(np.zeros(3))
    q = np.array([0.8, 0.2, -0.4, 0.4])
    q /= np.linalg.norm(q)
    rot = Rotation.from_quat(q[[1, 2, 3, 0]])
    for a in values:
        a = np.asarray(a)
        vc = K.dynamic_acc_var(aux_c, _sample(dt, a), 1.0, 0.0, 0.0, 0.0, tau)
        vp = K.dynamic_acc_var.py_func(aux_p, _sample(dt, a), 1.0, 0.0, 0.0, 0.0, tau)
        # the same ENU vector seen by a rotated device
        vr = K.dynamic_acc_var(aux_r, _sample(dt, rot.inv().apply(a)), *q, tau)
        assert vc >= 0.0
        assert vc == pytest.approx(vp, rel=1e-9, abs=1e-9)
        assert vr == pytest.approx(vc, rel=1e-6, abs=1e-6)
