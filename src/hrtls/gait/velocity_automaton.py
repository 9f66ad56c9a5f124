"""Walking velocity by the hybrid automaton of Colombo Sec. III-C (Fig. 3, eq. 12-14).

Input: the tangential acceleration ``a_xu`` of the user frame (eq. 12: the body-forward
acceleration with roll and pitch removed, i.e. levelled, gravity-free). States:
``0`` still (``x_s = 0``), ``1`` accelerating and ``2`` decelerating part of a step, where
``x_s = [delta_v, v]`` integrates ``a_xu`` (``A = I``, ``B = T_c 1``).

Guards: M1 ``std(a_xu)`` over ``Tm`` > ``sigma_min``; M2 time in state 0 >= ``Tm``; M3 ``a_xu``
crosses zero downwards; M4 crosses zero upwards; M5 ``a_xu > 0``; M6 ``v`` changes sign.
Fig. 3 (the edges) is not legible in our copy; we use the edges the text implies:

* 0 -> 1 on M1 and M2 and M5 (motion starts with a forward acceleration);
* 1 -> 2 on M3, 2 -> 1 on M4 with the reset of eq. 13-14: ``delta_v = 0`` and
  ``v = v`` during the first two steps, ``v = v - delta_v`` afterwards;
* 1 or 2 -> 0 on not M1 (motion ended), resetting ``x_s = 0``;
* M6: the text says it "removes sudden, erroneous velocity variations occurring during one
  step". We read it as: when ``v`` turns negative (a forward walking speed cannot), the
  variation of the current step is dropped, ``v = v - delta_v`` (the value at the step's
  start) and ``delta_v = 0``, staying in motion (``m6_reset="step"``, default). The earlier
  reading, a reset to the still state (``m6_reset="still"``), zeroes the speed of a walker
  whose slow-down into a corner outweighs the kept increments, and with M2 loses the next
  ``Tm`` of motion as well (Colombo's square, Case B).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_time, as_vector, check_positive
from hrtls.gait.motion_detector import RunningStd, RunningStdState
from hrtls.kernels import njit

IntArray = NDArray[np.int64]


@dataclass(frozen=True, kw_only=True, slots=True)
class AutomatonParams:
    """Parameters of the velocity automaton (Colombo Sec. III-C, V).

    Attributes
    ----------
    sigma_min_m_s2: motion threshold on the std of ``a_xu``, m/s^2 (0.2).
    tm_s: window of the std and minimum time in the still state, s (0.5).
    settle_steps: steps during which the velocity increment is kept (2, eq. 14).
    prefilter_hz: corner of two cascaded first-order low-passes applied to ``a_xu`` before the
        zero-crossing guards (our addition: sensor noise otherwise makes M3/M4 chatter), Hz.
    m6_reset: what M6 does: ``"step"`` drops the current step's increment (default),
        ``"still"`` goes to the still state (see the module docstring).
    """

    sigma_min_m_s2: float = 0.2
    tm_s: float = 0.5
    settle_steps: int = 2
    prefilter_hz: float = 2.0
    m6_reset: str = "step"


@njit(cache=True)
def automaton_kernel(t: FloatArray, a: FloatArray, sigma: FloatArray, pars: FloatArray,
                     st: FloatArray, v_out: FloatArray,
                     mode_out: np.ndarray) -> None:  # pragma: no cover
    """Run the automaton over a chunk (state updated in place).

    ``pars = [sigma_min, tm, settle_steps, prefilter_hz, m6_still]`` (``m6_still`` 1: M6 goes
    to the still state, 0 or absent: M6 restores the step's start velocity);
    ``st = [mode, delta_v, v, t_enter_still, a_prev, steps, t_last, f1, f2]`` (t_last NaN at
    start; f1, f2 the low-pass states).
    """
    smin, tm, settle, fc = pars[0], pars[1], pars[2], pars[3]
    m6_still = pars.shape[0] > 4 and pars[4] > 0.5
    mode, dv, v, t_still, a_prev, nsteps, t_last = st[0], st[1], st[2], st[3], st[4], st[5], st[6]
    f1, f2 = st[7], st[8]
    for i in range(t.shape[0]):
        if not np.isfinite(t_last):
            dt = 0.0
            t_still = t[i]
            f1 = a[i]
            f2 = a[i]
            a_prev = a[i]
        else:
            dt = t[i] - t_last
        t_last = t[i]
        alpha = 1.0 - np.exp(-2.0 * np.pi * fc * dt)
        f1 += alpha * (a[i] - f1)
        f2 += alpha * (f1 - f2)
        ai = f2
        m1 = sigma[i] > smin
        if mode == 0.0:
            dv = 0.0
            v = 0.0
            if m1 and (t[i] - t_still) >= tm and ai > 0.0:
                mode = 1.0
                nsteps = 0.0
                dv = dt * ai
                v = dt * ai
        else:
            v_old = v
            dv += dt * ai
            v += dt * ai
            m6 = v_old >= 0.0 and v < 0.0
            if (not m1) or (m6 and m6_still):
                mode = 0.0
                dv = 0.0
                v = 0.0
                t_still = t[i]
            elif m6:
                # M6: the variation of this step is erroneous; back to its start value
                v = v - dv
                dv = 0.0
            elif mode == 1.0 and a_prev > 0.0 and ai <= 0.0:
                mode = 2.0
            elif mode == 2.0 and a_prev < 0.0 and ai >= 0.0:
                # eq. 13-14: reset of delta_v, increment kept only in the first steps
                nsteps += 1.0
                if nsteps > settle:
                    v = v - dv
                dv = 0.0
                mode = 1.0
        a_prev = ai
        v_out[i] = v
        mode_out[i] = int(mode)
    st[0], st[1], st[2], st[3], st[4], st[5], st[6] = mode, dv, v, t_still, a_prev, nsteps, t_last
    st[7], st[8] = f1, f2


@dataclass
class AutomatonState:
    """``values = [mode, delta_v, v, t_enter_still, a_prev, steps, t_last, f1, f2]``, std window."""

    values: FloatArray = field(default_factory=lambda: np.array(
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, np.nan, 0.0, 0.0]))
    window: RunningStdState | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-able (NaN written as None)."""
        return {"values": [None if not np.isfinite(v) else float(v) for v in self.values],
                "window": None if self.window is None else self.window.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AutomatonState:
        """Inverse of :meth:`to_dict`."""
        vals = np.array([np.nan if v is None else v for v in data["values"]], dtype=np.float64)
        win = data.get("window")
        return cls(vals, None if win is None else RunningStdState.from_dict(win))


@dataclass(frozen=True, slots=True, eq=False)
class VelocityResult:
    """Per-sample velocity.

    Attributes
    ----------
    t: times, s.
    velocity_m_s: tangential walking velocity ``v_xu``, m/s.
    mode: automaton state (0 still, 1 accelerating, 2 decelerating).
    """

    t: FloatArray
    velocity_m_s: FloatArray
    mode: IntArray


class VelocityAutomaton:
    """Colombo Sec. III-C walking velocity estimator."""

    def __init__(self, params: AutomatonParams | None = None) -> None:
        self.params = params or AutomatonParams()
        p = self.params
        check_positive(p.sigma_min_m_s2, "sigma_min_m_s2")
        check_positive(p.tm_s, "tm_s")
        check_positive(p.prefilter_hz, "prefilter_hz")
        if p.m6_reset not in ("step", "still"):
            raise InputError(f"m6_reset {p.m6_reset!r}", where="AutomatonParams.m6_reset",
                             expected="'step' or 'still'")
        self._pars = np.array([p.sigma_min_m_s2, p.tm_s, float(p.settle_steps), p.prefilter_hz,
                               float(p.m6_reset == "still")])
        self._std = RunningStd(window_s=p.tm_s)
        self.reset()

    def reset(self) -> None:
        """Back to the still state with zero velocity."""
        self._std.reset()
        self.state = AutomatonState(window=self._std.state)

    def update(self, t: FloatArray, a_forward_m_s2: FloatArray) -> VelocityResult:
        """Process a chunk of levelled forward acceleration ``a_xu`` (m/s^2)."""
        if self.state.window is not None:
            self._std.state = self.state.window
        last = self.state.values[6]
        tt = as_time(t, where="automaton time", after=last if np.isfinite(last) else -np.inf)
        a = as_vector(a_forward_m_s2, where="forward acceleration", length=tt.shape[0])
        _, sigma = self._std.update(tt, a)
        v = np.empty(tt.shape[0])
        mode = np.empty(tt.shape[0], dtype=np.int64)
        automaton_kernel(tt, a, sigma, self._pars, self.state.values, v, mode)
        self.state.window = self._std.state
        return VelocityResult(tt, v, mode)

    def process(self, t: FloatArray, a_forward_m_s2: FloatArray) -> VelocityResult:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(t, a_forward_m_s2)
