"""How a walk ends when the person stops and stands: the last step and the closing movement.

Drawn from the development recording mobgap HA/001 (lower back; ``benchmarks/closing_steps.py``,
the walks of Test5 and Test11 that end standing; MS/001 and HA/002 held out). In the tracker's
own measure (a detected step's peak over the median of the 4 detected peaks before the last
step, the quantity ``WalkStepParams.closing_ratio`` is compared against) the last step the
INDIP reference counts peaks at 0.70-1.08 times the walk's level (median 0.85); after it comes
a closing movement (the trailing foot set beside the other) that no reference counts as a
contact, 0.28-0.49 times the walk's level, peaking 0.9-1.3 step periods after the last step
(5 of 6; one 1.9), with no forward progression. Both generators reproduce these in the
tracker's measure, each with its own amplitude constant: the short walks
(:func:`hrtls.gait.synthetic.short_walk_u_turn`: end ramp and closing pulse) and the scenario
simulator (:func:`stop_pulses`).

In the scenario simulator a stop-free run ends at rest on its last heel strike, where the
speed-driven oscillation has faded out; :func:`stop_pulses` adds to the vertical waist
displacement one step-like cycle centred on that heel strike's peak and one closing cycle
after it. Each cycle has zero net velocity and displacement, so positions and everything
outside the cycles are unchanged; the true steps are unchanged (the closing movement is no
step). The last step's cycle adds to what is left of the faded oscillation, which partly
cancels it, and the tracker's peak of the sum is lower again than the low-passed truth's, so
``LAST_STEP_CYCLE_RANGE`` is larger than the evidence's range: it is set so that the tracker's
measure of the simulated last steps matches the real one (docs/simulator.md). The closing
cycle, alone after the walk, matches with the evidence's range.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfilt

from hrtls.data import Activity, StepEvents

FloatArray = NDArray[np.float64]

LAST_STEP_AMPLITUDE_RANGE: tuple[float, float] = (0.6, 1.0)
"""Short walks: vertical amplitude at the end of the end ramp (the last step before standing),
share of the walking amplitude."""
LAST_STEP_CYCLE_RANGE: tuple[float, float] = (0.8, 1.2)
"""Scenario simulator: amplitude of the last step's cycle, share of the walk's level in the
``MEASURE_CUTOFF_HZ`` measure (set on development seeds 0-29, module notes)."""
CLOSING_AMPLITUDE_RANGE: tuple[float, float] = (0.28, 0.49)
"""Vertical amplitude of the closing movement, share of the walking amplitude (both
generators)."""
CLOSING_DELAY_STEPS_RANGE: tuple[float, float] = (0.9, 1.3)
"""Delay of the closing movement's peak after the last step, walking step periods."""
PEAK_DELAY_STEPS = 0.07
"""Vertical peak of a step after its heel strike, step periods (module notes of gait_model)."""
MEASURE_CUTOFF_HZ = 3.0
"""The evidence's peaks are of the vertical acceleration low-passed at this corner (4th-order
Butterworth, as the step detector sees it); levels and amplitudes are matched in that measure."""
LEVEL_STEPS = 4
"""The walk's level: median peak of this many steps before the last one (as in the evidence)."""


def cycle_acceleration(u: FloatArray) -> FloatArray:
    """One Hann-windowed cycle ``0.5 (1 + cos pi u) cos 2 pi u`` for ``|u| < 1``, else 0."""
    inside = np.abs(u) < 1.0
    return np.where(inside, 0.5 * (1.0 + np.cos(np.pi * u)) * np.cos(2.0 * np.pi * u), 0.0)


def cycle_displacement(u: FloatArray, period_s: float) -> FloatArray:
    """Displacement (per unit amplitude) of one cycle of ``u = (t - t_c) / period_s``.

    Its second time derivative is :func:`cycle_acceleration`; zero, with zero velocity, at
    and beyond ``|u| = 1``.
    """

    def f(x: FloatArray) -> FloatArray:
        return np.asarray(0.5 * np.cos(2.0 * np.pi * x) / (2.0 * np.pi) ** 2
                          + 0.25 * np.cos(np.pi * x) / np.pi ** 2
                          + 0.25 * np.cos(3.0 * np.pi * x) / (3.0 * np.pi) ** 2)

    inside = np.abs(u) < 1.0
    return np.where(inside, -(period_s ** 2) * (f(u) - f(np.ones(1))), 0.0)


def _runs(steps: StepEvents) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """First and last step index of each stop-free run."""
    n = len(steps)
    new_run = np.concatenate([[True], np.abs(steps.t_start[1:] - steps.t_end[:-1]) > 1e-9])
    first = np.flatnonzero(new_run)
    last = np.concatenate([first[1:] - 1, [n - 1]])
    return first.astype(np.int64), last.astype(np.int64)


def _step_peaks(t: FloatArray, acc: FloatArray, steps: StepEvents) -> FloatArray:
    """Maximum of ``acc`` within each step (heel strike to next heel strike)."""
    n = len(t)
    i0 = np.minimum(np.searchsorted(t, steps.t_start), n - 1)
    i1 = np.clip(np.searchsorted(t, steps.t_end, side="right"), i0 + 1, n)
    pairs = np.column_stack([i0, i1]).ravel()
    return np.asarray(np.maximum.reduceat(np.append(acc, 0.0), pairs)[::2], dtype=np.float64)


def stop_pulses(t: FloatArray, acc_up: FloatArray, steps: StepEvents, moving: NDArray[np.bool_],
                rng: np.random.Generator) -> FloatArray:
    """Vertical displacement (m) of the last step and closing movement of each walking stop.

    ``acc_up`` is the vertical acceleration of the oscillation, ``moving`` the samples that
    belong to a run. A run gets them when its last step is walking, it has more than
    ``LEVEL_STEPS`` steps, and the person stands until the closing cycle is over. The walk's
    level is the median peak (in the evidence's measure, ``MEASURE_CUTOFF_HZ``) of the
    ``LEVEL_STEPS`` steps before the last one, its period their median duration.
    """
    out = np.zeros(len(t))
    if len(steps) == 0 or len(t) < 2:
        return out
    first, last = _runs(steps)
    rate_hz = 1.0 / float(t[1] - t[0])
    sos = butter(4, min(MEASURE_CUTOFF_HZ, 0.45 * rate_hz), fs=rate_hz, output="sos")
    step_peaks = _step_peaks(t, sosfilt(sos, acc_up), steps)
    for a, b in zip(first, last, strict=True):
        # one draw per run (also for runs that get none), so runs draw independently
        end_amp, close_amp, delay = (rng.uniform(*LAST_STEP_CYCLE_RANGE),
                                     rng.uniform(*CLOSING_AMPLITUDE_RANGE),
                                     rng.uniform(*CLOSING_DELAY_STEPS_RANGE))
        if b - a < LEVEL_STEPS or int(steps.activity[b]) != int(Activity.WALKING):
            continue
        t_hs = float(steps.t_end[b])
        idx = np.arange(b - LEVEL_STEPS, b)
        period = float(np.median(steps.t_end[idx] - steps.t_start[idx]))
        level = float(np.median(step_peaks[idx]))
        t_pk = t_hs + PEAK_DELAY_STEPS * period
        t_close = t_pk + delay * period
        i_after = int(np.searchsorted(t, t_close + period))
        if i_after >= len(t) or np.any(moving[int(np.searchsorted(t, t_hs)) + 2:i_after + 1]):
            continue
        # filtered peak of a unit cycle of this period
        u = np.arange(-1.0, 3.0, 1.0 / (rate_hz * period))
        gain = float(np.max(sosfilt(sos, cycle_acceleration(u))))
        out += end_amp * level / gain * cycle_displacement((t - t_pk) / period, period)
        out += close_amp * level / gain * cycle_displacement((t - t_close) / period, period)
    return out
