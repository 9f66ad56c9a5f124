"""Step detection with a phase-locked loop on vertical acceleration (Basso Sec. II-C, Fig. 2-3).

The loop has the three parts of Basso Fig. 2:

* phase detector: ``e = -x_n sin(phi)``, the product of the normalized input
  ``x_n = (a_z - mu_z) / sigma_z`` (window mean and std of the motion detector, Sec. II-B) and the
  quadrature of the oscillator; its slow part is ``(A/2) sin(theta - phi)`` for an input
  ``A cos(theta)``;
* loop filter: a first-order low-pass (``detector_cutoff_hz``) removing the double-frequency term,
  followed by a proportional-integral controller (type-2 loop, zero phase error in lock);
* controlled oscillator: ``phi += 2 pi f dt`` with ``f = f_free + k_p e_f + k_i int(e_f)``, clipped
  to ``[min_frequency_hz, walk_max_frequency_hz]`` while walking (so that the loop cannot slip
  onto the second harmonic of a walking signal) and to ``[min_frequency_hz, max_frequency_hz]``
  while running; its output is ``cos(phi)``. When the motion class changes during motion the
  integrator is re-set so that the frequency stays continuous (only a loop that starts from rest
  starts at the free-running frequency of its class).

In lock ``phi = theta``, so the oscillator peaks (``phi`` crossing a multiple of ``2 pi``) fall on
the peaks of the fundamental of ``a_z``; each peak ends one step and starts the next. The step
frequency is ``f_k = 1 / T_k`` (Basso Sec. II-C). The loop runs only while the motion detector
reports motion; when motion resumes the instant is kept as the start of the next step so that the
arrest time is not counted. The free-running frequency is ``walk_frequency_hz`` (1.8 Hz, Basso)
while walking and ``run_frequency_hz`` while running (our choice, so that the loop also locks on
running steps at 2.5 to 4 Hz).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import (
    FloatArray,
    as_time,
    as_vector,
    check_positive,
    state_from_dict,
)
from hrtls.gait.motion_detector import RUN, MotionResult
from hrtls.kernels import njit

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, kw_only=True, slots=True)
class PllParams:
    """Parameters of the step PLL.

    Attributes
    ----------
    walk_frequency_hz: free-running frequency while walking, Hz (1.8 in Basso).
    run_frequency_hz: free-running frequency while running, Hz.
    min_frequency_hz, max_frequency_hz: limits of the oscillator frequency, Hz.
    walk_max_frequency_hz: upper limit while walking, Hz (Basso: walking up to ~2.2 Hz).
    loop_natural_hz: natural frequency of the linearized loop, Hz.
    damping: damping ratio of the linearized loop.
    detector_cutoff_hz: corner of the low-pass after the phase detector, Hz.
    min_sigma_m_s2: floor of the normalizing standard deviation, m/s^2.
    """

    walk_frequency_hz: float = 1.8
    run_frequency_hz: float = 2.8
    min_frequency_hz: float = 0.6
    max_frequency_hz: float = 4.5
    walk_max_frequency_hz: float = 2.6
    loop_natural_hz: float = 0.5
    damping: float = 0.8
    detector_cutoff_hz: float = 2.0
    min_sigma_m_s2: float = 0.05

    def gains(self) -> tuple[float, float]:
        """(k_p, k_i) of the PI filter in Hz per unit detector output (k_i per s).

        For a unit-variance sinusoid the detector gain is ``K_d = 1/sqrt(2)``; the closed loop
        ``s^2 + 2 pi K_d k_p s + 2 pi K_d k_i`` gets natural frequency ``w_n`` and damping
        ``zeta`` with ``k_i = w_n^2 / (2 pi K_d)`` and ``k_p = 2 zeta w_n / (2 pi K_d)``.
        """
        kd = 1.0 / np.sqrt(2.0)
        wn = TWO_PI * self.loop_natural_hz
        return 2.0 * self.damping * wn / (TWO_PI * kd), wn * wn / (TWO_PI * kd)


@njit(cache=True)
def pll_kernel(t: FloatArray, x: FloatArray, mean: FloatArray, sigma: FloatArray,
               mode: np.ndarray, pars: FloatArray, st: FloatArray, osc: FloatArray,
               freq: FloatArray, steps: FloatArray) -> int:  # pragma: no cover
    """Run the loop over a chunk; return the number of steps written to ``steps``.

    ``pars = [f_walk, f_run, f_min, f_max, k_p, k_i, lp_cutoff, min_sigma, walk_max]``.
    ``st = [phase, integ, e_f, t_last, enabled, t_prev_step, acc_max, acc_min, f, mode]``
    (updated in place; ``t_last`` NaN before the first sample).
    ``steps`` rows: ``t_start, t_end, frequency, acc_max, acc_min``.
    """
    f_walk, f_run, f_min, f_hi = pars[0], pars[1], pars[2], pars[3]
    walk_max = pars[8]
    last_mode = st[9]
    kp, ki, lp_hz, min_sig = pars[4], pars[5], pars[6], pars[7]
    phase, integ, e_f, t_last = st[0], st[1], st[2], st[3]
    enabled, t_prev, amax, amin, f = st[4], st[5], st[6], st[7], st[8]
    ns = 0
    for i in range(t.shape[0]):
        dt = 0.0 if not np.isfinite(t_last) else t[i] - t_last
        t_last = t[i]
        f0 = f_run if mode[i] == 2 else f_walk
        f_max = f_hi if mode[i] == 2 else walk_max
        if enabled == 1.0 and mode[i] != 0 and mode[i] != last_mode and last_mode != 0:
            # class change in motion: keep the frequency continuous
            integ += ((f_walk if last_mode == 2 else f_run) - f0) / ki
        last_mode = float(mode[i])
        if mode[i] == 0:
            # arrest: the detector is disabled and the loop returns to free running
            enabled = 0.0
            integ = 0.0
            e_f = 0.0
            f = f0
            phase += TWO_PI * f * dt
            if phase >= TWO_PI:
                phase -= TWO_PI * np.floor(phase / TWO_PI)
            osc[i] = np.cos(phase)
            freq[i] = f
            continue
        if enabled == 0.0:
            enabled = 1.0
            t_prev = t[i]  # the step period starts when motion resumes
            amax = x[i]
            amin = x[i]
        s = sigma[i] if sigma[i] > min_sig else min_sig
        xn = (x[i] - mean[i]) / s
        e = -xn * np.sin(phase)
        alpha = 1.0 - np.exp(-TWO_PI * lp_hz * dt)
        e_f += alpha * (e - e_f)
        integ += e_f * dt
        f = f0 + kp * e_f + ki * integ
        if f > f_max:
            integ -= e_f * dt
            f = f_max
        elif f < f_min:
            integ -= e_f * dt
            f = f_min
        prev = phase
        phase += TWO_PI * f * dt
        if x[i] > amax:
            amax = x[i]
        if x[i] < amin:
            amin = x[i]
        if phase >= TWO_PI:
            frac = (TWO_PI - prev) / (phase - prev)
            t_step = t[i] - dt + frac * dt
            if t_step > t_prev:
                steps[ns, 0] = t_prev
                steps[ns, 1] = t_step
                steps[ns, 2] = 1.0 / (t_step - t_prev)
                steps[ns, 3] = amax
                steps[ns, 4] = amin
                ns += 1
            t_prev = t_step
            amax = x[i]
            amin = x[i]
            phase -= TWO_PI * np.floor(phase / TWO_PI)
        osc[i] = np.cos(phase)
        freq[i] = f
    st[0], st[1], st[2], st[3] = phase, integ, e_f, t_last
    st[4], st[5], st[6], st[7], st[8] = enabled, t_prev, amax, amin, f
    st[9] = last_mode
    return ns


@dataclass
class PllState:
    """Savable loop state.

    ``values = [phase, integ, e_f, t_last, enabled, t_prev_step, acc_max, acc_min, frequency,
    mode]``
    (t_last NaN before the first sample).
    """

    values: FloatArray = field(default_factory=lambda: np.array(
        [0.0, 0.0, 0.0, np.nan, 0.0, 0.0, 0.0, 0.0, 1.8, 0.0]))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (NaN written as None)."""
        return {"values": [None if not np.isfinite(v) else float(v) for v in self.values]}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PllState:
        """Inverse of :meth:`to_dict`."""
        return state_from_dict(cls, {"values": [np.nan if v is None else v
                                                for v in data["values"]]})


@dataclass(frozen=True, slots=True, eq=False)
class StepDetection:
    """Steps found by a detector.

    Attributes
    ----------
    t_start, t_end: step boundaries, s.
    frequency_hz: ``1 / (t_end - t_start)``, Hz.
    acc_max, acc_min: extremes of the detector's input signal within the step, m/s^2.
    """

    t_start: FloatArray
    t_end: FloatArray
    frequency_hz: FloatArray
    acc_max: FloatArray
    acc_min: FloatArray

    def __len__(self) -> int:
        return int(self.t_end.shape[0])

    @classmethod
    def from_rows(cls, rows: FloatArray) -> StepDetection:
        """From an (N, 5) array ``t_start, t_end, frequency, acc_max, acc_min``."""
        r = np.ascontiguousarray(rows, dtype=np.float64).reshape(-1, 5)
        return cls(r[:, 0].copy(), r[:, 1].copy(), r[:, 2].copy(), r[:, 3].copy(),
                   r[:, 4].copy())

    @classmethod
    def concat(cls, parts: list[StepDetection]) -> StepDetection:
        """Join chunk results."""
        if not parts:
            return cls.from_rows(np.zeros((0, 5)))
        return cls(*(np.concatenate([getattr(p, name) for p in parts])
                     for name in ("t_start", "t_end", "frequency_hz", "acc_max", "acc_min")))


@dataclass(frozen=True, slots=True, eq=False)
class PllResult:
    """Output of :class:`PllStepDetector` for one chunk.

    Attributes
    ----------
    steps: detected steps.
    oscillator: oscillator output ``cos(phi)`` per sample.
    frequency_hz: oscillator frequency per sample, Hz.
    """

    steps: StepDetection
    oscillator: FloatArray
    frequency_hz: FloatArray


class PllStepDetector:
    """Basso Sec. II-C step detector (phase-locked loop on vertical acceleration)."""

    def __init__(self, params: PllParams | None = None) -> None:
        self.params = params or PllParams()
        p = self.params
        for name in ("walk_frequency_hz", "run_frequency_hz", "min_frequency_hz",
                     "max_frequency_hz", "walk_max_frequency_hz", "loop_natural_hz", "damping",
                     "detector_cutoff_hz", "min_sigma_m_s2"):
            check_positive(getattr(p, name), name)
        if not (p.min_frequency_hz < p.walk_frequency_hz < p.walk_max_frequency_hz
                <= p.max_frequency_hz
                and p.min_frequency_hz < p.run_frequency_hz < p.max_frequency_hz):
            raise InputError("free-running frequency outside the limits", where="PllParams",
                             expected="min < walk_frequency < walk_max <= max and "
                                      "min < run_frequency < max (Hz)")
        kp, ki = p.gains()
        self._pars = np.array([p.walk_frequency_hz, p.run_frequency_hz, p.min_frequency_hz,
                               p.max_frequency_hz, kp, ki, p.detector_cutoff_hz,
                               p.min_sigma_m_s2, p.walk_max_frequency_hz])
        self.reset()

    def reset(self) -> None:
        """Back to free running, no step in progress."""
        self.state = PllState()
        self.state.values[8] = self.params.walk_frequency_hz

    def update(self, a_vertical_m_s2: FloatArray, motion: MotionResult) -> PllResult:
        """Process one chunk.

        Parameters
        ----------
        a_vertical_m_s2: vertical acceleration (navigation frame), m/s^2, (N,).
        motion: the motion detector output for the same samples (gives mean, sigma, gating).
        """
        t = motion.t
        last = self.state.values[3]
        as_time(t, where="pll time", after=last if np.isfinite(last) else -np.inf)
        x = as_vector(a_vertical_m_s2, where="pll vertical acceleration", length=t.shape[0])
        n = t.shape[0]
        osc = np.empty(n)
        freq = np.empty(n)
        steps = np.empty((n // 2 + 2, 5))
        mode = np.ascontiguousarray(motion.state, dtype=np.int64)
        ns = pll_kernel(t, x, motion.mean_m_s2, motion.sigma_m_s2, mode, self._pars,
                        self.state.values, osc, freq, steps)
        return PllResult(StepDetection.from_rows(steps[:ns]), osc, freq)

    def process(self, a_vertical_m_s2: FloatArray, motion: MotionResult) -> PllResult:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(a_vertical_m_s2, motion)


__all__ = ["RUN", "PllParams", "PllResult", "PllState", "PllStepDetector", "StepDetection",
           "pll_kernel"]
