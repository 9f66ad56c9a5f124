"""Starting values of the range-SLAM smoother (:mod:`hrtls.mission.graph`) and its nodes.

A node is solved with at least ``min_ranges`` ranges whose reading positions (the agents' rows
at the ranges' times) spread ``min_spread_m`` off their best-fit line (the RMS distance: the
square root of the smaller eigenvalue of their covariance); it starts at the linear
trilateration ``||p - a_k||^2 = r_k^2`` about the positions' centroid. A pose after the last
solved one starts at the last solved pose carried on by the rows' increments, scaled and rotated
by the last segment's corrections.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from hrtls.mission.graph import AgentPath, RangeSet
    from hrtls.mission.graph_params import SmootherParams

FloatArray = NDArray[np.float64]


def spread(a: FloatArray) -> float:
    """RMS distance of the points ``a`` (N, 2) from their best-fit line."""
    c = a - a.mean(axis=0)
    w = np.linalg.eigvalsh(np.cov(c.T, bias=True).reshape(2, 2))
    return float(np.sqrt(max(w[0], 0.0)))


def linear_init(a: FloatArray, r: FloatArray) -> FloatArray | None:
    """Linear least squares of ``||p - a_k||^2 = r_k^2`` about the centroid."""
    c = a.mean(axis=0)
    d = a - c
    rhs = np.sum(d ** 2, axis=1) - r ** 2
    lhs = 2.0 * (d - d.mean(axis=0))
    sol, _, rank, _ = np.linalg.lstsq(lhs, rhs - rhs.mean(), rcond=None)
    return None if rank < 2 else np.asarray(c + sol, np.float64)


def raw_positions(paths: list[AgentPath], ranges: RangeSet) -> FloatArray:
    """The agents' rows at the ranges' times (N, 2)."""
    xy = np.zeros((len(ranges.t), 2))
    for a, p in enumerate(paths):
        m = ranges.agent == a
        xy[m, 0] = np.interp(ranges.t[m], p.t, p.xy_m[:, 0])
        xy[m, 1] = np.interp(ranges.t[m], p.t, p.xy_m[:, 1])
    return xy


def select_nodes(paths: list[AgentPath], ranges: RangeSet, prm: SmootherParams
                 ) -> dict[str, float]:
    """Nodes with enough ranges from positions spread off a line: id -> spread, m."""
    raw = raw_positions(paths, ranges)
    out = {}
    for n in sorted(set(ranges.node.tolist())):
        m = ranges.node == n
        s = spread(raw[m]) if np.count_nonzero(m) >= prm.min_ranges else 0.0
        if s >= prm.min_spread_m:
            out[str(n)] = s
    return out


def extend(poses: FloatArray, f: FloatArray, k: int, scale: float, heading_rad: float) -> None:
    """Poses from ``k`` on, in place: the last solved pose carried on by the rows' increments.

    The increments are scaled and rotated by the last segment's corrections.
    """
    if k < 1 or k >= len(poses):
        return
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    d = np.diff(f[k - 1:], axis=0) * (1.0 + scale)
    rd = np.column_stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]])
    poses[k:] = poses[k - 1] + np.cumsum(rd, axis=0)
