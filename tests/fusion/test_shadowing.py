"""AR(1) discount of correlated RSS readings of one beacon (hrtls.fusion.shadowing)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.rss import rss_update
from hrtls.fusion.shadowing import ShadowingMemory, ShadowingParams, information_fraction
from hrtls.fusion.state import FilterState

MODEL = PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=5.0)


def _gls_information(t: np.ndarray, tau_s: float) -> float:
    """``1^T Sigma^-1 1`` of readings at ``t`` with AR(1) correlation ``exp(-|dt|/tau)``."""
    sigma = np.exp(-np.abs(t[:, None] - t[None, :]) / tau_s)
    return float(np.ones(len(t)) @ np.linalg.solve(sigma, np.ones(len(t))))


def test_two_readings_hand_computed() -> None:
    """dt << tau: the information of one reading; dt >> tau: of two; dt = tau: tanh(1/2)."""
    m = ShadowingMemory()
    w = m.fractions([10.0, 10.01], ["b", "b"], tau_s=100.0)
    assert w[0] == 1.0 and 1.0 + w[1] == pytest.approx(1.0, abs=1e-4)
    w = ShadowingMemory().fractions([10.0, 110.0], ["b", "b"], tau_s=1.0)
    assert 1.0 + w[1] == pytest.approx(2.0, abs=1e-12)
    rho = math.exp(-1.0)
    assert information_fraction(2.0, 2.0) == pytest.approx((1 - rho) / (1 + rho), rel=1e-12)
    assert information_fraction(2.0, 2.0) == pytest.approx(math.tanh(0.5), rel=1e-12)
    # two readings with correlation rho carry 2 / (1 + rho) readings' worth (GLS)
    assert 1.0 + information_fraction(2.0, 2.0) == pytest.approx(2.0 / (1.0 + rho))


def test_independent_when_tau_is_zero_or_first_reading() -> None:
    assert information_fraction(0.0, 0.0) == 1.0
    assert information_fraction(math.inf, 5.0) == 1.0
    assert information_fraction(0.0, 5.0) == 0.0
    w = ShadowingMemory().fractions([0.0, 0.1, 0.2], ["a", "b", "a"], tau_s=0.0)
    np.testing.assert_array_equal(w, 1.0)


@pytest.mark.parametrize("tau_s", [0.3, 2.0, 30.0])
def test_sum_equals_the_gls_information_of_the_ar1_readings(tau_s: float) -> None:
    """Eq. 1 summed over a beacon's readings is exactly the GLS information (tridiagonal)."""
    t = np.cumsum(np.random.default_rng(4).exponential(0.5, 12))
    w = ShadowingMemory().fractions(t, np.full(len(t), "b"), tau_s=tau_s)
    assert w.sum() == pytest.approx(_gls_information(t, tau_s), rel=1e-9)


def test_memory_across_calls_equals_one_call() -> None:
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 20, 60))
    a = rng.choice(["x", "y", "z"], 60)
    whole = ShadowingMemory().fractions(t, a, tau_s=1.5)
    m = ShadowingMemory()
    parts = [m.fractions(t[i:j], a[i:j], tau_s=1.5) for i, j in ((0, 7), (7, 33), (33, 60))]
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=0)
    assert m.last_t == {k: float(t[a == k].max()) for k in ("x", "y", "z")}


def test_params_refuse_negative_time() -> None:
    with pytest.raises(Exception, match="shadowing_time_s"):
        ShadowingParams(shadowing_time_s=-1.0)


def test_update_with_fraction_equals_update_with_inflated_sigma() -> None:
    """w enters as the variance sigma^2 / w (the gate aside)."""
    s = FilterState.initial(t=0.0, xyz=(3.0, 4.0, 0.0), sigma_xy_m=2.0)
    a = np.array([0.0, 0.0, 0.0])
    upd = rss_update(s, a, -78.0, MODEL, gate_probability=None, info_fraction=0.25)
    ref = rss_update(s, a, -78.0, PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=10.0),
                     gate_probability=None)
    np.testing.assert_allclose(upd.state.x, ref.state.x, rtol=1e-12)
    np.testing.assert_allclose(upd.state.P, ref.state.P, rtol=1e-12)


def test_gate_uses_the_readings_own_variance() -> None:
    """A discounted reading is gated as the reading it is, not by its inflated variance."""
    s = FilterState.initial(t=0.0, xyz=(3.0, 4.0, 0.0), sigma_xy_m=0.3)
    a = np.array([0.0, 0.0, 0.0])
    full = rss_update(s, a, -20.0, MODEL)
    low = rss_update(s, a, -20.0, MODEL, info_fraction=0.01)
    assert not full.diagnostics.accepted and not low.diagnostics.accepted
    assert low.diagnostics.nis == pytest.approx(full.diagnostics.nis)


@settings(max_examples=60, deadline=None)
@given(gaps=st.lists(st.floats(0.0, 10.0), min_size=1, max_size=15),
       names=st.lists(st.sampled_from("abc"), min_size=15, max_size=15),
       tau=st.floats(0.0, 50.0))
def test_information_never_exceeds_the_independent_case(gaps: list[float], names: list[str],
                                                        tau: float) -> None:
    t = np.cumsum(gaps)
    a = np.array(names[:len(t)])
    w = ShadowingMemory().fractions(t, a, tau_s=tau)
    assert np.all((w >= 0.0) & (w <= 1.0))
    assert w.sum() <= len(t) + 1e-12
    # the posterior covariance is never smaller than with independent readings (readings
    # at their predicted value: the estimate stays put, so both runs share the Jacobians)
    s0 = FilterState.initial(t=0.0, xyz=(4.0, 2.0, 0.0), sigma_xy_m=3.0)
    s_ind, s_dis = s0, s0
    anchors = {"a": (0.0, 0.0, 0.0), "b": (10.0, 0.0, 0.0), "c": (0.0, 8.0, 0.0)}
    rss = {k: float(MODEL.expected_rss(math.dist(v[:2], (4.0, 2.0)))) for k, v in anchors.items()}
    for k in range(len(t)):
        s_ind = rss_update(s_ind, anchors[a[k]], rss[a[k]], MODEL, gate_probability=None).state
        s_dis = rss_update(s_dis, anchors[a[k]], rss[a[k]], MODEL, gate_probability=None,
                           info_fraction=float(w[k])).state
    info_ind = np.linalg.inv(s_ind.P[:2, :2])
    info_dis = np.linalg.inv(s_dis.P[:2, :2])
    assert np.linalg.eigvalsh(info_ind - info_dis).min() > -1e-6 * np.abs(info_ind).max()
