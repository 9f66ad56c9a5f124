"""Ranges between dropped nodes in the range-SLAM smoother (:mod:`hrtls.mission.graph`).

Links. Two static nodes measure one and the same distance every time, through the same walls:
their ranges' errors are not independent over the mission (an NLOS bias stays), so the ranges
of a pair are taken as one factor (the mission-long version of ``range_correlation_s``): the
median ``r`` of the pair's ranges, residual ``(r - ||p_a - p_b||) / s`` with
``s = sqrt(sigma_m^2 + (sigma_fraction r)^2)`` (the estimator's own noise model of the radio,
:class:`~hrtls.mission.graph_params.SmootherParams` ``link_sigma_m``, ``link_sigma_fraction``),
under the robust loss of the agents' ranges. Both nodes lie on the floor: no height term.

Geometry. A node enters the problem and may count as localized when the positions it is ranged
from spread off a line (:func:`hrtls.mission.graph_init.select_nodes`). With links, its
anchors are also its neighbours already in the problem (at their starting positions): its
effective spread is the largest of its agents' spread, the largest distance of a neighbour
from the best-fit line of its reading positions (a line of passes leaves a mirror ambiguity
that a neighbour off the line resolves) and, with three anchors or more, the spread of all of
them (TLA/SELA: a node between localized neighbours). Nodes join in rounds, each round's
nodes being anchors of the next (SELA's iterative localization); a joining node starts at the
linear trilateration from all its anchors.
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

MAX_ROUNDS = 8
"""Rounds of nodes joining through their neighbours, at most."""


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
               sigma_m: float, sigma_fraction: float) -> NodeLinks:
    """The ranges grouped by unordered pair: each pair's median range and sigma (module doc)."""
    if not len(range_m):
        return NodeLinks.empty()
    a, b = node_a.astype(str), node_b.astype(str)
    lo, hi = np.where(a < b, a, b), np.where(a < b, b, a)
    pairs, inv = np.unique(np.column_stack([lo, hi]), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    order = np.lexsort((range_m, inv))
    counts = np.bincount(inv, minlength=len(pairs))
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    srt = range_m[order]
    med = 0.5 * (srt[start + (counts - 1) // 2] + srt[start + counts // 2])
    sig = np.hypot(sigma_m, sigma_fraction * med)
    return NodeLinks(pairs[:, 0], pairs[:, 1], med, sig, counts.astype(np.int64))


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


def select_linked(paths: list[AgentPath], ranges: RangeSet, links: NodeLinks,
                  base: dict[str, float], start_m: dict[str, FloatArray],
                  prm: SmootherParams, height_m: float
                  ) -> tuple[dict[str, float], dict[str, FloatArray]]:
    """Nodes of the problem with links (module doc): id -> effective spread; starting points.

    ``base``: the nodes selected from the agents' ranges alone (id -> spread); ``start_m``:
    known starting positions (the others of ``base`` start at their agents' trilateration);
    ``height_m``: the antenna height difference the agents' ranges are reduced by.
    """
    out = dict(base)
    if not len(links):
        return out, {}
    raw = raw_positions(paths, ranges)
    horiz = np.sqrt(np.maximum(ranges.range_m ** 2 - height_m ** 2, 0.0))
    ids = sorted(set(links.a.tolist()) | set(links.b.tolist()))
    own = {n: np.flatnonzero(ranges.node == n) for n in ids}
    pos: dict[str, FloatArray] = {}
    for n in out:
        p = start_m.get(n)
        if p is None and n in own and len(own[n]) >= 3:
            p = linear_init(raw[own[n]], horiz[own[n]])
        if p is not None and np.all(np.isfinite(p)):
            pos[n] = np.asarray(p, np.float64)
    new: dict[str, FloatArray] = {}
    for _ in range(MAX_ROUNDS):
        joined = {}
        for n in ids:
            m = np.flatnonzero((links.a == n) | (links.b == n))
            other = np.where(links.a[m] == n, links.b[m], links.a[m])
            ok = np.array([o in pos for o in other.tolist()], dtype=bool)
            if not ok.any():
                continue
            nb = np.array([pos[o] for o in other[ok].tolist()]).reshape(-1, 2)
            k = own.get(n, np.zeros(0, np.int64))
            s = _effective(raw[k], nb, out.get(n, 0.0), prm.min_spread_m)
            if n in out:
                out[n] = max(out[n], s)
            elif s >= prm.min_spread_m:
                p = _start(raw[k], horiz[k], nb, links.range_m[m][ok])
                if p is not None and np.all(np.isfinite(p)):
                    joined[n] = (s, p)
        if not joined:
            break
        for n, (s, p) in joined.items():
            out[n], pos[n], new[n] = s, p, p
    return out, new


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

    def parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Whitened residuals, ``p_a - p_b`` and the distance."""
        diff = np.column_stack([x[self.ca] - x[self.cb], x[self.ca + 1] - x[self.cb + 1]])
        d = np.maximum(np.hypot(diff[:, 0], diff[:, 1]), 1e-9)
        return (self.r - d) / self.s, diff, d

    def jacobian(self, x: FloatArray, row0: int
                 ) -> tuple[list[IntArray], list[IntArray], list[FloatArray]]:
        """Rows, columns and values of the link rows' Jacobian, from row ``row0``."""
        _, diff, d = self.parts(x)
        u = diff / (d * self.s)[:, None]
        ri = row0 + np.arange(len(self.r))
        rows, cols, vals = [], [], []
        for ax in (0, 1):
            rows += [ri, ri]
            cols += [self.ca + ax, self.cb + ax]
            vals += [-u[:, ax], u[:, ax]]
        return rows, cols, vals
