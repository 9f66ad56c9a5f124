from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from hrtls.errors import InputError
from hrtls.fusion.gating import (
    chi2_threshold,
    is_spd,
    kalman_update,
    nis,
    summarize,
    symmetrize,
)


def test_scalar_kalman_matches_closed_form() -> None:
    # prior N(1, 4), measurement z = 3 with variance 1 -> posterior mean 2.6, variance 0.8
    res = kalman_update(np.array([1.0]), np.array([[4.0]]), np.array([[1.0]]),
                        np.array([[1.0]]), np.array([2.0]))
    assert res.diagnostics.accepted
    assert res.x[0] == pytest.approx(1.0 + 4.0 / 5.0 * 2.0)
    assert res.P[0, 0] == pytest.approx(4.0 * 1.0 / 5.0)
    assert res.diagnostics.nis == pytest.approx(4.0 / 5.0)


def test_joseph_equals_standard_form_for_optimal_gain() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = rng.normal(size=(4, 4))
        p = a @ a.T + 0.1 * np.eye(4)
        h = rng.normal(size=(2, 4))
        b = rng.normal(size=(2, 2))
        r = b @ b.T + 0.1 * np.eye(2)
        x = rng.normal(size=4)
        nu = rng.normal(size=2) * 0.1
        res = kalman_update(x, p, h, r, nu)
        s = h @ p @ h.T + r
        k = p @ h.T @ np.linalg.inv(s)
        np.testing.assert_allclose(res.P, (np.eye(4) - k @ h) @ p, atol=1e-9)
        np.testing.assert_allclose(res.x, x + k @ nu, atol=1e-12)


def test_gate_rejects_20_sigma_outlier() -> None:
    p = np.eye(2)
    r = np.eye(2) * 0.25
    s_sigma = np.sqrt(1.25)
    res = kalman_update(np.zeros(2), p, np.eye(2), r, np.array([20.0 * s_sigma, 0.0]),
                        gate_probability=0.999, kind="fix")
    assert res.diagnostics.status == "rejected"
    assert res.diagnostics.nis == pytest.approx(400.0)
    np.testing.assert_array_equal(res.x, np.zeros(2))
    np.testing.assert_array_equal(res.P, p)
    ok = kalman_update(np.zeros(2), p, np.eye(2), r, np.array([2.0 * s_sigma, 0.0]),
                       gate_probability=0.999)
    assert ok.diagnostics.accepted


def test_chi2_threshold_and_nis() -> None:
    assert chi2_threshold(2, 0.99) == pytest.approx(chi2.ppf(0.99, 2))
    for dof in range(1, 7):  # scipy.stats' quantile, to the bit (the gates are unchanged)
        for p in (0.9, 0.95, 0.99, 0.997, 0.999, 0.9999):
            assert chi2_threshold(dof, p) == chi2.ppf(p, dof)
    s = np.array([[2.0, 0.5], [0.5, 1.0]])
    nu = np.array([1.0, -1.0])
    assert nis(nu, s) == pytest.approx(nu @ np.linalg.solve(s, nu))
    with pytest.raises(InputError):
        chi2_threshold(0, 0.9)
    with pytest.raises(InputError):
        chi2_threshold(1, 1.0)


def test_bad_shapes_and_nan_raise() -> None:
    with pytest.raises(InputError):
        kalman_update(np.zeros(2), np.eye(2), np.eye(3), np.eye(3), np.zeros(3))
    with pytest.raises(InputError):
        kalman_update(np.zeros(2), np.eye(2), np.eye(2), np.eye(2), np.array([np.nan, 0.0]))


def test_angle_wraps_and_diagnostics_json() -> None:
    res = kalman_update(np.array([3.1]), np.array([[1.0]]), np.array([[1.0]]),
                        np.array([[1e-6]]), np.array([0.2]), angle_index=0, kind="bearing")
    assert -np.pi < res.x[0] <= np.pi
    assert res.x[0] == pytest.approx(3.3 - 2 * np.pi, abs=1e-5)
    json.dumps(res.diagnostics.to_dict())
    assert summarize([res.diagnostics, res.diagnostics]) == {"bearing": {"accepted": 2}}


@settings(max_examples=100, deadline=None)
@given(st.integers(min_value=0, max_value=10_000), st.integers(min_value=1, max_value=3))
def test_update_keeps_covariance_spd(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(4, 4)) * rng.uniform(0.01, 100)
    p = symmetrize(a @ a.T + 1e-6 * np.eye(4))
    h = rng.normal(size=(m, 4))
    r = np.eye(m) * rng.uniform(1e-4, 10)
    res = kalman_update(rng.normal(size=4), p, h, r, rng.normal(size=m))
    assert is_spd(res.P)
    assert np.trace(res.P) <= np.trace(p) * (1 + 1e-9)


def numpy_kalman(x: np.ndarray, p: np.ndarray, h: np.ndarray, r: np.ndarray, nu: np.ndarray,
                 threshold: float) -> tuple[str, float, np.ndarray, np.ndarray]:
    """Reference of the compiled core: numpy Cholesky test, solve, Joseph form."""
    s = 0.5 * ((h @ p @ h.T + r) + (h @ p @ h.T + r).T)
    try:
        np.linalg.cholesky(s)
    except np.linalg.LinAlgError:
        return "not_pd", float("nan"), x, p
    sol = np.linalg.solve(s, np.column_stack([nu, h @ p]))
    value = float(nu @ sol[:, 0])
    if value > threshold:
        return "gate", value, x, p
    k = sol[:, 1:].T
    a = np.eye(len(x)) - k @ h
    q = a @ p @ a.T + k @ r @ k.T
    return "accepted", value, x + k @ nu, 0.5 * (q + q.T)


@settings(max_examples=150, deadline=None)
@given(n=st.integers(1, 5), m=st.integers(1, 3), seed=st.integers(0, 10_000),
       scale=st.floats(1e-3, 1e3), singular=st.booleans())
def test_compiled_update_equals_numpy(n: int, m: int, seed: int, scale: float,
                                      singular: bool) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    p = scale * (a @ a.T + 0.01 * np.eye(n))
    h = rng.normal(size=(m, n))
    b = rng.normal(size=(m, m))
    r = b @ b.T + 0.05 * np.eye(m)
    if singular:    # S = H P H^T + R with a negative direction: not positive definite
        r = r - (np.max(np.linalg.eigvalsh(h @ p @ h.T + r)) + 1.0) * np.eye(m)
    x = rng.normal(size=n)
    nu = rng.normal(size=m) * np.sqrt(scale) * rng.choice([0.1, 1.0, 10.0])
    thr = chi2_threshold(m, 0.99)
    status, value, x_ref, p_ref = numpy_kalman(x, p, h, r, nu, thr)
    res = kalman_update(x, p, h, r, nu, gate_probability=0.99)
    d = res.diagnostics
    expected = {"accepted": "accepted", "gate": "rejected", "not_pd": "rejected"}[status]
    assert d.status == expected
    if status == "not_pd":
        assert d.reason == "innovation covariance not positive definite" and np.isnan(d.nis)
    else:
        assert d.nis == pytest.approx(value, rel=1e-8, abs=1e-12)
    np.testing.assert_allclose(res.x, x_ref, rtol=1e-8, atol=1e-9 * np.sqrt(scale))
    np.testing.assert_allclose(res.P, p_ref, rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_array_equal(res.P, res.P.T)


def test_angle_wrapped_and_rejection_returns_prior() -> None:
    x = np.array([0.0, 3.1])
    p = np.eye(2)
    h = np.array([[0.0, 1.0]])
    res = kalman_update(x, p, h, np.array([[0.01]]), np.array([0.5]), angle_index=1)
    assert -np.pi < res.x[1] <= np.pi and res.x[1] < 0
    rej = kalman_update(x, p, h, np.array([[0.01]]), np.array([50.0]), gate_probability=0.99)
    assert rej.x is x and rej.P is p
