"""Inter-agent ranges to the mission's range-SLAM smoother (``SmootherParams.peer_factors``).

Collect. With ``peer_factors`` and cooperation, every range an agent measured to another agent
(:func:`hrtls.mission.peers.split_peer_ranges`) is kept in the smoother's state as ``[agent
index, t, peer, range, sigma]`` blocks (all of them; a tracker takes at most one per peer and
window); a solve takes those both agents' paths cover (:func:`problem_peers`: a range later
than either agent's latest row waits for the next solve) as factors between their poses
(:mod:`hrtls.mission.graph_peers`).

Counted once (:func:`takes_peers`). An agent the smoother feeds back (a rescuer with
``feedback``; a robot with ``robots`` "feedback") takes no inter-agent range in its tracker:
the smoother solves both agents' poses with the range, and the feedback carries it to the
tracker; taken there too it would count twice (as a fed-back rescuer's ranges to the
smoother's nodes, :func:`hrtls.mission.smoothing.via_feedback`). Any other agent (every agent
without feedback; the robot of the ``feedback`` mode, ``robots`` "alone") keeps its tracker's
own correction (:mod:`hrtls.mission.peers`; none with ``PeerRangeParams.factors_only``: it
then ignores its peer ranges): the smoother takes the raw range as a factor and never that
correction (its jump leaves the agent's dead reckoning and it is no factor,
:func:`hrtls.mission.smoothing._agent_path`), so no range enters the smoother twice.

Window. When an agent's poses before ``t_c`` leave the problem, so do the ranges it measured
or was measured by before ``t_c`` (:func:`cut`; which of them the prior keeps:
:func:`hrtls.mission.graph_peers.marginalizable`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hrtls.data.observations import RangeMeasurements
from hrtls.mission.graph_peers import PeerSet
from hrtls.mission.robot import RobotTracker
from hrtls.pipeline.tracker import Tracker

if TYPE_CHECKING:
    from hrtls.mission.graph import AgentPath
    from hrtls.mission.tracker import MissionTracker


def active(mt: MissionTracker) -> bool:
    """The smoother takes the inter-agent ranges (``peer_factors``, with cooperation)."""
    prm = mt.params.smoother
    return prm is not None and prm.peer_factors and mt.params.cooperate and \
        mt.smoother is not None


def takes_peers(mt: MissionTracker, i: int) -> bool:
    """Agent ``i``'s tracker takes its ranges to other agents (module doc: counted once)."""
    prm = mt.params.smoother
    if not active(mt) or prm is None or prm.feedback == "off":
        return True
    tr = mt.trackers[mt.names[i]]
    fed = isinstance(tr, Tracker) or (isinstance(tr, RobotTracker) and prm.robots == "feedback")
    return not fed and not mt.params.peer_ranges.factors_only


def collect(mt: MissionTracker, i: int, ranges: RangeMeasurements) -> None:
    """Keep agent ``i``'s ranges to the other agents (``ranges``: those) for the smoother."""
    st = mt.smoother
    if not active(mt) or st is None:
        return
    m = np.isin(ranges.node, mt.names) & (ranges.node != mt.names[i])
    if m.any():
        st.peers.append([i, ranges.t[m].copy(), ranges.node[m].astype(str),
                         ranges.range_m[m].copy(), ranges.sigma_m[m].copy()])


def problem_peers(mt: MissionTracker, paths: list[AgentPath]) -> PeerSet:
    """The kept ranges between two agents of ``paths`` inside both paths' spans."""
    st = mt.smoother
    if st is None or not st.peers:
        return PeerSet.empty()
    index = {p.name: k for k, p in enumerate(paths)}
    a = np.concatenate([np.full(len(p[1]), index.get(mt.names[int(p[0])], -1), np.int64)
                        for p in st.peers])
    b = np.array([index.get(n, -1) for p in st.peers for n in p[2].tolist()], np.int64)
    t = np.concatenate([p[1] for p in st.peers])
    ok = (a >= 0) & (b >= 0)
    t0 = np.array([p.t[0] for p in paths])
    t1 = np.array([p.t[-1] for p in paths])
    ok[ok] &= (t[ok] >= t0[a[ok]]) & (t[ok] >= t0[b[ok]]) & (t[ok] <= t1[a[ok]]) & \
        (t[ok] <= t1[b[ok]])
    return PeerSet(a[ok], b[ok], t[ok], np.concatenate([p[3] for p in st.peers])[ok],
                   np.concatenate([p[4] for p in st.peers])[ok])


def cut(mt: MissionTracker, i: int, t_c: float) -> None:
    """Drop the kept ranges agent ``i`` measured or was measured by before ``t_c``."""
    st = mt.smoother
    if st is None or not st.peers:
        return
    name = mt.names[i]
    parts = []
    for p in st.peers:
        mine = np.full(len(p[1]), int(p[0]) == i) | (p[2] == name)
        keep = ~(mine & (p[1] < t_c))
        if keep.any():
            parts.append([p[0], *(v[keep] for v in p[1:])])
    st.peers = parts
