"""Step length from the vertical excursion of the pelvis (inverted pendulum model).

Not one of the project papers: the model of Zijlstra and Hof (Gait & Posture 18, 2003), which
treats the body over the stance leg as an inverted pendulum of length ``L`` (here the height of
the sensor above the ground, about the leg length). If the pelvis rises and falls by ``h`` during
a step, the horizontal travel of the pendulum is ``2 sqrt(2 L h - h^2)``; a user factor ``K``
calibrated on walks of known length (like Weinberg's ``K``, Tarrio eq. 3) absorbs the model
error:

    l = K * 2 * sqrt(2 L h - h^2).

Unlike the Weinberg rule ``K (a_max - a_min)^(1/4)``, whose fourth root hardly changes between a
normal and a shuffling step, ``h`` shrinks with the step, so short daily-life steps get short
lengths.

``h`` of one step (:func:`vertical_excursion`): the vertical linear acceleration between the
step's start and end is integrated twice (trapezoid rule). A step is one period of the gait, so
the vertical velocity and the height must come back to their start values: the linear trend
that makes the velocity periodic is removed (it also removes a constant bias of the levelled
acceleration), then its mean (the pelvis has no net vertical speed), then the linear trend of
the height. ``h`` is the range of the height over the step.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_vector, check_positive
from hrtls.gait.pll import StepDetection
from hrtls.kernels import njit


@njit(cache=True)
def excursion_kernel(t: FloatArray, a: FloatArray, t0: FloatArray, t1: FloatArray,
                     out: FloatArray) -> None:  # pragma: no cover
    """``out[k]``: vertical excursion (m) over the samples of ``t`` in ``[t0[k], t1[k]]``.

    Steps with fewer than 4 samples get 0.
    """
    longest = 0
    for k in range(t0.shape[0]):
        n = np.searchsorted(t, t1[k], side="right") - np.searchsorted(t, t0[k], side="left")
        if n > longest:
            longest = n
    vel = np.empty(max(longest, 1))
    pos = np.empty(max(longest, 1))
    for k in range(t0.shape[0]):
        i0 = np.searchsorted(t, t0[k], side="left")
        i1 = np.searchsorted(t, t1[k], side="right")
        n = i1 - i0
        if n < 4:
            out[k] = 0.0
            continue
        span = t[i1 - 1] - t[i0]
        vel[0] = 0.0
        for j in range(1, n):
            i = i0 + j
            vel[j] = vel[j - 1] + 0.5 * (a[i] + a[i - 1]) * (t[i] - t[i - 1])
        # periodic velocity (same at both ends), then zero mean
        end = vel[n - 1]
        mean = 0.0
        for j in range(n):
            vel[j] -= end * (t[i0 + j] - t[i0]) / span
            mean += vel[j]
        mean /= n
        pos[0] = 0.0
        for j in range(n):
            vel[j] -= mean
        for j in range(1, n):
            i = i0 + j
            pos[j] = pos[j - 1] + 0.5 * (vel[j] + vel[j - 1]) * (t[i] - t[i - 1])
        end = pos[n - 1]
        lo = np.inf
        hi = -np.inf
        for j in range(n):
            p = pos[j] - end * (t[i0 + j] - t[i0]) / span
            if p < lo:
                lo = p
            if p > hi:
                hi = p
        out[k] = hi - lo


def vertical_excursion(t: FloatArray, a_vertical_m_s2: FloatArray, t_start: FloatArray,
                       t_end: FloatArray) -> FloatArray:
    """Vertical excursion ``h`` (m) of each step ``[t_start[k], t_end[k]]`` (see module notes).

    Parameters
    ----------
    t: sample times, s (strictly increasing).
    a_vertical_m_s2: vertical linear acceleration at ``t``, m/s^2 (a constant offset does not
        matter).
    t_start, t_end: step boundaries, s.
    """
    tt = as_vector(t, where="excursion time")
    a = as_vector(a_vertical_m_s2, where="vertical acceleration", length=tt.shape[0])
    t0 = as_vector(t_start, where="step starts")
    t1 = as_vector(t_end, where="step ends", length=t0.shape[0])
    out = np.empty(t0.shape[0])
    excursion_kernel(tt, a, t0, t1, out)
    return out


@dataclass(frozen=True, kw_only=True, slots=True)
class PendulumModel:
    """Inverted-pendulum step length ``K 2 sqrt(2 L h - h^2)`` (see module notes).

    Attributes
    ----------
    k: user correction factor ``K`` (1 for the ideal pendulum).
    leg_length_m: pendulum length ``L``: the height of the sensor above the ground, m.
    max_length_m: upper clip of the result, m.
    """

    k: float = 1.0
    leg_length_m: float = 0.95
    max_length_m: float = 2.5

    def __post_init__(self) -> None:
        check_positive(self.k, "k")
        check_positive(self.leg_length_m, "leg_length_m")
        check_positive(self.max_length_m, "max_length_m")

    def unit_lengths(self, excursion_m: FloatArray) -> FloatArray:
        """``2 sqrt(2 L h - h^2)`` per step (the length for ``K = 1``), m."""
        h = np.clip(np.asarray(excursion_m, dtype=np.float64), 0.0, self.leg_length_m)
        return np.asarray(2.0 * np.sqrt(2.0 * self.leg_length_m * h - h * h), dtype=np.float64)

    def lengths(self, steps: StepDetection, excursion_m: FloatArray | None = None) -> FloatArray:
        """Step lengths, m; ``excursion_m`` (one ``h`` per step, m) is required."""
        if excursion_m is None:
            raise InputError("no vertical excursions", where="PendulumModel.lengths",
                             expected="excursion_m, one value per step (m)")
        h = as_vector(excursion_m, where="excursion_m", length=len(steps))
        return np.asarray(np.clip(self.k * self.unit_lengths(h), 0.0, self.max_length_m),
                          dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """User-profile form ``{"kind": "pendulum", ...}``."""
        return {"kind": "pendulum", **asdict(self)}


__all__ = ["PendulumModel", "excursion_kernel", "vertical_excursion"]
