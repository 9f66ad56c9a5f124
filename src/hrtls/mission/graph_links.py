"""Ranges between dropped nodes in the range-SLAM smoother (:mod:`hrtls.mission.graph`).

Links. Two static nodes measure one and the same distance every time, through the same walls:
their ranges' errors are not independent over the mission (an NLOS bias stays), so the ranges
of a pair are taken as one factor (the mission-long version of ``range_correlation_s``): the
median ``r`` of the pair's ranges, residual ``(r - ||p_a - p_b||) / s`` with
``s = sqrt(max(sqrt(sigma_m^2 + (sigma_fraction r)^2), 1.4826 MAD)^2 + bias_sigma_m^2)``: the
estimator's own noise model of the radio (:class:`~hrtls.mission.graph_params.SmootherParams`
``link_sigma_m``, ``link_sigma_fraction``), or the spread of the pair's ranges (median absolute
deviation) when larger: ranges through walls scatter with their bias, so a pair whose ranges
scatter more than the noise model is taken as biased by about that spread; and the part of the
excess path that stays the same for every range of the pair (``link_bias_sigma_m``), which no
spread shows. Under the robust loss of the agents'
ranges. Both nodes lie on the floor: no height term.

Geometry. A node enters the problem and may count as localized when the positions it is ranged
from spread off a line (:func:`hrtls.mission.graph_init.select_nodes`). With links, its
anchors are also its placed neighbours (localized by the previous solve or the mission, or held
by the marginalized prior, at those positions): its effective spread is the largest of its
agents' spread, the largest distance of a neighbour from the best-fit line of its reading
positions (a line of passes leaves a mirror ambiguity that a neighbour off the line resolves)
and, with three anchors or more, the spread of all of them (TLA: a node between localized
neighbours). A node that joins starts at the linear trilateration from all its anchors and is
an anchor from the next solve on, once localized (SELA's rounds, one per solve: rounds
within one solve, through neighbours not localized yet, did worse on the development seeds,
docs/mission.md).

Confirmation. A node joins only when that start agrees with each kind of anchor on its own:
the median of ``| ||p - a_k|| - r_k |`` over its links, and over its agents' ranges when it has
any, at most ``link_join_tol_m`` (:func:`confirmed`). The linear trilateration is not the
least-squares fit: from readings along a line (the mirror), an ill-conditioned set of anchors
or a misplaced neighbour it lands metres off, and the solve, started there, keeps the node in
a wrong minimum that drags its agents' poses and, through the feedback, the rescuers
(docs/mission.md, "Node ranges and the rescuers"). A start both kinds confirm is not such a
point; a node not confirmed now may join at a later solve.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hrtls.mission.graph_init import linear_init, raw_positions, spread

if TYPE_CHECKING:
    from hrtls.mission.graph import AgentPath, RangeSet
    from hrtls.mission.graph_params import SmootherParams

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MAD_SIGMA = 1.4826
"""A Gaussian's sigma per median absolute deviation."""


@dataclass(frozen=True, eq=False)
class NodeLinks:
    """One factor per pair of nodes: ids ``a < b``, median range (m), sigma (m), ranges."""

    a: NDArray[np.str_]
    b: NDArray[np.str_]
    range_m: FloatArray
    sigma_m: FloatArray
    count: IntArray

    @classmethod
    def empty(cls) -> NodeLinks:
        """No links."""
        z = np.zeros(0)
        return cls(np.zeros(0, np.str_), np.zeros(0, np.str_), z, z, np.zeros(0, np.int64))

    def __len__(self) -> int:
        return len(self.a)

    def select(self, mask: NDArray[np.bool_]) -> NodeLinks:
        """The links where ``mask`` is True."""
        return NodeLinks(self.a[mask], self.b[mask], self.range_m[mask], self.sigma_m[mask],
                         self.count[mask])


def pair_links(node_a: NDArray[np.str_], node_b: NDArray[np.str_], range_m: FloatArray, *,
               sigma_m: float, sigma_fraction: float, bias_sigma_m: float = 0.0) -> NodeLinks:
    """The ranges grouped by unordered pair: each pair's median range and sigma (module doc)."""
    if not len(range_m):
        return NodeLinks.empty()
    a, b = node_a.astype(str), node_b.astype(str)
    lo, hi = np.where(a < b, a, b), np.where(a < b, b, a)
    pairs, inv = np.unique(np.column_stack([lo, hi]), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    counts = np.bincount(inv, minlength=len(pairs))
    med = _group_median(range_m, inv, counts)
    mad = _group_median(np.abs(range_m - med[inv]), inv, counts)
    sig = np.hypot(np.maximum(np.hypot(sigma_m, sigma_fraction * med), MAD_SIGMA * mad),
                   bias_sigma_m)
    return NodeLinks(pairs[:, 0], pairs[:, 1], med, sig, counts.astype(np.int64))


def _group_median(v: FloatArray, group: IntArray, counts: IntArray) -> FloatArray:
    """Median of ``v`` per group (groups ``0..len(counts)-1``, each non-empty)."""
    srt = v[np.lexsort((v, group))]
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.asarray(0.5 * (srt[start + (counts - 1) // 2] + srt[start + counts // 2]),
                      np.float64)


def _effective(pts: FloatArray, nb: FloatArray, agent_spread: float, extent_m: float) -> float:
    """Effective spread of a node from its reading positions and neighbour anchors (doc).

    The reading positions make a line only when they extend ``extent_m`` along it (RMS).
    """
    s = agent_spread
    if len(pts) >= 2 and len(nb):
        c = pts.mean(axis=0)
        w, v = np.linalg.eigh(np.cov((pts - c).T, bias=True).reshape(2, 2))
        if np.sqrt(max(w[1], 0.0)) >= extent_m:
            s = max(s, float(np.max(np.abs((nb - c) @ v[:, 0]))))
    if len(pts) + len(nb) >= 3 and len(nb):
        s = max(s, spread(np.vstack([pts, nb]) if len(pts) else nb))
    return s


def _start(pts: FloatArray, r_pts: FloatArray, nb: FloatArray, r_nb: FloatArray
           ) -> FloatArray | None:
    """Linear trilateration from all anchors (None: rank deficient)."""
    a = np.vstack([pts, nb])
    r = np.concatenate([r_pts, r_nb])
    return None if len(a) < 3 else linear_init(a, r)


def confirmed(*, start_m: FloatArray, reading_xy_m: FloatArray, reading_range_m: FloatArray,
              neighbour_xy_m: FloatArray, link_range_m: FloatArray, tol_m: float) -> bool:
    """Whether a joining node's start agrees with each kind of anchor (module doc).

    Its links (neighbours' positions and the pairs' ranges) and its agents' ranges (reading
    positions, horizontal ranges; none: links only): each kind's median absolute range
    residual at ``start_m`` at most ``tol_m``.
    """
    for a, r in ((neighbour_xy_m, link_range_m), (reading_xy_m, reading_range_m)):
        if len(a) and float(np.median(np.abs(np.linalg.norm(a - start_m, axis=1) - r))) > tol_m:
            return False
    return True


def select_linked(paths: list[AgentPath], ranges: RangeSet, links: NodeLinks,
                  base: dict[str, float], anchors_m: dict[str, FloatArray],
                  prm: SmootherParams, height_m: float
                  ) -> tuple[dict[str, float], dict[str, FloatArray]]:
    """Nodes of the problem with links (module doc): id -> effective spread; starting points.

    ``base``: the nodes selected from the agents' ranges alone (id -> spread); ``anchors_m``:
    the placed nodes' positions (the mission's localized estimates, the marginalized prior's,
    the previous solve's localized ones): of ``base``, those are the anchors; ``height_m``: the
    antenna height difference the agents' ranges are reduced by. The starting points are those
    of the nodes that joined (confirmed by both anchor kinds: :func:`confirmed`).
    """
    out = dict(base)
    if not len(links):
        return out, {}
    raw = raw_positions(paths, ranges)
    horiz = np.sqrt(np.maximum(ranges.range_m ** 2 - height_m ** 2, 0.0))
    pos = {n: np.asarray(anchors_m[n], np.float64) for n in out
           if n in anchors_m and np.all(np.isfinite(anchors_m[n]))}
    joined: dict[str, FloatArray] = {}
    for n in sorted(set(links.a.tolist()) | set(links.b.tolist())):
        m = np.flatnonzero((links.a == n) | (links.b == n))
        other = np.where(links.a[m] == n, links.b[m], links.a[m])
        ok = np.array([o in pos for o in other.tolist()], dtype=bool)
        if not ok.any():
            continue
        nb = np.array([pos[o] for o in other[ok].tolist()]).reshape(-1, 2)
        k = np.flatnonzero(ranges.node == n)
        s = _effective(raw[k], nb, out.get(n, 0.0), prm.min_spread_m)
        if n in out:
            out[n] = max(out[n], s)
        elif s >= prm.min_spread_m:
            p = _start(raw[k], horiz[k], nb, links.range_m[m][ok])
            if p is not None and np.all(np.isfinite(p)) and confirmed(
                    start_m=p, reading_xy_m=raw[k], reading_range_m=horiz[k], neighbour_xy_m=nb,
                    link_range_m=links.range_m[m][ok], tol_m=prm.link_join_tol_m):
                out[n], joined[n] = s, p
    return out, joined


class LinkRows:
    """The link factors of one solve: node columns, ranges and sigmas (module doc)."""

    def __init__(self, links: NodeLinks, node_ids: list[str], node_col: int) -> None:
        index = {n: i for i, n in enumerate(node_ids)}
        keep = np.array([a in index and b in index for a, b in
                         zip(links.a.tolist(), links.b.tolist(), strict=True)], dtype=bool)
        kept = links.select(keep) if len(links) else links
        self.ca = node_col + 2 * np.array([index[a] for a in kept.a.tolist()], np.int64)
        self.cb = node_col + 2 * np.array([index[b] for b in kept.b.tolist()], np.int64)
        self.r = kept.range_m
        self.s = kept.sigma_m

    def __len__(self) -> int:
        return len(self.r)

    def cov_scale(self, n_nodes: int, node_col: int, prm: SmootherParams) -> FloatArray:
        """Each node's covariance calibration (``n_nodes``; columns from ``node_col``).

        ``node_cov_scale``, times ``link_cov_scale`` for a node with links.
        """
        linked = np.zeros(n_nodes, dtype=bool)
        linked[(np.concatenate([self.ca, self.cb]) - node_col) // 2] = True
        return np.where(linked, prm.node_cov_scale * prm.link_cov_scale, prm.node_cov_scale)

    def parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Whitened residuals, ``p_a - p_b`` and the distance."""
        diff = np.column_stack([x[self.ca] - x[self.cb], x[self.ca + 1] - x[self.cb + 1]])
        return distance_rows(diff, self.r, self.s)

    def jacobian(self, x: FloatArray, row0: int
                 ) -> tuple[list[IntArray], list[IntArray], list[FloatArray]]:
        """Rows, columns and values of the link rows' Jacobian, from row ``row0``."""
        _, diff, d = self.parts(x)
        return distance_jacobian(diff, d, self.s, row0, [(self.ca, -1.0), (self.cb, 1.0)])


Terms = list[tuple[IntArray, "FloatArray | float"]]


def distance_rows(diff: FloatArray, r: FloatArray, s: FloatArray
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Whitened range residuals ``(r - ||diff||) / s``, ``diff`` (N, 2) and ``||diff||``."""
    d = np.maximum(np.hypot(diff[:, 0], diff[:, 1]), 1e-9)
    return (r - d) / s, diff, d


def distance_jacobian(diff: FloatArray, d: FloatArray, s: FloatArray, row0: int, terms: Terms
                      ) -> tuple[list[IntArray], list[IntArray], list[FloatArray]]:
    """Rows, columns and values of the Jacobian of :func:`distance_rows`, from row ``row0``.

    ``diff = sum_i c_i x[col_i]`` over ``terms`` ``(col_i, c_i)`` (the x column of each 2-D
    position; y is the next), so ``de / dx[col_i] = c_i u`` with ``u = diff / (d s)``.
    """
    u = diff / (d * s)[:, None]
    ri = row0 + np.arange(len(d))
    rows: list[IntArray] = []
    cols: list[IntArray] = []
    vals: list[FloatArray] = []
    for ax in (0, 1):
        for col, coef in terms:
            rows.append(ri)
            cols.append(col + ax)
            vals.append(coef * u[:, ax])
    return rows, cols, vals
