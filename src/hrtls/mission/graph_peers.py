"""Inter-agent ranges as factors of the range-SLAM smoother (:mod:`hrtls.mission.graph`).

Factor. A range ``r`` at time ``t`` between agents ``a`` and ``b`` (``a`` measured ``b``: UWB
between teammates and robots, :mod:`hrtls.mission.peers`) ties the two agents' paths:

    e = (r - ||x_a(t) - x_b(t)||) / s,     x_a(t) = (1 - w_a) x_a,k + w_a x_a,k+1

each agent's position interpolated between its two poses around ``t`` (:func:`pose_weights`,
as the agent's position at a range to a node). No height term: both antennas are carried by
agents. ``s``: the range's sigma as received times ``sqrt(n)``, ``n`` the ranges of the same
pair, measured either way (the same walls), within ``range_correlation_s`` of it
(:mod:`hrtls.mission.range_weights`); the rows are under the robust loss of the ranges to nodes
(walls lengthen ranges). With ``u = (x_a(t) - x_b(t)) / (||x_a(t) - x_b(t)|| s)``:

    de/dx_a,k = -(1 - w_a) u,   de/dx_a,k+1 = -w_a u,   de/dx_b,k = (1 - w_b) u,
    de/dx_b,k+1 = w_b u.

Window (:mod:`hrtls.mission.graph_window`). A range leaves the problem when either agent's cut
pose passes it (its time before that agent's first kept pose). The marginalized prior holds,
per agent, only its first kept pose: a leaving range is marginalized when its time is at or
before both agents' first kept poses and both agents are in the new prior (it then touches
only removed poses and the first kept ones); otherwise (a range between the two agents' cut
times, or with an agent not cut yet) its information is dropped (:func:`marginalizable`):
dropped information is conservative, information on a kept pose outside the prior's columns
would be lost from the coupling and wrongly placed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, csr_matrix, diags

from hrtls.mission.graph_covariance import robust_weights
from hrtls.mission.graph_links import Terms, distance_jacobian, distance_rows
from hrtls.mission.range_weights import correlated_sigma

if TYPE_CHECKING:
    from hrtls.mission.graph_params import SmootherParams
    from hrtls.mission.graph_window import Layout

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
At = Callable[[int, FloatArray], tuple[IntArray, IntArray, FloatArray]]


@dataclass(frozen=True, eq=False)
class PeerSet:
    """Ranges between agents: measuring, measured agent (path indices), t (s), m, sigma (m)."""

    a: IntArray
    b: IntArray
    t: FloatArray
    range_m: FloatArray
    sigma_m: FloatArray

    @classmethod
    def empty(cls) -> PeerSet:
        """No ranges."""
        z = np.zeros(0)
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), z, z, z)

    def __len__(self) -> int:
        return len(self.t)

    def select(self, mask: NDArray[np.bool_]) -> PeerSet:
        """The ranges where ``mask`` is True."""
        return PeerSet(self.a[mask], self.b[mask], self.t[mask], self.range_m[mask],
                       self.sigma_m[mask])


def pose_weights(t_s: FloatArray, col0: int, tq_s: FloatArray
                 ) -> tuple[IntArray, IntArray, FloatArray]:
    """Columns of the poses around each of ``tq_s`` and the weight of the later one.

    Poses at times ``t_s``, the first at column ``col0``; the weight is 0 before the first pose
    and 1 after the last.
    """
    k = np.clip(np.searchsorted(t_s, tq_s, side="right") - 1, 0, len(t_s) - 1)
    k1 = np.minimum(k + 1, len(t_s) - 1)
    dt = t_s[k1] - t_s[k]
    w = np.where(dt > 0, np.clip((tq_s - t_s[k]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0), 0.0)
    return col0 + 2 * k, col0 + 2 * k1, w


class PeerRows:
    """The inter-agent range rows of one solve (module doc)."""

    def __init__(self, peers: PeerSet, at: At, *, correlation_s: float) -> None:
        n = len(peers)
        self.r = peers.range_m
        lo, hi = np.minimum(peers.a, peers.b), np.maximum(peers.a, peers.b)
        self.s = correlated_sigma(lo, hi, peers.t, peers.sigma_m, window_s=correlation_s)
        self.cols = [np.zeros(n, np.int64) for _ in range(4)]
        self.w = [np.zeros(n), np.zeros(n)]
        for side, agent in enumerate((peers.a, peers.b)):
            for g in np.unique(agent).tolist():
                m = agent == g
                c0, c1, w = at(int(g), peers.t[m])
                self.cols[2 * side][m], self.cols[2 * side + 1][m], self.w[side][m] = c0, c1, w

    def __len__(self) -> int:
        return len(self.r)

    def _xy(self, x: FloatArray, side: int) -> FloatArray:
        w = self.w[side][:, None]
        c0, c1 = self.cols[2 * side], self.cols[2 * side + 1]
        return (1.0 - w) * np.column_stack([x[c0], x[c0 + 1]]) + \
            w * np.column_stack([x[c1], x[c1 + 1]])

    def parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Whitened residuals, ``x_a(t) - x_b(t)`` and the distance."""
        return distance_rows(self._xy(x, 0) - self._xy(x, 1), self.r, self.s)

    def jacobian(self, x: FloatArray, row0: int
                 ) -> tuple[list[IntArray], list[IntArray], list[FloatArray]]:
        """Rows, columns and values of the rows' Jacobian, from row ``row0`` (module doc)."""
        _, diff, d = self.parts(x)
        terms: Terms = []
        for side, sign in ((0, -1.0), (1, 1.0)):
            w = self.w[side]
            terms += [(self.cols[2 * side], sign * (1.0 - w)), (self.cols[2 * side + 1], sign * w)]
        return distance_jacobian(diff, d, self.s, row0, terms)


def layout_at(lay: Layout) -> At:
    """The pose interpolation of a solve's columns."""
    return lambda a, tq: pose_weights(lay.t[a], lay.pose_col[a], tq)


def marginalizable(peers: PeerSet, lay: Layout, cut: dict[str, int],
                   agents: tuple[str, ...]) -> NDArray[np.bool_]:
    """Of a solve's ranges, those the window's marginalization may take (module doc).

    The ranges that stay in the problem, and those that leave it at or before both agents'
    first kept poses with both agents in the new prior (``agents``).
    """
    first = np.array([float(lay.t[a][cut.get(n, 0)]) for a, n in enumerate(lay.names)])
    in_prior = np.array([n in agents for n in lay.names], dtype=bool)
    ta, tb = first[peers.a], first[peers.b]
    stays = (peers.t >= ta) & (peers.t >= tb)
    return stays | ((peers.t <= ta) & (peers.t <= tb) & in_prior[peers.a] & in_prior[peers.b])


def information(peers: PeerSet, mask: NDArray[np.bool_], lay: Layout, x: FloatArray,
                prm: SmootherParams) -> tuple[csc_matrix, FloatArray]:
    """Information ``J^T W J`` and half-gradient ``J^T W r`` of some ranges' rows at ``x``.

    The rows of the ranges where ``mask`` is True, on the solve's columns; ``W`` the robust
    loss's weights at ``x``; the sigmas from all ``peers``, as in the solve.
    """
    rows = PeerRows(peers, layout_at(lay), correlation_s=prm.range_correlation_s)
    res = rows.parts(x)[0]
    sw = np.sqrt(robust_weights(res ** 2 / prm.loss_scale ** 2, prm.loss)) * mask
    r_, c_, v_ = rows.jacobian(x, 0)
    jac = csr_matrix((np.concatenate(v_), (np.concatenate(r_), np.concatenate(c_))),
                     shape=(len(res), lay.n))
    jw = csr_matrix(diags(sw) @ jac)
    return csc_matrix(jw.T @ jw), np.asarray(jw.T @ (sw * res), np.float64)
