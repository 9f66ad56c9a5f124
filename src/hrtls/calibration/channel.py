"""Path-loss law fitted on readings taken at known positions (a site survey).

Tarrio eq. 1: ``rss = A - 10 eta log10(d / 1 m) + N(0, sigma)``. Given readings and the
distances from the receiver to their anchors, ``(A, eta)`` follow by linear least squares; an
``eta`` outside ``eta_bounds`` is clamped and ``A`` refitted for it; ``sigma`` is the residual
standard deviation (with two fitted parameters), floored at ``min_sigma_db``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.landmarks import Landmark
from hrtls.data.session import ChannelModel
from hrtls.errors import InputError

MIN_DISTANCE_M = 1.0
"""Distances below this are set to it (the log-distance law does not hold in the near field)."""


def fit_path_loss(*, distance_m: ArrayLike, rss_dbm: ArrayLike,
                  eta_bounds: tuple[float, float] = (1.0, 6.0),
                  min_sigma_db: float = 0.5) -> ChannelModel:
    """``(A, eta, sigma)`` of the log-distance law from readings at known distances."""
    d = np.maximum(np.asarray(distance_m, dtype=np.float64).ravel(), MIN_DISTANCE_M)
    z = np.asarray(rss_dbm, dtype=np.float64).ravel()
    if d.shape != z.shape or d.size < 3:
        raise InputError(f"{d.size} distances and {z.size} readings", where="path-loss fit",
                         expected="at least 3 readings, one distance each")
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(z))):
        raise InputError("non-finite value", where="path-loss fit", expected="finite numbers")
    lo, hi = eta_bounds
    if not 0 < lo <= hi:
        raise InputError(f"eta_bounds={eta_bounds}", where="path-loss fit",
                         expected="0 < low <= high")
    g = -10.0 * np.log10(d)
    (a_dbm, eta), *_ = np.linalg.lstsq(np.column_stack([np.ones_like(g), g]), z, rcond=None)
    if not lo <= eta <= hi:
        eta = float(np.clip(eta, lo, hi))
        a_dbm = float(np.mean(z - eta * g))
    resid = z - (a_dbm + eta * g)
    sigma = float(np.sqrt(np.sum(resid**2) / max(z.size - 2, 1)))
    return ChannelModel(a_dbm=float(a_dbm), eta=float(eta), sigma_db=max(sigma, min_sigma_db))


def survey_path_loss(*, receiver_xy: ArrayLike, anchors: Sequence[str], rss_dbm: ArrayLike,
                     landmarks: Mapping[str, Landmark],
                     eta_bounds: tuple[float, float] = (1.0, 6.0)) -> ChannelModel:
    """:func:`fit_path_loss` on readings taken at known receiver positions.

    ``receiver_xy`` (N, 2) are the receiver positions at the readings, ``anchors`` the anchor
    of each reading (landmark ids); the distance is horizontal.
    """
    anchor_xy = np.array([landmarks[a].xyz()[:2] for a in anchors])
    return fit_path_loss(distance_m=np.linalg.norm(np.asarray(receiver_xy) - anchor_xy, axis=1),
                         rss_dbm=rss_dbm, eta_bounds=eta_bounds)
