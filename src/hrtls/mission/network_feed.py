"""Ranges between the dropped nodes in the mission loop (:meth:`MissionTracker.feed_network`).

The ranges fed wait in a buffer until their window is processed, like an agent's parts
(:class:`~hrtls.mission.buffer.AgentBuffer`): a range older than the processed horizon is late
(counted, returned as :class:`~hrtls.mission.buffer.LateData` with agent ``"network"``, not
used). They never hold the windows back (the nodes are not agents: a window waits for the
agents only). Each processed window ``[t_start, t_end)`` moves its ranges to the mission's
links, kept for the whole mission: the nodes are static, so every range of a pair measures the
same distance and the smoother takes a pair's ranges as one factor
(:mod:`hrtls.mission.graph_links`; the state grows with the ranges, at most a pair's ranges at
the radio's rate). A range naming an agent or a landmark with a position is not a range
between dropped nodes: warned of (:class:`~hrtls.errors.DegradedInputWarning`), then kept
apart from the problem (only nodes of the problem are linked). On two floors a link joins
two nodes only while their estimated floors agree.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from hrtls.data.landmarks import Landmark
from hrtls.data.session import SessionMeta
from hrtls.errors import DegradedInputWarning
from hrtls.mission.buffer import LateData
from hrtls.mission.graph_links import NodeLinks, pair_links
from hrtls.mission.graph_params import SmootherParams
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.nodes import NodeRanges

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

NETWORK = "network"
"""The ``agent`` of the network's :class:`~hrtls.mission.buffer.LateData`."""


@dataclass
class NetworkState:
    """The network's ranges in the loop.

    ``pending``: fed, not processed; ``used``: those of the processed windows; ``heard_s``:
    the clock of the latest part; ``late``: how many ranges came late; ``pairs``: ``used``
    grouped by pair (derived, not snapshotted: None until asked after ``used`` changed).
    """

    pending: NetworkRanges = field(default_factory=NetworkRanges.empty)
    used: NetworkRanges = field(default_factory=NetworkRanges.empty)
    heard_s: float = -math.inf
    late: int = 0
    pairs: NodeLinks | None = None


def feed(mt: MissionTracker, part: NetworkRanges, *, now_s: float | None) -> LateData | None:
    """Buffer ``part``; its ranges before the processed horizon come back as late (module doc)."""
    st = mt.network
    if not len(part):
        return None
    _warn_not_nodes(mt, part)
    st.heard_s = max(st.heard_s, float(part.t_s.max()) if now_s is None else now_s)
    late = part.t_s < mt.horizon_s
    st.pending = NetworkRanges.concat([st.pending, part.select(~late)])
    if not late.any():
        return None
    st.late += int(np.count_nonzero(late))
    t = part.t_s[late]
    return LateData(NETWORK, float(t.min()), float(t.max()), mt.horizon_s,
                    int(np.count_nonzero(late)))


def known_ids(meta: SessionMeta, landmarks: Mapping[str, Landmark]) -> list[str]:
    """Ids of an agent's landmarks with a position (local, or WGS-84 with a georeference)."""
    geo = meta.georeference is not None
    return sorted(k for k, lm in landmarks.items()
                  if lm.position is not None or (geo and lm.wgs84 is not None))


def _warn_not_nodes(mt: MissionTracker, part: NetworkRanges) -> None:
    taken = set(mt.names) | {k for ids in mt.known for k in ids}
    bad = sorted(set(part.nodes()) & taken)
    if bad:
        shown = ", ".join(bad[:5]) + (" ..." if len(bad) > 5 else "")
        warnings.warn(f"network ranges: {len(bad)} id(s) name an agent or a landmark with a "
                      f"position, not a dropped node ({shown})", DegradedInputWarning,
                      stacklevel=3)


def step(mt: MissionTracker, t_start: float, t_end: float) -> None:
    """Move the window's ranges (``t_start <= t < t_end``) to the links (module doc)."""
    st = mt.network
    if not len(st.pending):
        return
    now = st.pending.t_s < t_end
    if now.any():
        st.used = NetworkRanges.concat([st.used, st.pending.select(now)])
        st.pending = st.pending.select(~now)
        st.pairs = None


def _pairs(mt: MissionTracker) -> NodeLinks:
    """Every pair of the processed windows as a factor, computed once per change.

    With the smoother's noise model (by default :class:`SmootherParams`'s).
    """
    st = mt.network
    if st.pairs is None:
        prm = mt.params.smoother or SmootherParams()
        st.pairs = pair_links(st.used.node_a, st.used.node_b, st.used.range_m,
                              sigma_m=prm.link_sigma_m, sigma_fraction=prm.link_sigma_fraction,
                              bias_sigma_m=prm.link_bias_sigma_m)
    return st.pairs


def links(mt: MissionTracker) -> NodeLinks:
    """The pairs of the processed windows as factors, on agreeing floors (module doc)."""
    if not len(mt.network.used) or mt.params.smoother is None:
        return NodeLinks.empty()
    out = _pairs(mt)
    if not mt.node_floor:
        return out
    fa = np.array([mt.node_floor.get(n, -1) for n in out.a.tolist()])
    fb = np.array([mt.node_floor.get(n, -1) for n in out.b.tolist()])
    return out.select((fa == fb) | (fa < 0) | (fb < 0))


def node_ranges(mt: MissionTracker, node: str, floor: int) -> NodeRanges:
    """The node's readings on ``floor`` for the per-node estimator, with its neighbours.

    Each localized neighbour on the same floor linked to the node is one more anchor (TLA):
    at its estimate, with its covariance as an agent's (added to the range's variance by the
    estimator), its pair's one range (:func:`~hrtls.mission.graph_links.pair_links`, the
    smoother's noise model, by default :class:`~hrtls.mission.graph_params.SmootherParams`'s),
    its own pass and chain (the pair's row of :func:`_pairs`): its error is taken as
    independent of the agents' errors in the node's readings (module doc of
    :mod:`hrtls.mission.nodes`: only the common part ``agent_correlation`` is shared).
    """
    obs = mt.readings[node].ranges(mt.params.pass_gap_s, floor=floor)
    if not len(mt.network.used) or not len(obs):
        return obs
    pairs = _pairs(mt)
    links = pairs.select((pairs.a == node) | (pairs.b == node))
    if not len(links):
        return obs
    other = np.where(links.a == node, links.b, links.a).tolist()
    k = [j for j, o in enumerate(other) if o in mt.estimates and mt.estimates[o].localized
         and mt.node_floor.get(o, 0) == floor]
    if not k:
        return obs
    est = [mt.estimates[other[j]] for j in k]
    new = np.arange(len(k), dtype=np.int64)
    t = obs.t_s if obs.t_s is not None else np.zeros(len(obs))
    return NodeRanges.build(
        agent_xy_m=np.vstack([obs.agent_xy_m, [e.position_m for e in est]]),
        agent_cov_m2=np.concatenate([obs.agent_cov_m2, [e.covariance_m2 for e in est]]),
        range_m=np.concatenate([obs.range_m, links.range_m[k]]),
        range_sigma_m=np.concatenate([obs.range_sigma_m, links.sigma_m[k]]),
        group=np.concatenate([obs.group, obs.group.max() + 1 + new]),
        chain=np.concatenate([obs.chain, obs.chain.max() + 1 + new]),
        t_s=np.concatenate([t, np.full(len(k), t.max())]))


def state_of(st: NetworkState) -> dict[str, Any]:
    """Plain values of the state (snapshot)."""
    return {k: [r.t_s, r.node_a.astype(str).tolist(), r.node_b.astype(str).tolist(), r.range_m]
            for k, r in (("pending", st.pending), ("used", st.used))} | {
        "heard_s": st.heard_s, "late": st.late}


def state_from(d: dict[str, Any] | None) -> NetworkState:
    """The state from :func:`state_of` values (an older snapshot without it: empty)."""
    if d is None:
        return NetworkState()
    parts = {k: NetworkRanges(np.asarray(v[0], np.float64), np.asarray(v[1], np.str_),
                              np.asarray(v[2], np.str_), np.asarray(v[3], np.float64))
             if len(v[0]) else NetworkRanges.empty() for k, v in
             ((k, d[k]) for k in ("pending", "used"))}
    return NetworkState(parts["pending"], parts["used"], float(d["heard_s"]), int(d["late"]))
