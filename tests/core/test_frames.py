import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from hrtls import frames as fr
from hrtls.errors import InputError

finite = st.floats(-1e6, 1e6, allow_nan=False)


@given(arrays(np.float64, st.integers(1, 50), elements=finite))
def test_wrap_angle_range_and_equivalence(a):
    w = fr.wrap_angle(a)
    assert np.all(w > -np.pi - 1e-12) and np.all(w <= np.pi)
    assert np.allclose(np.cos(w), np.cos(a), atol=1e-6) and np.allclose(np.sin(w), np.sin(a),
                                                                          atol=1e-6)


def test_wrap_angle_hand_cases():
    assert fr.wrap_angle(np.pi) == pytest.approx(np.pi)
    assert fr.wrap_angle(-np.pi) == pytest.approx(np.pi)
    assert fr.wrap_angle(3 * np.pi / 2) == pytest.approx(-np.pi / 2)
    assert fr.angle_difference(0.1, 2 * np.pi - 0.1) == pytest.approx(0.2)


def test_bearing_heading_hand_cases():
    # north = bearing 0 = heading +90 deg; east = bearing 90 deg = heading 0
    assert fr.heading_from_bearing(0.0) == pytest.approx(np.pi / 2)
    assert fr.heading_from_bearing(np.pi / 2) == pytest.approx(0.0)
    assert fr.bearing_from_heading(np.pi) == pytest.approx(3 * np.pi / 2)


def _random_quats(n, seed):
    return fr.quat_from_rotation(Rotation.random(n, random_state=seed))


def test_quaternion_ops_match_scipy_on_thousands():
    p, q = _random_quats(2000, 1), _random_quats(2000, 2)
    rp, rq = fr.quat_to_rotation(p), fr.quat_to_rotation(q)
    # Hamilton product p*q is the rotation rp * rq (apply q first)
    assert np.allclose(fr.quat_normalize(fr.quat_multiply(p, q)), fr.quat_from_rotation(rp * rq),
                       atol=1e-12)
    v = np.random.default_rng(3).normal(size=(2000, 3))
    assert np.allclose(fr.quat_rotate(p, v), rp.apply(v), atol=1e-12)
    assert np.allclose(fr.quat_to_matrix(p), rp.as_matrix(), atol=1e-12)
    assert np.allclose(fr.quat_normalize(fr.quat_conjugate(p)), fr.quat_from_rotation(rp.inv()),
                       atol=1e-12)


def test_euler_round_trip_against_scipy_zyx():
    rng = np.random.default_rng(4)
    n = 3000
    roll = rng.uniform(-np.pi, np.pi, n)
    pitch = rng.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    q = fr.quat_from_euler(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll]))
    assert np.allclose(fr.quat_to_matrix(q), ref.as_matrix(), atol=1e-12)
    r2, p2, y2 = fr.euler_from_quat(q)
    assert np.allclose(fr.angle_difference(r2, roll), 0, atol=1e-9)
    assert np.allclose(p2, pitch, atol=1e-9)
    assert np.allclose(fr.angle_difference(y2, yaw), 0, atol=1e-9)


def test_heading_quaternion_turns_x_to_y():
    q = fr.quat_from_euler(0.0, 0.0, np.pi / 2)
    assert np.allclose(fr.quat_rotate(q, [1.0, 0, 0]), [0, 1, 0], atol=1e-15)
    assert fr.heading_from_quat(q) == pytest.approx(np.pi / 2)


@settings(max_examples=100)
@given(arrays(np.float64, (5, 3), elements=st.floats(-3, 3)))
def test_rotvec_matches_scipy(v):
    assert np.allclose(fr.quat_to_matrix(fr.quat_from_rotvec(v)),
                       Rotation.from_rotvec(v).as_matrix(), atol=1e-12)


@given(arrays(np.float64, (4,), elements=st.floats(-10, 10)))
def test_normalize_gives_unit_nonnegative_w(q):
    if np.linalg.norm(q) < 1e-6:
        return
    n = fr.quat_normalize(q)
    assert np.isclose(np.linalg.norm(n), 1.0) and n[0] >= 0


def test_normalize_rejects_zero_and_bad_shape():
    with pytest.raises(InputError):
        fr.quat_normalize([0, 0, 0, 0])
    with pytest.raises(InputError, match="last axis of length 4"):
        fr.quat_multiply([1, 0, 0], [1, 0, 0, 0])


def test_quat_angle_between_hand_case():
    q = fr.quat_from_euler(0, 0, 0.3)
    assert fr.quat_angle_between(q, np.array([1.0, 0, 0, 0])) == pytest.approx(0.3)
    assert fr.quat_angle_between(q, -q) == pytest.approx(0.0, abs=1e-7)


def test_georeference_round_trip_and_rotation():
    geo = fr.Georeference(49.4431, 11.0885, 300.0, rotation_rad=0.0)
    xyz = np.array([[0, 0, 0], [100.0, 0, 0], [0, 100.0, 5.0], [-250.0, 30.0, -2.0]])
    wgs = geo.to_wgs84(xyz)
    assert np.allclose(geo.from_wgs84(wgs[:, 0], wgs[:, 1], wgs[:, 2]), xyz, atol=1e-6)
    assert wgs[1, 1] > geo.lon_deg and np.isclose(wgs[1, 0], geo.lat_deg, atol=1e-5)
    assert wgs[2, 0] > geo.lat_deg
    # a local frame whose x axis points north: local +x is a northward displacement
    rotated = fr.Georeference(49.4431, 11.0885, 300.0, rotation_rad=np.pi / 2)
    north = rotated.to_wgs84([[100.0, 0.0, 0.0]])[0]
    assert north[0] > geo.lat_deg and np.isclose(north[1], geo.lon_deg, atol=1e-6)
    back = rotated.from_wgs84(north[0], north[1], north[2])
    assert np.allclose(back, [[100.0, 0, 0]], atol=1e-6)


def test_georeference_validates():
    with pytest.raises(InputError, match="latitude"):
        fr.Georeference(95.0, 0.0)
