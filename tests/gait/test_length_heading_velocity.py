"""Step length models and their calibration, Fourier heading, velocity automaton."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.gait.fourier_heading import (
    FourierHeading,
    FourierHeadingParams,
    FourierHeadingState,
    average_two,
)
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length import (
    FrequencyLawModel,
    StairsModel,
    WeinbergModel,
    displacements,
    step_model_from_dict,
)
from hrtls.gait.step_length_fit import (
    CalibrationWalk,
    calibration_points,
    fit_frequency_law,
    fit_weinberg,
    mean_frequency,
)
from hrtls.gait.velocity_automaton import (
    AutomatonState,
    VelocityAutomaton,
)


def steps_from(freq: np.ndarray, span: np.ndarray) -> StepDetection:
    t_end = np.cumsum(1.0 / freq)
    return StepDetection(t_end - 1.0 / freq, t_end, freq, span / 2, -span / 2)


def test_weinberg_hand_values() -> None:
    st_ = steps_from(np.array([2.0, 2.0]), np.array([16.0, 1.0]))
    np.testing.assert_allclose(WeinbergModel(k=0.5).lengths(st_), [1.0, 0.5])


def test_frequency_law_segments_and_clip() -> None:
    m = FrequencyLawModel(walk_slope_m_s=0.4, walk_intercept_m=0.0, run_slope_m_s=0.1,
                          run_intercept_m=0.8, split_hz=2.5, max_length_m=1.5)
    np.testing.assert_allclose(m.length_at([2.0, 3.0, 2.4999, 30.0]), [0.8, 1.1, 0.99996, 1.5])
    with pytest.raises(InputError):
        m.length_at([np.nan])


def test_displacements_stairs_and_standing() -> None:
    st_ = steps_from(np.full(4, 2.0), np.full(4, 16.0))
    act = np.array([Activity.WALKING, Activity.UPSTAIRS, Activity.DOWNSTAIRS, Activity.STANDING])
    length, dz = displacements(st_, act, WeinbergModel(k=0.5), StairsModel(depth_m=0.3,
                                                                            height_m=0.17))
    np.testing.assert_allclose(length, [1.0, 0.3, 0.3, 0.0])
    np.testing.assert_allclose(dz, [0.0, 0.17, -0.17, 0.0])
    with pytest.raises(InputError):
        displacements(st_, act[:2], WeinbergModel())


def test_model_dict_roundtrip() -> None:
    for m in (WeinbergModel(k=0.41), FrequencyLawModel(walk_slope_m_s=0.3)):
        assert step_model_from_dict(m.to_dict()) == m
    with pytest.raises(InputError):
        step_model_from_dict({"kind": "magic"})


@settings(max_examples=50, deadline=None)
@given(k=st.floats(0.2, 0.8), seed=st.integers(0, 1000))
def test_fit_weinberg_recovers_k(k: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    walks = []
    for _ in range(3):
        span = rng.uniform(1, 10, 20)
        s = steps_from(np.full(20, 1.8), span)
        walks.append(CalibrationWalk(s, float(np.sum(k * span ** 0.25))))
    assert fit_weinberg(walks).k == pytest.approx(k, rel=1e-9)


def test_fit_frequency_law_eq_1_2() -> None:
    # walks at several paces on the line SL = 0.3 f + 0.1 (walking) and 0.2 f + 0.5 (running)
    walks = []
    for f in (1.6, 1.9, 2.2, 2.8, 3.3):
        freq = np.full(30, f)
        sl = 0.3 * f + 0.1 if f < 2.45 else 0.2 * f + 0.5
        walks.append(CalibrationWalk(steps_from(freq, np.ones(30)), 30 * sl))
    m = fit_frequency_law(walks)
    assert m.walk_slope_m_s == pytest.approx(0.3)
    assert m.walk_intercept_m == pytest.approx(0.1)
    assert m.run_slope_m_s == pytest.approx(0.2)
    assert m.run_intercept_m == pytest.approx(0.5)
    f, sl = calibration_points(walks)
    np.testing.assert_allclose(f, [1.6, 1.9, 2.2, 2.8, 3.3])
    # eq. 1 is the harmonic mean of the step frequencies
    s = steps_from(np.array([1.0, 2.0]), np.ones(2))
    assert mean_frequency(s) == pytest.approx(2 / (1 + 0.5))
    # one pace only: slope kept, intercept fitted
    one = fit_frequency_law(walks[:1], base=FrequencyLawModel(walk_slope_m_s=0.25))
    assert one.walk_slope_m_s == 0.25
    assert one.length_at([1.6])[0] == pytest.approx(0.3 * 1.6 + 0.1)
    with pytest.raises(InputError):
        CalibrationWalk(s, -1.0)


def planar_walk(direction: float, rate: float = 100.0, n_steps: int = 12,
                f: float = 1.8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal acceleration of a straight walk: forward decel early, accel late each step."""
    t = np.arange(0, n_steps / f, 1 / rate)
    phi = 2 * np.pi * f * t
    fwd = 1.5 * np.cos(phi - 1.4 * np.pi)
    lat = 0.8 * np.sin(phi / 2 + 0.3)
    c, s = np.cos(direction), np.sin(direction)
    a = np.column_stack([c * fwd - s * lat, s * fwd + c * lat])
    ends = np.arange(1, n_steps) / f
    return t, a, ends


@settings(max_examples=60, deadline=None)
@given(direction=st.floats(-np.pi, np.pi))
def test_fourier_heading_recovers_direction(direction: float) -> None:
    t, a, ends = planar_walk(direction)
    res = FourierHeading().process(t, a, ends)
    h = res.heading_rad[np.isfinite(res.heading_rad)]
    assert h.size >= len(ends) - 3
    assert np.max(np.abs(wrap_angle(h - direction))) < np.deg2rad(3.0)


def test_fourier_heading_tip_order_flips_direction() -> None:
    t, a, ends = planar_walk(0.3)
    res = FourierHeading(FourierHeadingParams(tip_is_second=False)).process(t, a, ends)
    h = res.heading_rad[np.isfinite(res.heading_rad)]
    assert np.max(np.abs(wrap_angle(h - 0.3 - np.pi))) < np.deg2rad(3.0)


def test_fourier_heading_chunks_equal_batch() -> None:
    t, a, ends = planar_walk(1.0, n_steps=20)
    whole = FourierHeading().process(t, a, ends)
    fh = FourierHeading()
    k = 333
    r1 = fh.update(t[:k], a[:k], ends[ends <= t[k - 1]])
    fh.state = FourierHeadingState.from_dict(fh.state.to_dict())
    r2 = fh.update(t[k:], a[k:], ends[ends > t[k - 1]])
    np.testing.assert_allclose(np.concatenate([r1.heading_rad, r2.heading_rad]),
                               whole.heading_rad, equal_nan=True, atol=1e-12)


def test_average_two_is_circular() -> None:
    out = average_two(np.array([np.pi - 0.1, -np.pi + 0.1]), np.nan)
    assert abs(abs(out[1]) - np.pi) < 1e-12


def test_automaton_keeps_start_velocity_and_chunks() -> None:
    t = np.arange(0, 12, 0.01)
    # ramp to 1.2 m/s within 1 s, then oscillation, then stop
    speed = np.clip(t - 2, 0, 1) * 1.2 * (t < 10)
    acc = np.gradient(speed, 0.01) + np.where((t > 2) & (t < 10),
                                               1.0 * np.sin(2 * np.pi * 1.8 * (t - 2)), 0)
    va = VelocityAutomaton()
    res = va.process(t, acc)
    mid = (t > 5) & (t < 9)
    assert 0.6 < np.median(res.velocity_m_s[mid]) < 1.6
    va.reset()
    r1 = va.update(t[:500], acc[:500])
    va.state = AutomatonState.from_dict(va.state.to_dict())
    r2 = va.update(t[500:], acc[500:])
    np.testing.assert_allclose(np.concatenate([r1.velocity_m_s, r2.velocity_m_s]),
                               res.velocity_m_s, atol=1e-12)
