"""Noise of the range-SLAM smoother's pose-chain increments (:mod:`hrtls.mission.graph`).

Two models of the white noise ``N(0, Q_k)`` of the increment ``x_{k+1} - x_k`` between two
poses (on top of the segments' scale and rotation):

* ``"length"``: ``Q_k = (odo_sigma_m^2 + (odo_fraction |d_k|)^2) I``, ``d_k`` the dead
  reckoning's increment;
* ``"tracker"``: the tracker's own covariance growth between the poses without the
  corrections' shrinkage. With ``P(t)`` the tracker's horizontal covariance at its rows and
  ``(P0_c, P1_c)`` the covariance before and after each correction, the growth curve
  ``C(t) = P(t) + sum_{t_c <= t} (P0_c - P1_c)`` is what the covariance would be with no
  correction since the start; ``Q_k`` is the positive semi-definite part of
  ``C(t_{k+1}) - C(t_k)`` plus ``odo_sigma_m^2 I`` (a floor).

Both are returned as whitening matrices ``W_k`` (``W_k^T W_k = Q_k^-1``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def growth_curve(cov_m2: FloatArray, t_s: FloatArray, t_corr_s: FloatArray,
                 cov0_m2: FloatArray, cov1_m2: FloatArray) -> FloatArray:
    """``C`` (N, 2, 2) at the rows' times ``t_s`` from their covariances ``cov_m2`` (module doc).

    A correction at a row's time counts for that row (the row holds the corrected state).
    """
    c = np.asarray(cov_m2, np.float64).reshape(-1, 2, 2)
    if not len(t_corr_s):
        return c.copy()
    order = np.argsort(t_corr_s, kind="stable")
    shrink = (np.asarray(cov0_m2) - np.asarray(cov1_m2))[order].reshape(-1, 4)
    cum = np.vstack([np.zeros((1, 4)), np.cumsum(shrink, axis=0)])
    k = np.searchsorted(np.asarray(t_corr_s)[order], t_s, side="right")
    return c + cum[k].reshape(-1, 2, 2)


def psd_part(a: FloatArray) -> FloatArray:
    """The positive semi-definite part of each symmetric 2x2 block (negative eigenvalues: 0)."""
    s = 0.5 * (a + np.swapaxes(a, 1, 2))
    w, v = np.linalg.eigh(s)
    return np.asarray(np.einsum("nij,nj,nkj->nik", v, np.maximum(w, 0.0), v), np.float64)


def whitening(d_m: FloatArray, *, odo_sigma_m: float, odo_fraction: float,
              growth_m2: FloatArray | None = None) -> FloatArray:
    """``W_k`` (K, 2, 2), 1/m, of the increments ``d_m`` (K, 2) (module doc).

    ``growth_m2`` (K + 1, 2, 2): ``C`` at the poses (the ``"tracker"`` model); None: the
    ``"length"`` model.
    """
    n = len(d_m)
    if growth_m2 is None:
        q = np.sqrt(odo_sigma_m ** 2 + (odo_fraction * np.hypot(d_m[:, 0], d_m[:, 1])) ** 2)
        return np.asarray(np.eye(2)[None, :, :] / q[:, None, None], np.float64)
    cov = psd_part(np.diff(growth_m2, axis=0)) + odo_sigma_m ** 2 * np.eye(2)[None, :, :]
    w, v = np.linalg.eigh(cov.reshape(n, 2, 2))
    return np.asarray(np.swapaxes(v, 1, 2) / np.sqrt(w)[:, :, None], np.float64)
