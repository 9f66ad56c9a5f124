"""Covariances of the range-SLAM smoother's solution (:mod:`hrtls.mission.graph`).

Blocks of the inverse information matrix ``(J^T W J)^-1`` (by sparse LU solves against unit
columns, never the dense inverse) and the inflation of a node's block by the mean square whitened
range residual: of all ranges, or of the node's own when larger (a node seen mostly through
walls).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, identity
from scipy.sparse.linalg import SuperLU, splu

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def spd_lu(m: csc_matrix) -> SuperLU:
    """LU of a symmetric positive definite matrix.

    Minimum degree ordering on ``A + A^T`` and no pivoting off the diagonal: far less fill-in
    than the default column ordering.
    """
    return splu(m, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                options={"SymmetricMode": True})


def node_inflation(e: FloatArray, inlier: NDArray[np.bool_], node: IntArray, n_nodes: int
                   ) -> FloatArray:
    """Covariance inflation per node (at least one).

    The mean square of the inlier whitened residuals ``e``: of all ranges, or of the node's own
    when larger.
    """
    sq = np.where(inlier, e * e, 0.0)
    total = float(np.sum(sq) / np.count_nonzero(inlier)) if inlier.any() else 1.0
    own_n = np.bincount(node[inlier], minlength=n_nodes).astype(np.float64)
    own = np.bincount(node, weights=sq, minlength=n_nodes) / np.maximum(own_n, 1.0)
    return np.maximum(np.maximum(own, total), 1.0)


def inverse_blocks(info: csc_matrix, cols: list[int], inflation: FloatArray) -> list[FloatArray]:
    """The 2x2 blocks of ``info^-1`` at columns ``cols``, each times its ``inflation``.

    NaN blocks when ``info`` is singular.
    """
    k = len(cols)
    if k == 0:
        return []
    try:
        lu = spd_lu(csc_matrix(info + 1e-9 * identity(info.shape[0], format="csc")))
        rhs = np.zeros((info.shape[0], 2 * k))
        at = np.repeat(np.asarray(cols, np.int64), 2) + np.tile([0, 1], k)
        rhs[at, np.arange(2 * k)] = 1.0
        sol = lu.solve(rhs)
    except (RuntimeError, ValueError):
        return [np.full((2, 2), np.nan)] * k
    out = []
    for i, c in enumerate(cols):
        b = inflation[i] * sol[c:c + 2, 2 * i:2 * i + 2]
        out.append(0.5 * (b + b.T))
    return out


def robust_weights(z: FloatArray, loss: str) -> FloatArray:
    """IRLS weights ``rho'(z)`` of the range rows at the solution."""
    if loss == "soft_l1":
        return np.asarray(1.0 / np.sqrt(1.0 + z), np.float64)
    if loss == "cauchy":
        return np.asarray(1.0 / (1.0 + z), np.float64)
    if loss == "huber":
        return np.asarray(np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300))),
                          np.float64)
    return np.ones_like(z)
