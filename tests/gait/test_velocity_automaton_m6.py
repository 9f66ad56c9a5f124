"""Colombo Sec. III-C guard M6 (our reading: drop the step's erroneous increment)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.gait.velocity_automaton import (
    AutomatonParams,
    AutomatonState,
    VelocityAutomaton,
    automaton_kernel,
)


def slow_automaton_m6(t: np.ndarray, a: np.ndarray, sigma: np.ndarray,
                      p: AutomatonParams) -> tuple[np.ndarray, np.ndarray]:
    """Pure-Python transcription with both M6 readings (reference for the kernel)."""
    mode, dv, v, nsteps = 0, 0.0, 0.0, 0
    t_still = t[0]
    f1 = f2 = a_prev = a[0]
    out = np.empty_like(a)
    modes = np.empty(a.shape[0], dtype=np.int64)
    for i in range(len(t)):
        dt = 0.0 if i == 0 else t[i] - t[i - 1]
        al = 1 - np.exp(-2 * np.pi * p.prefilter_hz * dt)
        f1 += al * (a[i] - f1)
        f2 += al * (f1 - f2)
        ai = f2
        if mode == 0:
            dv = v = 0.0
            if sigma[i] > p.sigma_min_m_s2 and t[i] - t_still >= p.tm_s and ai > 0:
                mode, nsteps, dv, v = 1, 0, dt * ai, dt * ai
        else:
            v_old = v
            dv += dt * ai
            v += dt * ai
            m6 = v_old >= 0 and v < 0
            if sigma[i] <= p.sigma_min_m_s2 or (m6 and p.m6_reset == "still"):
                mode, dv, v, t_still = 0, 0.0, 0.0, t[i]
            elif m6:
                v, dv = v - dv, 0.0
            elif mode == 1 and a_prev > 0 and ai <= 0:
                mode = 2
            elif mode == 2 and a_prev < 0 and ai >= 0:
                nsteps += 1
                if nsteps > p.settle_steps:
                    v -= dv
                dv = 0.0
                mode = 1
        a_prev = ai
        out[i] = v
        modes[i] = mode
    return out, modes


def _walk_with_brake(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start, steps, then a hard brake within one step (erroneous posture change)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 12, 0.01)
    a = np.where((t > 2) & (t < 10), 1.5 * np.sin(2 * np.pi * 1.8 * (t - 2)), 0.0)
    a += 0.6 * ((t > 2) & (t < 2.8))                      # start: +0.48 m/s
    a -= 3.0 * ((t > 6.0) & (t < 6.4))                    # brake: -1.2 m/s within a step
    a += rng.normal(0, 0.03, t.size)
    sigma = np.where((t > 2.2) & (t < 10.2), 1.0, 0.05)
    return t, a, sigma


@pytest.mark.parametrize("reading", ["step", "still"])
def test_kernel_matches_reference(reading: str) -> None:
    t, a, sigma = _walk_with_brake()
    p = AutomatonParams(m6_reset=reading)
    st_ = AutomatonState().values.copy()
    v = np.empty_like(t)
    mode = np.empty(t.size, dtype=np.int64)
    pars = np.array([p.sigma_min_m_s2, p.tm_s, float(p.settle_steps), p.prefilter_hz,
                     float(reading == "still")])
    automaton_kernel(t, a, sigma, pars, st_, v, mode)
    ref_v, ref_mode = slow_automaton_m6(t, a, sigma, p)
    np.testing.assert_allclose(v, ref_v, atol=1e-12)
    np.testing.assert_array_equal(mode, ref_mode)


def test_m6_readings_differ_as_documented() -> None:
    t, a, _ = _walk_with_brake()
    step = VelocityAutomaton(AutomatonParams(m6_reset="step")).process(t, a)
    still = VelocityAutomaton(AutomatonParams(m6_reset="still")).process(t, a)
    after = (t > 6.5) & (t < 9.5)
    # "still" drops to the still state at the brake (and waits Tm), "step" stays in motion
    assert np.any(still.mode[(t > 6.0) & (t < 6.6)] == 0)
    assert np.all(step.mode[(t > 6.0) & (t < 9.5)] != 0)
    assert np.all(step.velocity_m_s >= 0.0)
    assert np.mean(step.velocity_m_s[after]) >= np.mean(still.velocity_m_s[after])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), amp=st.floats(0.3, 3.0), brake=st.floats(0.0, 6.0))
def test_step_reading_never_gives_a_negative_speed(seed: int, amp: float, brake: float) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0, 8, 0.01)
    a = np.where(t > 1, amp * np.sin(2 * np.pi * rng.uniform(1.2, 2.4) * t), 0.0)
    a -= brake * ((t > 4) & (t < 4.3))
    a += rng.normal(0, 0.2, t.size)
    res = VelocityAutomaton().process(t, a)
    assert np.all(res.velocity_m_s >= 0.0)


def test_bad_m6_reading_is_named() -> None:
    with pytest.raises(InputError, match="m6_reset"):
        VelocityAutomaton(AutomatonParams(m6_reset="sometimes"))


def test_automaton_kernel_matches_python_reference() -> None:
    rng = np.random.default_rng(4)
    t = np.arange(0, 20, 0.01)
    a = np.where((t > 3) & (t < 15), 1.2 * np.sin(2 * np.pi * 1.8 * t) + 0.3 * (t < 4), 0.0)
    a = a + rng.normal(0, 0.05, t.size)
    sigma = np.where((t > 3.2) & (t < 15.2), 0.8, 0.05)
    p = AutomatonParams()
    st_ = AutomatonState().values.copy()
    v = np.empty_like(t)
    mode = np.empty(t.size, dtype=np.int64)
    pars = np.array([p.sigma_min_m_s2, p.tm_s, float(p.settle_steps), p.prefilter_hz])
    automaton_kernel(t, a, sigma, pars, st_, v, mode)
    np.testing.assert_allclose(v, slow_automaton_m6(t, a, sigma, p)[0], atol=1e-12)
    assert np.all(v[t < 3] == 0.0) and np.all(v[t > 16] == 0.0)
