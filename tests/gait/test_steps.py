"""Step detection: peak / zero crossing (Inderst 4.3.1) and the PLL (Basso II-C)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.gait.motion_detector import MotionDetector, MotionParams
from hrtls.gait.peak_steps import PeakStepDetector, PeakStepParams, PeakStepState
from hrtls.gait.pll import PllParams, PllState, PllStepDetector


def test_peak_detector_hand_case() -> None:
    # cos at 2 Hz with amplitude 2: peaks at 0.5, 1.0, ... (t=0 is also a peak but has no
    # preceding rise)
    t = np.arange(0, 5.0, 0.01)
    x = 2.0 * np.cos(2 * np.pi * 2.0 * t)
    steps = PeakStepDetector(PeakStepParams()).process(t, x)
    # the detrending low-pass starts at x[0]: the first peak may be missed while it settles
    np.testing.assert_allclose(steps.t_end[-8:], np.arange(1.0, 4.75, 0.5), atol=0.011)
    np.testing.assert_allclose(steps.frequency_hz[1:], 2.0, atol=0.05)
    # extremes are of the detrended signal: their range is the peak-to-peak amplitude
    np.testing.assert_allclose((steps.acc_max - steps.acc_min)[-6:], 4.0, atol=0.1)
    np.testing.assert_allclose(steps.t_start[1:], steps.t_end[:-1])


def test_peak_detector_ignores_small_and_too_close_peaks() -> None:
    t = np.arange(0, 10.0, 0.01)
    small = 0.2 * np.sin(2 * np.pi * 2.0 * t)
    assert len(PeakStepDetector().process(t, small)) == 0
    fast = 2.0 * np.sin(2 * np.pi * 6.0 * t)  # 6 Hz: peaks 0.167 s apart < min_step_s
    steps = PeakStepDetector().process(t, fast)
    assert np.all(np.diff(steps.t_end) >= 0.25 - 1e-9)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 1000), split=st.integers(1, 999))
def test_peak_detector_chunked_equals_batch(seed: int, split: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0, 10.0, 0.01)
    x = 1.5 * np.sin(2 * np.pi * rng.uniform(1.5, 2.5) * t) + rng.normal(0, 0.2, t.size)
    det = PeakStepDetector()
    whole = det.process(t, x)
    det.reset()
    a = det.update(t[:split], x[:split])
    saved = det.state.to_dict()
    det2 = PeakStepDetector()  # a fresh detector restored from the saved state
    det2.state = PeakStepState.from_dict(saved)
    b = det2.update(t[split:], x[split:])
    np.testing.assert_allclose(np.concatenate([a.t_end, b.t_end]), whole.t_end)


def test_pll_locks_on_walking_and_running_and_idles_when_still() -> None:
    rate = 100.0
    t = np.arange(0, 40, 1 / rate)
    f = np.where(t < 5, 0.0, np.where(t < 25, 1.6, 2.9))
    phase = 2 * np.pi * np.cumsum(f) / rate
    amp = np.where(t < 5, 0.05, np.where(t < 25, 3.0, 9.0))
    x = 9.81 + amp * np.cos(phase)
    motion = MotionDetector().process(t, x)
    res = PllStepDetector().process(x, motion)
    ends = res.steps.t_end
    assert not np.any(ends < 5.0)
    walk = ends[(ends > 12) & (ends < 25)]
    np.testing.assert_allclose(1 / np.diff(walk), 1.6, atol=0.1)
    run = ends[(ends > 31)]
    np.testing.assert_allclose(1 / np.diff(run), 2.9, atol=0.15)
    # in lock the oscillator peaks sit on the input peaks (phase error small)
    ph_at = np.interp(walk, t, phase)
    err = np.angle(np.exp(1j * ph_at))
    assert np.max(np.abs(err)) < 0.5
    assert np.all(np.abs(res.oscillator) <= 1.0)


def test_pll_chunks_and_state_roundtrip() -> None:
    t = np.arange(0, 20, 0.01)
    x = 9.81 + 3 * np.cos(2 * np.pi * 1.9 * t)
    motion = MotionDetector(MotionParams()).process(t, x)
    det = PllStepDetector()
    whole = det.process(x, motion)
    det.reset()
    m1 = MotionDetector().process(t[:777], x[:777])
    a = det.update(x[:777], m1)
    det.state = PllState.from_dict(det.state.to_dict())
    md = MotionDetector()
    md.process(t[:777], x[:777])
    m2 = md.update(t[777:], x[777:])
    b = det.update(x[777:], m2)
    np.testing.assert_allclose(np.concatenate([a.steps.t_end, b.steps.t_end]),
                               whole.steps.t_end, atol=1e-9)


def test_pll_parameter_checks() -> None:
    with pytest.raises(InputError):
        PllStepDetector(PllParams(walk_frequency_hz=5.0, max_frequency_hz=4.5))
    with pytest.raises(InputError):
        PllStepDetector(PllParams(damping=0.0))
    kp, ki = PllParams().gains()
    assert kp > 0 and ki > 0
