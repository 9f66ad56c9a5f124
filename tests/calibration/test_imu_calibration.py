"""Six-position test, rate test, magnetometer fit, calibration file."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hrtls.calibration import (
    Calibration,
    accelerometer_six_position,
    fit_magnetometer,
    gyroscope_rate_test,
    six_position_from_means,
)
from hrtls.data import ImuStream, SensorSeries
from hrtls.errors import FormatError, InputError
from hrtls.frames import GRAVITY_M_S2

vec = st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3)
scl = st.lists(st.floats(-0.05, 0.05), min_size=3, max_size=3)


def test_six_position_hand_computed():
    # axis x: up 10.0, down -9.6 -> b = 0.2, S = (19.6 - 2g) / 2g
    b, s = six_position_from_means([10.0, 9.81, 9.81], [-9.6, -9.81, -9.81], 9.81)
    np.testing.assert_allclose(b, [0.2, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(s[0], (19.6 - 19.62) / 19.62, atol=1e-12)
    with pytest.raises(InputError):
        six_position_from_means([1.0, 1, 1], [2.0, 0, 0])


@settings(max_examples=60, deadline=None)
@given(vec, scl)
def test_six_position_recovers_bias_and_scale(bias, scale):
    b = np.array(bias)
    s = np.array(scale)
    rng = np.random.default_rng(0)
    segs = {}
    for i, axis in enumerate("xyz"):
        for sign in (1.0, -1.0):
            true = np.zeros((200, 3))
            true[:, i] = sign * GRAVITY_M_S2
            segs[("+" if sign > 0 else "-") + axis] = (true * (1 + s) + b
                                                         + rng.normal(size=(200, 3)) * 1e-4)
    b_est, s_est = accelerometer_six_position(segs)
    np.testing.assert_allclose(b_est, b, atol=1e-4)
    np.testing.assert_allclose(s_est, s, atol=1e-5)
    cal = Calibration(accel_bias_m_s2=tuple(b_est), accel_scale=tuple(s_est))
    np.testing.assert_allclose(cal.correct_accel(segs["+z"]).mean(axis=0), [0, 0, GRAVITY_M_S2],
                               atol=1e-3)


def test_six_position_missing_position():
    with pytest.raises(InputError, match="missing"):
        accelerometer_six_position({"+x": np.ones((3, 3))})


def test_rate_test():
    w = 1.0
    b = np.array([0.01, -0.02, 0.003])
    s = np.array([0.01, 0.0, -0.02])
    ccw = w * (1 + s) + b
    cw = -w * (1 + s) + b
    b_est, s_est = gyroscope_rate_test(w, ccw, cw)
    np.testing.assert_allclose(b_est, b, atol=1e-12)
    np.testing.assert_allclose(s_est, s, atol=1e-12)
    with pytest.raises(InputError):
        gyroscope_rate_test(0.0, ccw, cw)


def _field_samples(n=600, seed=0):
    rng = np.random.default_rng(seed)
    rots = Rotation.random(n, random_state=seed)
    return rots.inv().apply(np.array([0.0, 24.0, -41.0])), rng


@pytest.mark.parametrize("model", ["sphere", "ellipsoid"])
def test_magnetometer_fit_recovers_hard_and_soft_iron(model):
    m_true, rng = _field_samples()
    c = np.array([12.0, -30.0, 5.0])
    A = np.eye(3) if model == "sphere" else np.array(
        [[1.1, 0.05, 0.0], [0.05, 0.92, 0.03], [0.0, 0.03, 1.02]])
    raw = m_true @ A.T + c + rng.normal(size=m_true.shape) * 0.05
    fit = fit_magnetometer(raw, model=model)
    np.testing.assert_allclose(fit.hard_iron_uT, c, atol=0.1)
    corrected = (raw - np.array(fit.hard_iron_uT)) @ np.array(fit.soft_iron).T
    norms = np.linalg.norm(corrected, axis=1)
    assert np.std(norms) < 0.1
    assert abs(fit.field_uT - np.mean(norms)) < 0.1
    assert fit.residual_uT < 0.1


def test_magnetometer_fit_needs_coverage():
    with pytest.raises(InputError):
        fit_magnetometer(np.ones((5, 3)))
    # samples on a plane only: not an ellipsoid
    ang = np.linspace(0, 2 * np.pi, 200)
    ring = np.column_stack([30 * np.cos(ang), 30 * np.sin(ang), np.zeros_like(ang)])
    with pytest.raises(InputError):
        fit_magnetometer(ring, model="ellipsoid")


def test_calibration_json_roundtrip_and_apply(tmp_path):
    m_true, _ = _field_samples(100)
    raw_mag = m_true * 1.1 + 3.0
    fit = fit_magnetometer(np.vstack([raw_mag, _field_samples(300, 1)[0] * 1.1 + 3.0]),
                           model="sphere")
    cal = Calibration(gyro_bias_rad_s=(0.01, 0.0, 0.0), accel_bias_m_s2=(0.1, 0.0, 0.0)
                      ).with_magnetometer(fit)
    path = cal.save(tmp_path / "cal.json")
    again = Calibration.load(path)
    assert again == cal
    t = np.arange(100) * 0.01
    imu = ImuStream(SensorSeries(t, np.tile([0.1, 0.0, 9.8], (100, 1))),
                    SensorSeries(t, np.tile([0.01, 0.0, 0.0], (100, 1))),
                    SensorSeries(t, raw_mag))
    out = again.apply(imu)
    np.testing.assert_allclose(out.gyro.values, 0.0, atol=1e-12)
    np.testing.assert_allclose(out.accel.values[:, 0], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(out.mag.values, axis=1), fit.field_uT, rtol=1e-3)


def test_calibration_load_errors(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(FormatError, match="line 1"):
        Calibration.load(p)
    p.write_text(json.dumps({"accel_scale": [0, 0, -0.9]}))
    with pytest.raises(FormatError, match="accel_scale"):
        Calibration.load(p)
    p.write_text(json.dumps({"mag_soft_iron": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}))
    with pytest.raises(FormatError, match="mag_soft_iron"):
        Calibration.load(p)
    with pytest.raises(FormatError):
        Calibration.load(tmp_path / "missing.json")


def test_package_exports_are_the_imu_module_api():
    # hrtls.calibration lists its lazy exports by hand (importing imu would defeat the lazy
    # import): the list must stay imu.__all__, each name the imu object
    import hrtls.calibration as pkg
    from hrtls.calibration import imu

    assert pkg.__all__ == imu.__all__
    assert all(getattr(pkg, name) is getattr(imu, name) for name in pkg.__all__)
    with pytest.raises(AttributeError, match="no attribute"):
        _ = pkg.not_a_calibration_name
