"""The compiled fusion functions against readable references (``tests/fusion/_reference.py``),
the generic Joseph update, and their own ``.py_func`` (the same code run by Python)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.fusion.channel import ChannelEstimatorParams, channel_update
from hrtls.fusion.gating import (
    ACCEPTED,
    GATED,
    chi2_threshold,
    kalman_update,
    position_update,
    scalar_update,
)
from hrtls.fusion.rss_scans import hyperbolic_wls_kernel
from hrtls.fusion.step_prediction import StepPredictionParams, predict_step

from . import _reference as ref

ACTS = [int(a) for a in (Activity.WALKING, Activity.STANDING, Activity.UPSTAIRS,
                         Activity.DOWNSTAIRS, Activity.RUNNING)]


def spd(seed: int, scale: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(4, 4)) * scale
    return a @ a.T + 1e-3 * np.eye(4)


step_case = st.tuples(st.integers(0, 10_000), st.floats(0.0, 1.5), st.floats(-4.0, 4.0),
                      st.floats(-0.3, 0.3), st.sampled_from(ACTS),
                      st.one_of(st.none(), st.floats(1e-5, 0.2)), st.booleans(), st.booleans(),
                      st.floats(-3.0, 3.0), st.booleans(), st.booleans())


@settings(max_examples=200, deadline=None)
@given(case=step_case)
def test_predict_step_equals_matrix_reference(case: tuple) -> None:  # type: ignore[type-arg]
    seed, length, heading, dz, act, var, state_mode, has_in, h_in, pending, stairs = case
    prm = StepPredictionParams(heading_mode="state" if state_mode else "input",
                               stairs_from_model=stairs)
    p0 = spd(seed, 0.3)
    x0 = np.array([1.0, -2.0, 0.5, 0.7])
    x, p = x0.copy(), p0.copy()
    out = predict_step(prm.record()[0], x, p, h_in, has_in, pending, length, heading, dz, act,
                       math.nan if var is None else var)
    xr, pr, *rest = ref.step_reference(prm, x0, p0, h_in, has_in, pending, length, heading, dz,
                                       act, var)
    np.testing.assert_allclose(x[:3], xr[:3], rtol=0, atol=1e-12)
    assert abs(math.remainder(x[3] - xr[3], 2 * math.pi)) < 1e-12
    np.testing.assert_allclose(p, pr, rtol=1e-12, atol=1e-12)
    assert out[0] == rest[0] and out[1] == rest[1] and out[2] == rest[2]


def test_py_func_is_the_same_code() -> None:
    """The slow Python run of the compiled functions gives the same numbers."""
    prm = StepPredictionParams(heading_mode="state")
    rec = prm.record().view(np.recarray)[0]
    for seed in range(20):
        p0 = spd(seed, 0.3)
        a = (p0.copy(), p0.copy())
        x = (np.array([0.0, 1.0, 0.0, 3.1]), np.array([0.0, 1.0, 0.0, 3.1]))
        r1 = predict_step(prm.record()[0], x[0], a[0], 0.2, True, True, 0.7, 0.25, 0.0,
                          int(Activity.WALKING), 0.01)
        r2 = predict_step.py_func(rec, x[1], a[1], 0.2, True, True, 0.7, 0.25, 0.0,
                                  int(Activity.WALKING), 0.01)
        assert r1 == r2
        np.testing.assert_allclose(x[0], x[1], rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(a[0], a[1], rtol=1e-14, atol=1e-15)
        h = (0.3, -0.2, 0.0, 0.1)
        xs = [np.array([1.0, 2.0, 0.0, 0.5]) for _ in range(2)]
        ps = [spd(seed), spd(seed)]
        c1 = scalar_update(xs[0], ps[0], h, 0.5, 0.4, 10.0, True)
        c2 = scalar_update.py_func(xs[1], ps[1], h, 0.5, 0.4, 10.0, True)
        np.testing.assert_allclose(c1, c2, rtol=1e-14)
        np.testing.assert_allclose(ps[0], ps[1], rtol=1e-13, atol=1e-15)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 10_000), h=st.tuples(*[st.floats(-3.0, 3.0)] * 4),
       r=st.floats(1e-3, 10.0), nu=st.floats(-5.0, 5.0), gated=st.booleans())
def test_scalar_update_equals_generic_joseph(seed: int, h: tuple[float, float, float, float],
                                             r: float, nu: float, gated: bool) -> None:
    p0 = spd(seed)
    x0 = np.array([1.0, 2.0, 0.3, 2.9])
    thr = chi2_threshold(1, 0.99)
    x, p = x0.copy(), p0.copy()
    code, nis, s = scalar_update(x, p, h, r, nu, thr, gated)
    res = kalman_update(x0, p0, np.array([h]), np.array([[r]]), np.array([nu]),
                        gate_probability=0.99 if gated else None, angle_index=3)
    assert s == np.float64(res.diagnostics.innovation_cov[0, 0]) or math.isclose(
        s, float(res.diagnostics.innovation_cov[0, 0]), rel_tol=1e-12)
    assert math.isclose(nis, res.diagnostics.nis, rel_tol=1e-10, abs_tol=1e-14)
    if abs(nis - thr) < 1e-9 * thr and gated:
        return
    assert (code == ACCEPTED) == res.diagnostics.accepted
    assert code in (ACCEPTED, GATED)
    np.testing.assert_allclose(x[:3], res.x[:3], rtol=0, atol=1e-10)
    assert abs(math.remainder(x[3] - res.x[3], 2 * math.pi)) < 1e-10
    np.testing.assert_allclose(p, res.P, rtol=1e-9, atol=1e-10)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 10_000), r=st.tuples(st.floats(0.05, 5.0), st.floats(-0.5, 0.5),
                                                st.floats(0.05, 5.0)),
       nu=st.tuples(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0)))
def test_position_update_equals_generic_joseph(seed: int, r: tuple[float, float, float],
                                               nu: tuple[float, float]) -> None:
    r00, r01, r11 = r[0], r[1] * math.sqrt(r[0] * r[2]), r[2]
    p0 = spd(seed)
    x0 = np.array([1.0, 2.0, 0.3, -3.0])
    thr = chi2_threshold(2, 0.999)
    x, p = x0.copy(), p0.copy()
    aux = np.empty(5)
    code, nis = position_update(x, p, r00, r01, r11, nu[0], nu[1], thr, aux)
    h = np.zeros((2, 4))
    h[0, 0] = h[1, 1] = 1.0
    res = kalman_update(x0, p0, h, np.array([[r00, r01], [r01, r11]]), np.array(nu),
                        gate_probability=0.999, angle_index=3)
    assert math.isclose(nis, res.diagnostics.nis, rel_tol=1e-9, abs_tol=1e-12)
    if abs(nis - thr) < 1e-9 * thr:
        return
    assert (code == ACCEPTED) == res.diagnostics.accepted
    np.testing.assert_allclose(aux[2:], [res.diagnostics.innovation_cov[0, 0],
                                         res.diagnostics.innovation_cov[0, 1],
                                         res.diagnostics.innovation_cov[1, 1]], rtol=1e-12)
    np.testing.assert_allclose(x[:3], res.x[:3], rtol=0, atol=1e-10)
    np.testing.assert_allclose(p, res.P, rtol=1e-9, atol=1e-10)


@settings(max_examples=200, deadline=None)
@given(a=st.floats(-80.0, -40.0), eta=st.floats(1.2, 5.0), c=st.tuples(
    st.floats(0.5, 50.0), st.floats(-0.9, 0.9), st.floats(0.01, 2.0)),
       res_sigma=st.floats(1.0, 8.0), rss=st.floats(-100.0, -30.0), d=st.floats(0.5, 40.0),
       dvar=st.floats(0.0, 30.0))
def test_channel_update_equals_vector_reference(a: float, eta: float,
                                                c: tuple[float, float, float],
                                                res_sigma: float, rss: float, d: float,
                                                dvar: float) -> None:
    prm = ChannelEstimatorParams()
    cov0 = np.array([[c[0], c[1] * math.sqrt(c[0] * c[2])],
                     [c[1] * math.sqrt(c[0] * c[2]), c[2]]])
    from hrtls.fusion.channel import CHANNEL_STATE_DTYPE

    cs = np.zeros(1, dtype=CHANNEL_STATE_DTYPE)
    cs["a_dbm"], cs["eta"], cs["residual_var_db2"] = a, eta, res_sigma**2
    cov = cov0.copy()
    used = channel_update(prm.record()[0], cs[0], cov, rss, d, dvar, 1.0)
    skip = d < prm.min_distance_m or dvar > prm.max_position_var_m2
    assert used != skip
    if skip:
        assert cs["a_dbm"][0] == a and np.array_equal(cov, cov0)
        return
    theta, cov_r, var_r = ref.channel_reference(
        np.array([a, eta]), cov0, res_sigma**2, rss, d, dvar, forgetting=prm.forgetting,
        sigma_a=prm.sigma_a_prior_db, sigma_eta=prm.sigma_eta_prior, eta_bounds=prm.eta_bounds)
    np.testing.assert_allclose([cs["a_dbm"][0], cs["eta"][0]], theta, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cov, cov_r, rtol=1e-10, atol=1e-12)
    assert math.isclose(cs["residual_var_db2"][0], var_r, rel_tol=1e-12)
    assert cs["count"][0] == 1


@settings(max_examples=150, deadline=None)
@given(pts=st.lists(st.tuples(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0),
                              st.floats(0.2, 30.0)), min_size=3, max_size=9),
       sigma_ln=st.floats(0.05, 1.0))
def test_wls_kernel_equals_matrix_reference(pts: list[tuple[float, float, float]],
                                            sigma_ln: float) -> None:
    a = np.array([[p[0], p[1]] for p in pts])
    d = np.array([p[2] for p in pts])
    out = np.empty(5)
    r = int(np.argmin(d))
    ok = hyperbolic_wls_kernel(a, d, sigma_ln, r, out)
    xy, cov, cond = ref.hyperbolic_wls_reference(a, d, sigma_ln, r)
    if not (ok and np.all(np.isfinite(xy))):
        # only near-degenerate geometry may be judged differently by the two
        assert ok == bool(np.all(np.isfinite(xy))) or cond > 1e10
        return
    scale = max(1.0, float(np.max(np.abs(xy))))
    tol = 1e-12 * cond * scale + 1e-9
    np.testing.assert_allclose(out[:2], xy, rtol=0, atol=tol)
    np.testing.assert_allclose(out[2:], [cov[0, 0], cov[0, 1], cov[1, 1]],
                               rtol=1e-12 * cond + 1e-9, atol=1e-12)
