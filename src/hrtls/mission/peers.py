"""Inter-agent ranges (UWB between teammates and robots) as corrections between agents' filters.

A range ``r`` from agent A to agent B (``ranges`` of A's session with node id ``B``) at time
``t`` corrects A's tracker through its range-to-landmark path (eq. 4.34-4.35): B is a temporary
landmark at B's estimate at ``t``. When B's track covers ``t`` (B went first in the window) it
is interpolated between B's rows; when ``t`` is later than B's latest row ``t_B`` (B goes
later in the window, or made no row since) B is carried from its rows at or before ``t_B``
(causal): by default held at its last row with the worst-case bound ``s_move^2 = (v_max g)^2``,
``g = t - t_B`` (``PEER_SPEED_M_S``, a bound on an agent's speed), or extrapolated (below).
B's own ranges to A correct B the same way, so each exchange corrects both agents.

Extrapolation (``PeerRangeParams.extrapolate``; off by default: it made the held-out missions
of ``benchmarks/mission.py --peer-ranges`` worse, docs/mission.md). B's velocity ``v`` is the
chord of its rows over the last ``velocity_window_s`` before ``t_B``; the landmark is
``x_B(t_B) + v g``, and its variance per axis is B's plus the extrapolation's::

    s_move^2 = g^2 lambda_max(S_v) + q g^3 / 3

``S_v`` the time-weighted spread of the row-to-row velocities around ``v`` in the window (how
steady B moved), ``q g^3 / 3`` the position variance of a continuous white-noise acceleration of
spectral density ``q = accel_sigma_m_s2^2`` over ``g`` (Bar-Shalom, Li, Kirubarajan 2001,
Sec. 6.2.2, eq. 6.2.2-12): B may turn or stop after its last row. With fewer than two rows B is
held with the bound.

Consistency. After a first exchange the two filters' errors are correlated, and a filter that
takes the peer as an independent anchor over-counts; so does a robot whose peer is a rescuer
the smoother fed back with the robot's own ranges. Two rules (``PeerRangeParams.rule``).

A robot (default ``"intersect"``) takes the range by split covariance intersection
(:mod:`hrtls.mission.robot`): B's variance along the line of sight, ``lambda_max(P_B) +
s_move^2``, is the part that may be correlated with the robot's whole state in any way, the
range's noise the independent part; consistent for every correlation, so each range is taken
as it comes (no count ``n``), and a peer is taken only when it lowers the robot's
uncertainty. On dev seeds 0-9 (docs/mission.md) the widening below made the robot's NEES
worse than without peer ranges (and its error on some seeds); the intersection kept its NEES
about the no-peer level and lowered its error.

A rescuer's tracker (and a robot with ``"widen"``) widens the range as for the dropped nodes
(:mod:`hrtls.mission.tracker`), which reuses the tracker's scalar range update unchanged:

    sigma_use^2 = sigma_r^2 + n * (lambda_max(P_B) + s_move^2)

``n`` the ranges A has used from B in the current pass (``pass_gap_s``), this one included, so
that ``sum 1/sigma_use^2`` over a pass, the information A takes from B's one (correlated) error,
stays about that of a single range with B's variance, ``1 / lambda_max(P_B)``, however many ranges
the pass holds; ``lambda_max`` makes the isotropic anchor variance at least B's in every
direction; ``s_move^2`` covers B's move between its estimate and the range (the bound or the
extrapolation's variance), and is zero when B's rows cover ``t``. The move is taken as
independent of B's estimate error (B's unknown manoeuvres, not its sensors); it is counted ``n``
times like B's error, which over-covers it when the ranges of a pass have different gaps. At
most one range per peer and window is used (the nearest in time to B's latest row): the
landmark holds one position per window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements
from hrtls.errors import InputError
from hrtls.mission import peer_feed
from hrtls.mission.robot import RobotTracker

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

RULES = ("widen", "intersect")
"""The robot's peer correction rules (``PeerRangeParams.rule``)."""

PEER_SPEED_M_S = 2.0
"""Bound on an agent's speed (walking rescuer, robot), m/s: B's move since its estimate."""

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class PeerRangeParams:
    """How a peer's estimate is carried to the time of a range (module doc).

    Attributes
    ----------
    extrapolate: extrapolate the peer with its estimated velocity; False (default): hold it at
        its last row with the speed bound (the extrapolation made held-out missions worse).
    velocity_window_s: span of the peer's latest rows its velocity is taken from, s.
    accel_sigma_m_s2: square root of the white-noise acceleration density ``q``, m/s^2/sqrt(Hz)
        (``q g^3 / 3``: position variance after ``g`` s).
    rule: a robot's correction by a peer range: ``"intersect"`` (default: covariance
        intersection, :mod:`hrtls.mission.robot`) or ``"widen"`` (the widening rule, module
        doc); a rescuer's tracker always widens.
    factors_only: with the smoother's peer factors (:mod:`hrtls.mission.peer_feed`) no tracker
        takes a peer range itself: a fed-back agent gets it through the feedback, any other
        agent (the ``feedback`` mode's robot) ignores it.
    """

    extrapolate: bool = False
    velocity_window_s: float = 2.0
    accel_sigma_m_s2: float = 0.6
    rule: str = "intersect"
    factors_only: bool = False

    def __post_init__(self) -> None:
        for name in ("velocity_window_s", "accel_sigma_m_s2"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} = {v}", where="PeerRangeParams", expected="> 0")
        if self.rule not in RULES:
            raise InputError(f"rule = {self.rule!r}", where="PeerRangeParams",
                             expected=" or ".join(RULES))

    def rows_kept_s(self) -> float:
        """How far back (s) an agent's rows must be kept for the extrapolation."""
        return self.velocity_window_s if self.extrapolate else 0.0


@dataclass(frozen=True)
class PeerExtrapolation:
    """A peer carried to a range's time: xy (m), velocity (m/s), extrapolation variance (m^2)."""

    xy_m: FloatArray
    velocity_m_s: FloatArray
    var_m2: float


def extrapolate_peer(*, t_s: FloatArray, xy_m: FloatArray, at_s: float,
                     params: PeerRangeParams) -> PeerExtrapolation:
    """The peer's position at ``at_s`` from its rows ``(t_s, xy_m)`` at or before it (module doc).

    Rows later than ``at_s`` are ignored (causal). With fewer than two rows in the window the
    peer is held at its last row with the bound ``(PEER_SPEED_M_S g)^2``.
    """
    m = t_s <= at_s
    t, x = t_s[m], xy_m[m]
    if len(t) == 0:
        raise InputError(f"no row at or before {at_s} s", where="extrapolate_peer",
                         expected="a row at or before the range time")
    g = at_s - float(t[-1])
    i0 = min(int(np.searchsorted(t, t[-1] - params.velocity_window_s)), len(t) - 2)
    if i0 < 0 or not params.extrapolate:
        return PeerExtrapolation(x[-1].copy(), np.zeros(2), (PEER_SPEED_M_S * g) ** 2)
    span = float(t[-1] - t[i0])
    v = (x[-1] - x[i0]) / span
    dt = np.diff(t[i0:])
    dv = np.diff(x[i0:], axis=0) / dt[:, None] - v
    spread = (dv * (dt / span)[:, None]).T @ dv                     # S_v
    q = params.accel_sigma_m_s2 ** 2
    var = g * g * float(np.linalg.eigvalsh(spread)[-1]) + q * g ** 3 / 3.0   # eq. 6.2.2-12
    return PeerExtrapolation(x[-1] + v * g, v, var)


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
    rows = mt.agent_rows(peer)
    if rows is None:
        return None
    tb, xy, cov = rows
    k = int(np.argmin(np.abs(t - min(float(tb[-1]), float(t[-1])))))
    tk = float(t[k])
    j = int(np.clip(np.searchsorted(tb, tk), 0, len(tb) - 1))
    if tk > float(tb[-1]):
        ext = extrapolate_peer(t_s=tb, xy_m=xy, at_s=tk, params=mt.params.peer_ranges)
        var = float(np.linalg.eigvalsh(cov[-1])[-1]) + ext.var_m2
        return k, ext.xy_m, var, float(tb[-1])
    pos = np.array([np.interp(tk, tb, xy[:, 0]), np.interp(tk, tb, xy[:, 1])])
    return k, pos, float(np.linalg.eigvalsh(cov[j])[-1]), float(tb[j])


def split_peer_ranges(mt: MissionTracker, i: int, ranges: RangeMeasurements | None
                      ) -> tuple[RangeMeasurements | None, RangeMeasurements | None]:
    """Agent ``i``'s ranges to nodes, and its ranges to peers ready for its tracker (module doc).

    Sets each used peer as a landmark of agent ``i``'s tracker; without cooperation
    (``MissionParams.cooperate``) peer ranges are dropped. With the smoother's peer factors
    they go to the smoother, and to the tracker only when it takes them
    (:mod:`hrtls.mission.peer_feed`).
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
    peer_feed.collect(mt, i, ranges)
    if not peer_feed.takes_peers(mt, i):
        return rest, None
    rows: list[tuple[float, str, float, float]] = []
    intersect = mt.params.peer_ranges.rule == "intersect"
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
        sigma_r = float(ranges.sigma_m[sel[k]])
        tr = mt.trackers[mt.names[i]]
        if intersect and isinstance(tr, RobotTracker):
            tr.set_peers({peer: (float(pos[0]), float(pos[1]), var)})
            rows.append((tk, peer, float(ranges.range_m[sel[k]]), sigma_r))
            continue
        lm = Landmark(id=peer, kind="node", floor=0, accuracy_m=math.sqrt(var),
                      position=(float(pos[0]), float(pos[1]), 0.0), updated=tk)
        mt.give_landmarks(mt.names[i], {peer: lm})
        rows.append((tk, peer, float(ranges.range_m[sel[k]]), math.sqrt(sigma_r ** 2 + n * var)))
    if not rows:
        return rest, None
    rows.sort()
    peer_r = RangeMeasurements(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                               np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
    return rest, peer_r
