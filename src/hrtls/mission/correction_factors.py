"""A tracker's corrections as dead reckoning plus factors on its positions.

The tracker records every update that moved its position (:mod:`hrtls.pipeline.corrections`):
at time ``t`` the horizontal mean and covariance before, ``(m0, P0)``, and after, ``(m1, P1)``.
The range-SLAM smoother (:mod:`hrtls.mission.graph`) uses them twice.

Dead reckoning. The row at a correction's time holds the corrected state, so the tracker's
motion between two rows is the rows' difference minus the jumps ``m1 - m0`` of the corrections
between them (after the first row, up to and including the second):
``g(t) = f(t) - sum_{t_c <= t} (m1 - m0)_c`` (:func:`dead_reckoning`); the pose chain takes
increments of ``g``, not of ``f``.

Factors. A linear-Gaussian update of the position marginal ``N(m0, P0) -> N(m1, P1)`` is the
prior times a likelihood ``l(x) ~ N(z; x, R)`` in ``x``: ``P1^-1 = P0^-1 + Lambda`` and
``P1^-1 m1 = P0^-1 m0 + Lambda z`` with ``Lambda = R^-1``, so

    Lambda = P1^-1 - P0^-1,    Lambda (z - m0) = P1^-1 (m1 - m0)

(the second form is the difference of the two information vectors, written about ``m0`` to
avoid cancelling large numbers). ``Lambda = V diag(w) V^T``; negative eigenvalues (an update
that widened the covariance, e.g. a re-initialization) are set to zero, and ``z - m0`` is the
pseudo-inverse solution. The factor is the residual ``W (x(t) - z)`` with ``W = diag(sqrt(w))
V^T`` (``W^T W = Lambda``), ``x(t)`` the agent's pose interpolated at ``t``.

Exact for a measurement of the position alone (``H = [I 0]`` in the tracker's state: a
position fix, a tag group's position update) with the update linear: by the Woodbury identity
the marginal update is ``P1^-1 = P0^-1 + R^-1`` and ``z`` the fix. A range (``H = [u^T 0]``,
``u`` the unit line of sight at ``m0``) gives the rank-1 ``Lambda = u u^T / s^2``: the range's
information along the line of sight, linearized at the tracker's prior mean. A measurement of
other states (a tag bearing, the magnetic heading) moves the position through the prior's
cross-covariance: the factor is then the measurement's likelihood of ``x`` averaged over the
tracker's conditional of the other states given ``x`` (``p(z | x) = int p(z | x, h) p(h | x)
dh``), which holds information the tracker took from earlier corrections: an approximation
that counts some of it twice. A gated (rejected) update does not move the state and leaves no
factor.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

MIN_EIGEN_M2 = 1e-9
"""Eigenvalues of ``Lambda`` below this (1/m^2) are taken as no information."""


def implied_factors(mean0_m: FloatArray, cov0_m2: FloatArray, mean1_m: FloatArray,
                    cov1_m2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The measurement ``z`` (N, 2), m, and whitening ``W`` (N, 2, 2), 1/m, of each update.

    ``W^T W = Lambda`` (module doc); rows of ``W`` without information are zero.
    """
    i0 = np.linalg.inv(cov0_m2)
    i1 = np.linalg.inv(cov1_m2)
    lam = i1 - i0
    lam = 0.5 * (lam + np.swapaxes(lam, 1, 2))
    w, v = np.linalg.eigh(lam)
    ok = w > MIN_EIGEN_M2
    w = np.where(ok, w, 0.0)
    eta = np.einsum("nij,nj->ni", i1, mean1_m - mean0_m)
    # z - m0 = V diag(1/w) V^T eta (pseudo-inverse), W = diag(sqrt w) V^T
    proj = np.einsum("nji,nj->ni", v, eta)
    coef = np.where(ok, proj / np.where(ok, w, 1.0), 0.0)
    z = mean0_m + np.einsum("nij,nj->ni", v, coef)
    wm = np.sqrt(w)[:, :, None] * np.swapaxes(v, 1, 2)
    return z, wm


def dead_reckoning(t_s: FloatArray, xy_m: FloatArray, t_corr_s: FloatArray,
                   jump_m: FloatArray) -> FloatArray:
    """Rows ``xy_m`` at ``t_s`` without the jumps (N, 2) of the corrections at ``t_corr_s``.

    A correction at a row's time counts for that row (the row holds the corrected state).
    """
    if not len(t_corr_s):
        return np.asarray(xy_m, np.float64).copy()
    order = np.argsort(t_corr_s, kind="stable")
    cum = np.vstack([np.zeros((1, 2)), np.cumsum(np.asarray(jump_m)[order], axis=0)])
    k = np.searchsorted(np.asarray(t_corr_s)[order], t_s, side="right")
    return np.asarray(xy_m, np.float64) - cum[k]
