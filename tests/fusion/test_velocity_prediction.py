from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.gating import is_spd
from hrtls.fusion.state import FilterState
from hrtls.fusion.velocity_prediction import (
    VelocityPredictionParams,
    VelocityPredictor,
    velocity_reference,
)


def inputs(n: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.002, 0.02, n))
    v = np.abs(rng.normal(1.0, 0.3, n))
    yaw = np.cumsum(rng.normal(0, 0.05, n))
    var_yaw = rng.uniform(1e-4, 1e-2, n)
    var_v = rng.uniform(1e-3, 1e-1, n)
    return t, v, yaw, var_yaw, var_v


@pytest.mark.parametrize("mode", ["input", "state"])
def test_kernel_matches_reference_and_chunks(mode: str) -> None:
    t, v, yaw, vy, vv = inputs(300, 3)
    s0 = FilterState.initial(t=0.0)
    prm = VelocityPredictionParams(heading_mode=mode)  # type: ignore[arg-type]
    pred = VelocityPredictor(prm)
    full = pred.run(s0, t, v, yaw, vy, vv)
    x_ref, p_ref = velocity_reference(t, v, yaw, vy, vv, s0, mode == "state",
                                      prm.heading_rate_var_rad2_s)
    np.testing.assert_allclose(full.state.x, x_ref, atol=1e-9)
    np.testing.assert_allclose(full.state.P, p_ref, atol=1e-9)
    a = pred.run(s0, t[:120], v[:120], yaw[:120], vy[:120], vv[:120])
    state = FilterState.from_dict(a.state.to_dict())   # save / restore between chunks
    b = pred.run(state, t[120:], v[120:], yaw[120:], vy[120:], vv[120:])
    np.testing.assert_allclose(b.state.x, full.state.x, atol=1e-12)
    np.testing.assert_allclose(b.state.P, full.state.P, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([a.xyz, b.xyz]), full.xyz, atol=1e-12)


def test_single_sample_eq_17() -> None:
    s0 = FilterState(0.0, np.zeros(4), np.zeros((4, 4)))
    res = VelocityPredictor().run(s0, [0.1], [2.0], [0.0], [0.01], [0.04])
    # p = [0.2, 0]; P = G_theta var G_theta^T + G_v var G_v^T
    np.testing.assert_allclose(res.xyz[0], [0.2, 0.0, 0.0])
    assert res.cov_xy[0, 1, 1] == pytest.approx((0.1 * 2.0) ** 2 * 0.01)
    assert res.cov_xy[0, 0, 0] == pytest.approx(0.1**2 * 0.04)


def test_circle_closes() -> None:
    fs = 100.0
    t = np.arange(1, 2001) / fs                  # 20 s, one lap of a circle of 20 m
    omega = 2 * np.pi / 20.0
    yaw = omega * t
    res = VelocityPredictor().run(FilterState.initial(), t, np.full(t.size, 1.0), yaw)
    np.testing.assert_allclose(res.xyz[-1, :2], [0.0, 0.0], atol=0.05)
    assert np.max(np.abs(res.xyz[:, 1])) > 6.0


def test_rejects_bad_input() -> None:
    pred = VelocityPredictor()
    s0 = FilterState.initial(t=1.0)
    with pytest.raises(InputError):
        pred.run(s0, [0.5, 1.2], [1.0, 1.0], [0.0, 0.0])   # before the state time
    with pytest.raises(InputError):
        pred.run(s0, [1.1, 1.2], [1.0, -1.0], [0.0, 0.0])
    with pytest.raises(InputError):
        pred.run(s0, [1.1, 1.2], [1.0, 1.0], [0.0, np.nan])


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(["input", "state"]))
def test_covariance_stays_spd(seed: int, mode: str) -> None:
    t, v, yaw, vy, vv = inputs(100, seed)
    res = VelocityPredictor(VelocityPredictionParams(heading_mode=mode)).run(  # type: ignore[arg-type]
        FilterState.initial(), t, v, yaw, vy, vv)
    assert is_spd(res.state.P)
    assert np.all(np.linalg.eigvalsh(res.cov_xy) > -1e-12)
    assert np.all(np.abs(res.heading_rad) <= np.pi)


def test_state_mode_adopts_first_yaw_when_start_heading_unknown() -> None:
    s = FilterState.initial(sigma_heading_rad=np.pi)
    res = VelocityPredictor(VelocityPredictionParams(heading_mode="state")).run(
        s, [0.1, 0.2], [1.0, 1.0], [1.0, 1.0], 0.01)
    assert res.heading_rad[0] == pytest.approx(1.0)
    assert res.var_heading[0] == pytest.approx(0.01)
