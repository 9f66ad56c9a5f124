"""Feeding a mission live in parts with a snapshot restored half-way (shared by the tests)."""

from __future__ import annotations

from collections.abc import Callable

from hrtls.data import Session
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionTracker
from hrtls.pipeline.chunks import split_session
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission


def restored_half_way(sessions: dict[str, Session], kinds: dict[str, str],
                      params: MissionParams, *, part_s: float = 1.0,
                      at_cut: Callable[[MissionTracker], None] | None = None,
                      network: NetworkRanges | None = None) -> MissionTracker:
    """Every agent's parts of ``part_s`` fed in arrival order (advancing after each), the
    tracker snapshot and restored before the middle part (``at_cut`` sees it first), every
    agent ended; :meth:`MissionTracker.run` then gives the result. ``network``: ranges between
    nodes, those before each part's end fed before it."""
    parts = sorted(((k, p) for k, s in sessions.items() for p in split_session(s, part_s)),
                   key=lambda kp: kp[1].time_span()[1])
    cut = len(parts) // 2
    mt = MissionTracker({k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()},
                        kinds=kinds, params=params)
    for j, (name, part) in enumerate(parts):
        if j == cut:
            if at_cut is not None:
                at_cut(mt)
            mt = MissionTracker.restore(mt.snapshot())
        if network is not None:
            t_end = part.time_span()[1]
            mt.feed_network(network.select(network.t_s <= t_end), now_s=float(j))
            network = network.select(network.t_s > t_end)
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
    for k in sessions:
        mt.end(k)
    return mt


def short_mission(seed: int) -> tuple[dict[str, Session], dict[str, str]]:
    """A 60 s hybrid mission with 15 nodes; sessions without ground truth, and the kinds."""
    m = inderst_hybrid_mission(seed, MissionOptions(walk_s=60.0, stagger_s=15.0, n_nodes=15))
    return ({k: s.with_parts(truth=None, checkpoints=None) for k, s in m.agents.items()},
            dict(m.kinds))
