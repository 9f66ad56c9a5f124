"""Inverted-pendulum step length: vertical excursion kernel, model, calibration, analyzer."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import cumulative_trapezoid

from hrtls.errors import InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length import displacements, step_model_from_dict
from hrtls.gait.step_length_fit import CalibrationWalk, fit_pendulum
from hrtls.gait.step_length_pendulum import PendulumModel, vertical_excursion
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate


def slow_excursion(t: np.ndarray, a: np.ndarray) -> float:
    """Reference with scipy: integrate, make periodic, zero mean, integrate, detrend."""
    v = cumulative_trapezoid(a, t, initial=0.0)
    v = v - v[-1] * (t - t[0]) / (t[-1] - t[0])
    v = v - v.mean()
    p = cumulative_trapezoid(v, t, initial=0.0)
    p = p - p[-1] * (t - t[0]) / (t[-1] - t[0])
    return float(p.max() - p.min())


def test_excursion_of_a_sinusoidal_bounce_hand_case() -> None:
    # z = A sin(2 pi f t): a = -A (2 pi f)^2 sin(2 pi f t); over one period h = 2 A
    amp, f = 0.025, 1.8
    t = np.arange(0.0, 3.0, 0.005)
    a = -amp * (2 * np.pi * f) ** 2 * np.sin(2 * np.pi * f * t) + 0.4  # + a constant bias
    t0 = np.array([0.1, 0.1 + 1 / f])
    h = vertical_excursion(t, a, t0, t0 + 1 / f)
    # the samples cover the period only up to one sample: a few % of the range
    np.testing.assert_allclose(h, 2 * amp, rtol=0.03)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(5, 120))
def test_excursion_matches_scipy_reference(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.015, 400))
    a = rng.normal(0.0, 2.0, t.size)
    i0 = int(rng.integers(0, t.size - n))
    h = vertical_excursion(t, a, t[i0:i0 + 1], t[i0 + n - 1:i0 + n])
    assert h[0] == pytest.approx(slow_excursion(t[i0:i0 + n], a[i0:i0 + n]), rel=1e-9,
                                 abs=1e-12)


def test_excursion_too_short_step_is_zero() -> None:
    t = np.arange(0.0, 1.0, 0.01)
    h = vertical_excursion(t, np.sin(t), np.array([0.5]), np.array([0.52]))
    assert h[0] == 0.0


def test_pendulum_model_hand_values_and_profile() -> None:
    m = PendulumModel(k=1.2, leg_length_m=1.0)
    steps = StepDetection.from_rows(np.array([[0.0, 0.5, 2.0, 1.0, -1.0],
                                              [0.5, 1.0, 2.0, 1.0, -1.0]]))
    h = np.array([0.05, 0.0])
    # 1.2 * 2 sqrt(2 * 1 * 0.05 - 0.05^2) = 1.2 * 2 * sqrt(0.0975)
    np.testing.assert_allclose(m.lengths(steps, h), [1.2 * 2 * np.sqrt(0.0975), 0.0])
    with pytest.raises(InputError):
        m.lengths(steps)
    with pytest.raises(InputError):
        PendulumModel(leg_length_m=0.0)
    again = step_model_from_dict(m.to_dict())
    assert again == m
    length, dz = displacements(steps, np.array([1, 0]), m, excursion_m=h)
    np.testing.assert_allclose(length, [1.2 * 2 * np.sqrt(0.0975), 0.0])
    np.testing.assert_allclose(dz, 0.0)


def test_fit_pendulum_recovers_k() -> None:
    base = PendulumModel(leg_length_m=0.9)
    rng = np.random.default_rng(1)
    walks = []
    for _ in range(3):
        n = 20
        steps = StepDetection.from_rows(np.column_stack([
            np.arange(n) * 0.5, np.arange(1, n + 1) * 0.5, np.full(n, 2.0), np.ones(n),
            -np.ones(n)]))
        h = rng.uniform(0.02, 0.05, n)
        dist = float(np.sum(1.3 * base.unit_lengths(h)))
        walks.append(CalibrationWalk(steps, dist, h))
    fitted = fit_pendulum(walks, base=base)
    assert fitted.k == pytest.approx(1.3)
    assert fitted.leg_length_m == 0.9
    with pytest.raises(InputError):
        fit_pendulum([CalibrationWalk(walks[0].steps, 5.0)])
    with pytest.raises(InputError):
        CalibrationWalk(walks[0].steps, 5.0, np.zeros(3))


def test_analyzer_with_calibrated_pendulum_on_simulated_walks() -> None:
    rng = np.random.default_rng(4)
    person = SimPerson.random(rng)
    ws = [simulate([(0, 3), (1, 30), (0, 3)], person=person, q_bd=random_mounting(rng),
                   seed=s) for s in (1, 2)]
    res = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=ws[0].q_bd).process(
        ws[0].t, ws[0].acc_d, ws[0].q_nd)
    s = res.steps
    assert res.step_excursion_m.shape == (len(s),)
    assert np.all(np.isfinite(res.step_excursion_m))
    walk = CalibrationWalk(StepDetection(s.t_start, s.t_end, s.frequency_hz, s.acc_max,
                                         s.acc_min), float(np.sum(ws[0].step_length_m)),
                           res.step_excursion_m)
    model = fit_pendulum([walk])
    other = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=ws[1].q_bd, step_model=model).process(
        ws[1].t, ws[1].acc_d, ws[1].q_nd)
    true = float(np.sum(ws[1].step_length_m))
    assert abs(float(np.sum(other.steps.length_m)) - true) < 0.05 * true
