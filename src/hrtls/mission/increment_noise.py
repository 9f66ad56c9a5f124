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

An agent may bring its own chain model (:class:`ChainNoise`, e.g. a robot's from its odometry
EKF's parameters, :func:`robot_chain`) in place of the smoother's, which models a walker.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

ROBOT_FLOOR_SIGMA_M = 0.02
"""Floor of a robot's increment noise in the smoother, m."""

ROBOT_SCALE_SIGMA = 0.01
"""Prior 1-sigma of a robot's odometry scale correction in the smoother."""

ROBOT_VARIANCE_SCALE = 2.0
"""A robot's chain variances in the smoother, times its EKF's (chosen on dev seeds 0-9)."""


@dataclass(frozen=True, kw_only=True)
class ChainNoise:
    """One agent's pose-chain noise (the ``"length"`` increments and the segment walks).

    Same meaning as :class:`hrtls.mission.graph_params.SmootherParams`' fields of these names.
    """

    odo_sigma_m: float
    odo_fraction: float
    scale_sigma: float
    scale_walk_sigma: float
    heading_sigma_rad: float
    heading_walk_rad: float


def robot_chain(*, odometry_fraction: float, heading_var_per_m: float,
                start_heading_sigma_rad: float, segment_m: float,
                floor_sigma_m: float = ROBOT_FLOOR_SIGMA_M,
                scale_sigma: float = ROBOT_SCALE_SIGMA,
                variance_scale: float = ROBOT_VARIANCE_SCALE) -> ChainNoise:
    """A wheeled robot's chain from its EKF's model (:mod:`hrtls.mission.robot`).

    The EKF's displacement noise ``odometry_fraction |d|`` per axis is the increments' part of
    their length; its odometry-frame rotation, a random walk of ``heading_var_per_m`` per metre
    from ``start_heading_sigma_rad``, is the segments' rotation walk
    (``sqrt(heading_var_per_m segment_m)`` per segment). The EKF has no scale error: the scale
    correction gets a small prior (``scale_sigma``) and no walk beyond a tenth of it, and the
    increments a small floor (``floor_sigma_m``: the rows' decimation and rounding). Every
    variance is then times ``variance_scale`` (as the mission scales the agents' covariances).
    """
    k = math.sqrt(variance_scale)
    return ChainNoise(odo_sigma_m=k * floor_sigma_m, odo_fraction=k * odometry_fraction,
                      scale_sigma=k * scale_sigma, scale_walk_sigma=k * 0.1 * scale_sigma,
                      heading_sigma_rad=k * max(start_heading_sigma_rad, 1e-3),
                      heading_walk_rad=k * math.sqrt(heading_var_per_m * segment_m))


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
