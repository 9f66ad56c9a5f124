"""Step detection by peak and zero crossing on low-passed vertical acceleration.

Inderst Sec. 4.3.1 (Fig. 4.5) and Tarrio Sec. III-B: the vertical acceleration, low-passed during
pre-processing, rises above zero, peaks at the heel strike and falls below zero once per step. A
step is accepted at the down-going zero crossing when the peak of the positive lobe exceeds
``peak_threshold_m_s2`` (or ``relative_threshold`` times the 2 s standard deviation, whichever is
larger) and is at least ``min_step_s`` after the previous step. The step ends at the peak and
starts at the previous step's peak (after a pause longer than ``max_step_s`` the start is the end
minus the last step period).

A timing rule (our addition, for stops and turns): the trailing 2 s deviation still
holds the full-speed steps when a person slows down to stop or turns on the spot, so the weaker
last and turning steps fell under the relative threshold. A peak that comes on the walking
rhythm (between ``rhythm_min_ratio`` and ``rhythm_max_ratio`` times the last step period after
the previous step) is held only to ``rhythm_relative_threshold`` times the deviation; the
secondary lobes the relative threshold rejects come early in a step, off the rhythm. The
decision needs only the lobe's own samples and the last two step times: the step is still
released at its down-going zero crossing.

Zero crossings use a small hysteresis band and the signal is detrended by subtracting a slow
first-order low-pass (``detrend_cutoff_hz``) so that a bias in the levelled acceleration does not
move the crossings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_time, as_vector, check_positive
from hrtls.gait.motion_detector import RunningStd, RunningStdState
from hrtls.gait.pll import StepDetection
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True, slots=True)
class PeakStepParams:
    """Parameters of the peak / zero-crossing detector.

    Attributes
    ----------
    peak_threshold_m_s2: smallest accepted peak above the detrended zero, m/s^2.
    relative_threshold: the peak must also exceed this times the 2 s std (0 disables).
    hysteresis_m_s2: half-width of the zero-crossing band, m/s^2.
    min_step_s: shortest step, s.
    max_step_s: longest step; a longer gap is a pause, s.
    default_step_s: step period assumed for the first step after a pause, s.
    detrend_cutoff_hz: corner of the slow mean removed before crossing tests, Hz.
    std_window_s: window of the running standard deviation, s.
    rhythm_relative_threshold: relative threshold for a peak on the walking rhythm (at most
        ``relative_threshold``).
    rhythm_min_ratio, rhythm_max_ratio: a peak is on the rhythm when it comes this many last
        step periods after the previous step.
    """

    peak_threshold_m_s2: float = 0.45
    relative_threshold: float = 0.5
    hysteresis_m_s2: float = 0.05
    min_step_s: float = 0.25
    max_step_s: float = 1.5
    default_step_s: float = 0.55
    detrend_cutoff_hz: float = 0.3
    std_window_s: float = 2.0
    rhythm_relative_threshold: float = 0.4
    rhythm_min_ratio: float = 0.7
    rhythm_max_ratio: float = 1.4


@njit(cache=True)
def peak_step_kernel(t: FloatArray, x: FloatArray, sigma: FloatArray, pars: FloatArray,
                     st: FloatArray, steps: FloatArray) -> int:  # pragma: no cover
    """Scan a chunk; return the number of steps written to ``steps`` (rows as StepDetection).

    ``pars = [peak_thr, rel_thr, hyst, min_step, max_step, default_step, detrend_hz,
    rhythm_rel, rhythm_min, rhythm_max]``.
    ``st = [t_last, trend, positive, peak_val, peak_t, min_val, last_step_t, last_period,
    sigma_max]`` (``sigma_max``: largest deviation over the current positive lobe); ``t_last``
    NaN before the first sample.
    """
    thr, rel, hyst = pars[0], pars[1], pars[2]
    min_step, max_step, def_step, det_hz = pars[3], pars[4], pars[5], pars[6]
    rhythm_rel, rhythm_min, rhythm_max = pars[7], pars[8], pars[9]
    t_last, trend, positive, peak_val = st[0], st[1], st[2], st[3]
    peak_t, min_val, last_t, last_period, sig_max = st[4], st[5], st[6], st[7], st[8]
    ns = 0
    for i in range(t.shape[0]):
        if not np.isfinite(t_last):
            trend = x[i]
            dt = 0.0
        else:
            dt = t[i] - t_last
        t_last = t[i]
        trend += (1.0 - np.exp(-2.0 * np.pi * det_hz * dt)) * (x[i] - trend)
        v = x[i] - trend
        if positive == 0.0:
            if v < min_val:
                min_val = v
            if v > hyst:
                positive = 1.0
                peak_val = v
                peak_t = t[i]
                sig_max = sigma[i]
        else:
            if v > peak_val:
                peak_val = v
                peak_t = t[i]
            if sigma[i] > sig_max:
                sig_max = sigma[i]
            if v < -hyst:
                positive = 0.0
                gap = peak_t - last_t
                on_rhythm = (last_period > 0.0 and gap <= max_step
                             and rhythm_min * last_period <= gap <= rhythm_max * last_period)
                level = (min(rhythm_rel, rel) if on_rhythm else rel) * sig_max
                if level < thr:
                    level = thr
                if peak_val >= level and gap >= min_step:
                    if gap <= max_step:
                        start = last_t
                        last_period = gap
                    else:
                        start = peak_t - (last_period if last_period > 0 else def_step)
                    steps[ns, 0] = start
                    steps[ns, 1] = peak_t
                    steps[ns, 2] = 1.0 / (peak_t - start)
                    steps[ns, 3] = peak_val
                    steps[ns, 4] = min_val
                    ns += 1
                    last_t = peak_t
                    min_val = v
                elif v < min_val:
                    min_val = v
    st[0], st[1], st[2], st[3] = t_last, trend, positive, peak_val
    st[4], st[5], st[6], st[7], st[8] = peak_t, min_val, last_t, last_period, sig_max
    return ns


@dataclass
class PeakStepState:
    """Savable detector state (see :func:`peak_step_kernel`) and the std window."""

    values: FloatArray = field(default_factory=lambda: np.array(
        [np.nan, 0.0, 0.0, 0.0, 0.0, 0.0, -1e9, 0.0, 0.0]))
    window: RunningStdState | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (NaN written as None)."""
        return {"values": [None if not np.isfinite(v) else float(v) for v in self.values],
                "window": None if self.window is None else self.window.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PeakStepState:
        """Inverse of :meth:`to_dict`."""
        vals = np.array([np.nan if v is None else v for v in data["values"]], dtype=np.float64)
        win = data.get("window")
        return cls(vals, None if win is None else RunningStdState.from_dict(win))


class PeakStepDetector:
    """Peak + zero-crossing step detector (Inderst Sec. 4.3.1, Tarrio Sec. III-B)."""

    def __init__(self, params: PeakStepParams | None = None) -> None:
        self.params = params or PeakStepParams()
        p = self.params
        for name in ("min_step_s", "max_step_s", "default_step_s", "detrend_cutoff_hz",
                     "std_window_s"):
            check_positive(getattr(p, name), name)
        if not (0.0 < p.rhythm_min_ratio < p.rhythm_max_ratio) or \
                p.rhythm_relative_threshold < 0.0:
            raise InputError(
                f"rhythm ratios {p.rhythm_min_ratio}-{p.rhythm_max_ratio}, relative "
                f"{p.rhythm_relative_threshold}", where="PeakStepParams",
                expected="0 < rhythm_min_ratio < rhythm_max_ratio, "
                         "rhythm_relative_threshold >= 0")
        self._pars = np.array([p.peak_threshold_m_s2, p.relative_threshold, p.hysteresis_m_s2,
                               p.min_step_s, p.max_step_s, p.default_step_s,
                               p.detrend_cutoff_hz, p.rhythm_relative_threshold,
                               p.rhythm_min_ratio, p.rhythm_max_ratio])
        self._std = RunningStd(window_s=p.std_window_s)
        self.reset()

    def reset(self) -> None:
        """No step seen yet."""
        self._std.reset()
        self.state = PeakStepState(window=self._std.state)

    def update(self, t: FloatArray, a_vertical_lp_m_s2: FloatArray) -> StepDetection:
        """Process a chunk of low-passed vertical acceleration (m/s^2) at times ``t`` (s)."""
        last = self.state.values[0]
        tt = as_time(t, where="step detector time", after=last if np.isfinite(last) else -np.inf)
        x = as_vector(a_vertical_lp_m_s2, where="vertical acceleration", length=tt.shape[0])
        if self.state.window is not None:
            self._std.state = self.state.window
        _, sigma = self._std.update(tt, x)
        self.state.window = self._std.state
        steps = np.empty((tt.shape[0] // 2 + 2, 5))
        ns = peak_step_kernel(tt, x, sigma, self._pars, self.state.values, steps)
        return StepDetection.from_rows(steps[:ns])

    def process(self, t: FloatArray, a_vertical_lp_m_s2: FloatArray) -> StepDetection:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(t, a_vertical_lp_m_s2)
