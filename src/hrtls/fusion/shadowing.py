"""Correlated shadowing of consecutive RSS readings of one beacon: the AR(1) discount.

A phone repeats or filters a beacon's RSS and the shadowing of a place persists while the
walker crosses it, so the errors of consecutive readings of one beacon are not independent.
Model: the shadowing error of a beacon is a first-order Gauss-Markov (AR(1)) process of
variance ``sigma^2`` and correlation time ``tau`` (``shadowing_time_s``),

    e_k = rho_k e_{k-1} + sqrt(1 - rho_k^2) w_k,   rho_k = exp(-dt_k / tau),

with ``dt_k`` the time since the previous reading of the same beacon. For readings of a fixed
position the generalized least-squares information of ``n`` readings is
``1^T Sigma^-1 1 = (1 + sum_{k>1} (1 - rho_k) / (1 + rho_k)) / sigma^2`` (the AR(1)
precision matrix is tridiagonal), so reading ``k`` adds the information of

    w_k = (1 - rho_k) / (1 + rho_k)                                           (1)

independent readings (the effective-sample-size factor of an AR(1) mean): the first reading
of a beacon, or one after a gap much longer than ``tau``, counts fully (``w = 1``); a repeat
within ``dt << tau`` counts ``~ dt / (2 tau)``. The tracker applies reading ``k`` with the
variance ``sigma^2 / w_k`` (:func:`hrtls.fusion.rss.rss_db_correction`); ``tau = 0`` is the
independent case (``w = 1`` always). ``w`` depends on the reading times only (not on the
estimate), so it is computed when readings are queued; :class:`ShadowingMemory` keeps the
last reading time of every beacon between chunks (and in snapshots).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.kernels import njit

MIN_INFO_FRACTION = 1e-6
"""Smallest information fraction applied (a repeat at the same time: no update to speak of)."""


@dataclass(frozen=True, kw_only=True)
class ShadowingParams:
    """AR(1) shadowing of one beacon's readings.

    Attributes
    ----------
    shadowing_time_s: correlation time ``tau`` of the shadowing error, s (0: independent
        readings).
    """

    shadowing_time_s: float = 0.0

    def __post_init__(self) -> None:
        finite_scalar(self.shadowing_time_s, where="shadowing_time_s", non_negative=True)


@njit(cache=True, error_model="numpy")
def information_fraction(dt_s: float, tau_s: float) -> float:  # pragma: no cover - compiled
    """Eq. 1: information of a reading ``dt_s`` after the previous one of its beacon.

    In ``[0, 1]``; 1 with ``tau_s = 0`` or ``dt_s = inf`` (no previous reading), 0 with
    ``dt_s = 0`` and ``tau_s > 0`` (a repeat carries nothing new).
    """
    if not tau_s > 0.0 or not dt_s < math.inf:
        return 1.0
    rho = math.exp(-max(dt_s, 0.0) / tau_s)
    return (1.0 - rho) / (1.0 + rho)


@dataclass(slots=True, eq=False)
class ShadowingMemory:
    """Last reading time (s) of every beacon seen so far (the discount's causal state)."""

    last_t: dict[str, float] = field(default_factory=dict)

    def fractions(self, t: ArrayLike, anchor: ArrayLike, *, tau_s: float) -> FloatArray:
        """Eq. 1 for readings ``t`` (s) of beacons ``anchor``; remembers the last of each.

        Readings of a beacon are taken in time order; its previous reading may be in an
        earlier call (a reading before it counts as a repeat, ``w = 0``).
        """
        tt = np.asarray(t, dtype=np.float64)
        ids = np.asarray(anchor).astype(str)
        if tt.shape != ids.shape or tt.ndim != 1:
            raise InputError(f"{tt.shape} times, {ids.shape} anchors",
                             where="ShadowingMemory.fractions",
                             expected="one anchor per reading time")
        if tt.size == 0:
            return np.zeros(0)
        names, inv = np.unique(ids, return_inverse=True)
        order = np.lexsort((tt, inv))          # by beacon, then time (stable)
        ts, gs = tt[order], inv[order]
        prev = np.empty_like(ts)
        prev[1:] = ts[:-1]
        first = np.ones(ts.size, dtype=bool)
        first[1:] = gs[1:] != gs[:-1]
        before = np.array([self.last_t.get(str(n), -math.inf) for n in names.tolist()])
        prev[first] = before[gs[first]]
        dt = ts - prev
        w = np.empty_like(ts)
        w[order] = fractions_of(dt, tau_s)
        last = np.flatnonzero(np.append(first[1:], True))
        for j, tl in zip(gs[last].tolist(), ts[last].tolist(), strict=True):
            self.last_t[str(names[j])] = float(tl)
        return w


@njit(cache=True, error_model="numpy")
def fractions_of(dt_s: FloatArray, tau_s: float) -> FloatArray:  # pragma: no cover - compiled
    """Eq. 1 for every gap of ``dt_s`` (s)."""
    out = np.empty(dt_s.shape[0])
    for i in range(dt_s.shape[0]):
        out[i] = information_fraction(dt_s[i], tau_s)
    return out
