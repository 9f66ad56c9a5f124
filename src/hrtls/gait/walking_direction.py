"""Walking direction relative to the device from the walking motion, causally (mounting unknown).

The levelled horizontal acceleration ``a_h(t)`` is expressed in the frame of a reference
direction ``psi_r(t)`` that turns with the device (the yaw of a level device axis; without an
attitude, the levelled device axes, ``psi_r = 0``),

    h(t) = R(-psi_r(t)) a_h(t),

(``a_h`` in the levelled navigation frame, x east and y north; yaws counter-clockwise from x,
docs/conventions.md; ``h`` has its x along the reference direction and its y to its left)

so that the walking direction is a constant offset ``delta`` in it however the walker turns:
``psi_walk = psi_r + delta``.

Which way is forward comes from the inverted-pendulum exchange of forward speed and height: the
trunk slows down while it rises over the stance foot and speeds up while it falls, so with the
vertical acceleration ``a_v ~ cos(w t)`` (peak at heel strike, ``w`` the step rate) the forward
acceleration is ``a_f ~ -sin(w t)``, in phase with the vertical jerk. On each step k, samples
``i`` in ``(t_start_k, t_end_k]``, the cross-moment of ``h`` with a band-limited jerk (the
difference of ``v``, the upward linear acceleration, over half a step, taken a quarter step
later; ``m`` = a quarter of the step's samples)

    c_k = sum_i h_{i-m} (v_i - v_{i-2m})

points forward: for the waveforms above each term is ``2 cos^2(w t_i)`` along the walking
direction. The lateral sway (half the step rate) alternates in sign from step to step, and a
tilt error that leaks ``eps a_v`` into ``h`` adds about ``eps sum a_v dv = 0`` over a periodic
step. The steps are blended recursively from a prior along the reference direction with a
forgetting factor ``lambda`` per step,

    c <- lambda c + c_k,   c_0 = c0 e_x,   delta = atan2(c_y, c_x).

The principal axis of the horizontal acceleration (forward larger than lateral) was measured
too and left out: in the daily-life mobgap trials the lateral variance was as large as or
larger than the forward one (docs/real-data.md).

Steps longer than ``max_step_s`` are not folded in. The offset applied to the step headings is
``delta*``, the estimate when ``settle_steps`` steps have been folded, kept from then on: the
first steps of a walk (gait initiation) often point ``c_k`` backwards, and a later change of
the applied offset would enter the tracker as a turn (it adds heading *changes*). The gait
analyzer holds the steps that end at most ``wait_s`` before ``delta*`` is fixed and gives them
``delta*`` too (:class:`~hrtls.gait.step_release.HeadingOffset`); earlier steps, and all of
them when it is never fixed, get no heading (NaN). The running estimate ``atan2(c_y, c_x)``
stays in the state.

The state (``c``, the steps folded, ``delta*`` and the last seconds of samples) restores exactly,
and a recording processed in chunks gets the same offsets as in one call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_matrix, as_time, as_vector
from hrtls.gait.step_release import HeadingOffset
from hrtls.kernels import njit

__all__ = ["WalkingDirection", "WalkingDirectionParams", "WalkingDirectionState",
           "in_reference_frame"]

BUFFER_S = 5.0
"""samples are kept this long beyond ``max_step_s`` for steps reported late"""


@dataclass(frozen=True, kw_only=True, slots=True)
class WalkingDirectionParams:
    """Parameters of the walking-direction estimate.

    Attributes
    ----------
    forgetting_per_step: ``lambda``, weight kept by the past at each step (0 < lambda <= 1).
    prior_m2_s4: ``c0``, prior cross-moment along the reference direction, m^2/s^4.
    max_step_s: longest step used, s.
    settle_steps: steps folded in before the applied offset ``delta*`` is fixed (the first
        steps of a walk, gait initiation, often point the cross-moment backwards).
    wait_s: the gait analyzer holds a step up to this long after its end for ``delta*``, s.
    """

    forgetting_per_step: float = 0.99
    prior_m2_s4: float = 1.0
    max_step_s: float = 0.8
    settle_steps: int = 4
    wait_s: float = 4.0

    def __post_init__(self) -> None:
        if not 0.0 < self.forgetting_per_step <= 1.0:
            raise InputError(f"forgetting_per_step = {self.forgetting_per_step}",
                             where="WalkingDirectionParams", expected="0 < value <= 1")
        if self.settle_steps < 1:
            raise InputError(f"settle_steps = {self.settle_steps}",
                             where="WalkingDirectionParams", expected="an integer >= 1")
        for name in ("prior_m2_s4", "max_step_s", "wait_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0) or (name == "max_step_s" and v == 0.0):
                raise InputError(f"{name} = {v}", where="WalkingDirectionParams",
                                 expected="a finite value >= 0 (max_step_s > 0)")


@njit(cache=True)
def walking_direction_kernel(t: FloatArray, h: FloatArray, v: FloatArray, starts: FloatArray,
                             ends: FloatArray, pars: FloatArray, c: FloatArray,
                             delta: FloatArray) -> None:  # pragma: no cover
    """Fold the steps ``(starts[k], ends[k]]`` into ``c`` and write ``delta[k]`` after each.

    ``pars = [lambda, max_step_s, settle_steps]``;
    ``c = [c_x, c_y, steps folded, delta*, end of the step that set delta*]`` (in/out). The
    lag ``m`` is a quarter of the step's samples. ``delta[k]`` is NaN until ``settle_steps``
    are folded, then ``delta*``, the estimate at that step.
    """
    lam = pars[0]
    max_step = pars[1]
    settle = pars[2]
    for k in range(ends.shape[0]):
        if 0.0 < ends[k] - starts[k] <= max_step:
            i0 = np.searchsorted(t, starts[k], side="right")
            i1 = np.searchsorted(t, ends[k], side="right")
            m = max(1, (i1 - i0 + 2) // 4)
            if i0 >= 2 * m and i1 - i0 >= 4:
                cx = 0.0
                cy = 0.0
                for i in range(i0, i1):
                    dv = v[i] - v[i - 2 * m]
                    cx += h[i - m, 0] * dv
                    cy += h[i - m, 1] * dv
                c[0] = lam * c[0] + cx
                c[1] = lam * c[1] + cy
                c[2] += 1.0
                if c[2] == settle:
                    c[3] = math.atan2(c[1], c[0])
                    c[4] = ends[k]
        delta[k] = c[3]


def in_reference_frame(a_horizontal_m_s2: FloatArray, psi_ref_rad: FloatArray) -> FloatArray:
    """``h = R(-psi_r) a_h``: horizontal acceleration (N, 2) in the reference direction's frame."""
    c = np.cos(psi_ref_rad)
    s = np.sin(psi_ref_rad)
    a = a_horizontal_m_s2
    return np.column_stack([c * a[:, 0] + s * a[:, 1], -s * a[:, 0] + c * a[:, 1]])


@dataclass
class WalkingDirectionState:
    """Cross-moment, steps folded, applied offset and when ``c = [c_x, c_y, n, delta*, t*]``.

    And the recent samples.
    """

    c: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, np.nan, np.nan]))
    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    h: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    v: FloatArray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict[str, Any]:
        """Plain values (non-finite floats kept; the analyzer encodes them for JSON)."""
        return {"c": self.c.tolist(), "t": self.t.tolist(), "h": self.h.tolist(),
                "v": self.v.tolist()}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> WalkingDirectionState:
        """Inverse of :meth:`to_dict` (raises KeyError, TypeError or ValueError if malformed)."""
        return cls(np.asarray(d["c"], dtype=np.float64).reshape(5),
                   np.asarray(d["t"], dtype=np.float64).reshape(-1),
                   np.asarray(d["h"], dtype=np.float64).reshape(-1, 2),
                   np.asarray(d["v"], dtype=np.float64).reshape(-1))


class WalkingDirection:
    """Recursive walking-direction offset ``delta`` from the reference direction (see module)."""

    def __init__(self, params: WalkingDirectionParams | None = None) -> None:
        self.params = params or WalkingDirectionParams()
        p = self.params
        self._pars = np.array([p.forgetting_per_step, p.max_step_s, float(p.settle_steps)])
        self.state = WalkingDirectionState()
        self.reset()

    def reset(self) -> None:
        """Back to the prior (``delta = 0``)."""
        self.state = WalkingDirectionState(
            c=np.array([self.params.prior_m2_s4, 0.0, 0.0, np.nan, np.nan]))

    def heading_offset(self) -> HeadingOffset:
        """``delta*`` for the held steps: those ending at most ``wait_s`` before it was set."""
        c = self.state.c
        return HeadingOffset(float(c[3]), float(c[4]), self.params.wait_s)

    def to_dict(self) -> dict[str, Any]:
        """The state as plain values."""
        return self.state.to_dict()

    def from_dict(self, d: dict[str, Any] | None) -> None:
        """Continue from :meth:`to_dict` output (None: from the prior, e.g. an older state)."""
        if d is None:
            self.reset()
        else:
            self.state = WalkingDirectionState.from_dict(d)

    def update(self, t: FloatArray, a_horizontal_m_s2: FloatArray, psi_ref_rad: FloatArray,
               vertical_m_s2: FloatArray, step_starts: FloatArray,
               step_ends: FloatArray) -> FloatArray:
        """The applied offset ``delta*`` (rad) after each of the steps given (NaN: not yet).

        Parameters
        ----------
        t: sample times of the chunk, s (after the previous chunk).
        a_horizontal_m_s2: levelled horizontal acceleration (N, 2), m/s^2.
        psi_ref_rad: yaw of the reference direction at the samples (N,), rad.
        vertical_m_s2: upward linear acceleration (N,), m/s^2.
        step_starts, step_ends: the steps reported with this chunk, s (within the samples
            seen so far, starting at most ``max_step_s + BUFFER_S`` before the last one).
        """
        s = self.state
        tt = as_time(t, where="walking-direction time",
                     after=float(s.t[-1]) if s.t.size else -math.inf)
        a_h = as_matrix(a_horizontal_m_s2, where="horizontal acceleration", columns=2,
                        length=tt.shape[0])
        h = in_reference_frame(a_h, as_vector(psi_ref_rad, where="reference yaw",
                                              length=tt.shape[0]))
        v = as_vector(vertical_m_s2, where="vertical acceleration", length=tt.shape[0])
        starts = as_vector(step_starts, where="step starts")
        ends = as_vector(step_ends, where="step ends", length=starts.shape[0])
        tb = np.concatenate([s.t, tt])
        hb = np.concatenate([s.h, h])
        vb = np.concatenate([s.v, v])
        delta = np.empty(ends.shape[0])
        walking_direction_kernel(tb, hb, vb, starts, ends, self._pars, s.c, delta)
        if tb.size:
            keep = tb >= tb[-1] - self.params.max_step_s - BUFFER_S
            s.t, s.h, s.v = tb[keep], hb[keep], vb[keep]
        return delta
