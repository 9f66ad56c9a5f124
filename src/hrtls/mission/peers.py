"""Inter-agent ranges (UWB between teammates and robots) as corrections between agents' filters.

A range ``r`` from agent A to agent B (``ranges`` of A's session with node id ``B``) at time
``t`` corrects A's tracker through its range-to-landmark path (eq. 4.34-4.35): B is a temporary
landmark at B's latest estimate ``x_B(t_B)`` (``t_B`` the last row of B's track at or before
the window's processing, interpolated when B's track covers ``t``). B's own ranges to A correct
B the same way, so each exchange corrects both agents.

Consistency. After a first exchange the two filters' errors are correlated, and a filter that
takes the peer as an independent anchor over-counts. Rule chosen: the same widening as for the
dropped nodes (:mod:`hrtls.mission.tracker`), not covariance intersection, because it reuses
the trackers' scalar range update unchanged and keeps the cross terms bounded by construction:

    sigma_use^2 = sigma_r^2 + n * (lambda_max(P_B) + (v_max |t - t_B|)^2)

``n`` the ranges A has used from B in the current pass (``pass_gap_s``), this one included, so
that ``sum 1/sigma_use^2`` over a pass, the information A takes from B's one (correlated) error,
stays about that of a single range with B's variance, ``1 / lambda_max(P_B)``, however many ranges
the pass holds; ``lambda_max`` makes the isotropic anchor variance at least B's in every
direction; the motion term covers B's move between its estimate and the range
(``peer_speed_m_s``, a bound on an agent's speed). At most one range per peer and window is used
(the nearest in time to B's estimate): the landmark holds one position per window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

PEER_SPEED_M_S = 2.0
"""Bound on an agent's speed (walking rescuer, robot), m/s: B's move since its estimate."""


@dataclass
class PeerUses:
    """Per (agent index, peer name): time of the last range used and the uses in its pass."""

    uses: dict[tuple[int, str], tuple[float, int]] = field(default_factory=dict)


def merge_ranges(a: RangeMeasurements | None, b: RangeMeasurements | None
                 ) -> RangeMeasurements | None:
    """``a`` and ``b`` in one time-ordered set."""
    if a is None or b is None:
        return a if b is None else b
    t = np.concatenate([a.t, b.t])
    o = np.argsort(t, kind="stable")
    return RangeMeasurements(t[o], np.concatenate([a.node, b.node])[o],
                             np.concatenate([a.range_m, b.range_m])[o],
                             np.concatenate([a.sigma_m, b.sigma_m])[o])


def _peer_at(mt: MissionTracker, peer: str, t: np.ndarray
             ) -> tuple[int, np.ndarray, float, float] | None:
    """Index of the range of times ``t`` used, B's xy there, its variance, its landmark time."""
    if peer not in mt.started:
        return None
    rows = mt._agent_rows(peer)
    if rows is None:
        return None
    tb, xy, cov = rows
    k = int(np.argmin(np.abs(t - min(float(tb[-1]), float(t[-1])))))
    tk = float(t[k])
    j = int(np.clip(np.searchsorted(tb, tk), 0, len(tb) - 1))
    pos = np.array([np.interp(tk, tb, xy[:, 0]), np.interp(tk, tb, xy[:, 1])])
    gap = max(tk - float(tb[-1]), 0.0)
    var = float(np.linalg.eigvalsh(cov[j])[-1]) + (PEER_SPEED_M_S * gap) ** 2
    return k, pos, var, float(tb[min(j, len(tb) - 1)])


def split_peer_ranges(mt: MissionTracker, i: int, ranges: RangeMeasurements | None
                      ) -> tuple[RangeMeasurements | None, RangeMeasurements | None]:
    """Agent ``i``'s ranges to nodes, and its ranges to peers ready for its tracker (module doc).

    Sets each used peer as a landmark of agent ``i``'s tracker; without cooperation
    (``MissionParams.cooperate``) peer ranges are dropped.
    """
    if ranges is None:
        return None, None
    is_peer = np.isin(ranges.node, mt.names)
    if not is_peer.any():
        return ranges, None
    m = ~is_peer
    rest = (RangeMeasurements(ranges.t[m], ranges.node[m], ranges.range_m[m], ranges.sigma_m[m])
            if m.any() else None)
    if not mt.params.cooperate:
        return rest, None
    rows: list[tuple[float, str, float, float]] = []
    for peer in sorted(set(ranges.node[is_peer].tolist()) - {mt.names[i]}):
        sel = np.flatnonzero(ranges.node == peer)
        got = _peer_at(mt, peer, ranges.t[sel])
        if got is None:
            continue
        k, pos, var, _ = got
        tk = float(ranges.t[sel[k]])
        last_t, n = mt.peers.uses.get((i, peer), (-math.inf, 0))
        n = 1 if tk - last_t > mt.params.pass_gap_s else n + 1
        mt.peers.uses[(i, peer)] = (tk, n)
        sigma = math.sqrt(float(ranges.sigma_m[sel[k]]) ** 2 + n * var)
        lm = Landmark(id=peer, kind="node", floor=0, accuracy_m=math.sqrt(var),
                      position=(float(pos[0]), float(pos[1]), 0.0), updated=tk)
        mt._apply(mt.names[i], "set_landmarks", {peer: lm})
        rows.append((tk, peer, float(ranges.range_m[sel[k]]), sigma))
    if not rows:
        return rest, None
    rows.sort()
    peer_r = RangeMeasurements(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                               np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
    return rest, peer_r
