"""A simulated networked mission streamed live (``hrtls mission simulate inderst_hybrid_mission``).

The simulator's mission (:mod:`hrtls.sim.mission`: rescuers, robots, dropped range nodes) becomes
a service mission with its agents, the known tags as landmarks and the nodes declared as its
sensor network (``PUT /missions/{id}/network``), so the service runs the mission estimator.
Every agent streams with one common time shift (their relative timing is the simulator's;
for a fresh mission no shift: the mission's time is the simulator's).
The agents get their sessions without ground truth. When the nodes range each other
(``-O node_ranges=true``), a gateway thread posts those ranges with the same shift and pace
(``POST /missions/{id}/network/ranges``), each chunk when its first range is due: ahead of the
agents' data, so that none is late for the windows the estimator processes.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from hrtls.mission.network_ranges import NetworkRanges
from hrtls.service.client import AgentClient, ServiceError
from hrtls.service.missions import TeamMember, create_mission, stream_team
from hrtls.sim.mission import Mission, run_mission

RESCUER_PRESET = "rescue-mission"
"""The rescuers' tracker preset (the hybrid-mission study's settings, README)."""
ROBOT_PRESET = "default"


def network_team(name: str, *, seed: int, options: dict[str, Any],
                 rescuer_preset: str = RESCUER_PRESET) -> tuple[Mission, list[TeamMember]]:
    """The simulated mission and its agents as team members (sessions without truth).

    The rescuers get the tracker preset ``rescuer_preset``, the robots ``ROBOT_PRESET``.
    """
    mission = run_mission(name, seed, **options)
    members = []
    for k, s in mission.agents.items():
        kind = mission.kinds.get(k, "rescuer")
        members.append(TeamMember(k, kind, s.with_parts(truth=None, checkpoints=None),
                                  preset=ROBOT_PRESET if kind == "robot" else rescuer_preset))
    return mission, members


def create_network_mission(commander: AgentClient, name: str, mission: Mission,
                           members: list[TeamMember], *, params: dict[str, Any]
                           ) -> tuple[int, list[tuple[TeamMember, int, str]]]:
    """Create the service mission with its agents and declare its network."""
    mid, agents = create_mission(commander, f"{name} seed {mission.seed}", members)
    commander.request("PUT", f"/missions/{mid}/network",
                      json={"nodes": [{"id": n} for n in mission.node_truth_m],
                            "params": params})
    return mid, agents


MAX_LAG_S = 60.0
"""The simulator's own times are kept when its start is at most this behind the mission's now."""


def common_offset(commander: AgentClient, mission_id: int, members: list[TeamMember]) -> float:
    """The time shift of the team, s.

    None when the simulator's start is at most ``MAX_LAG_S`` behind the mission's now (a fresh
    mission: the service gets the very times the simulated mission folder has), else the shift
    putting its earliest sample at now (whole seconds).
    """
    now_t = float(commander.request("GET", f"/missions/{mission_id}")["now_t"])
    t_min = min(m.session.time_span()[0] for m in members)
    if 0.0 <= now_t - t_min <= MAX_LAG_S:
        return 0.0
    return float(math.ceil(now_t - t_min))


NETWORK_CHUNK_S = 5.0
"""Mission time of node-to-node ranges per posted batch, s."""


def post_network_ranges(commander: AgentClient, mission_id: int, ranges: NetworkRanges, *,
                        speed: float, t_offset_s: float, t_start_s: float,
                        clock: Callable[[], float] = time.monotonic,
                        sleep: Callable[[float], None] = time.sleep) -> int:
    """Post ``ranges`` in chunks of ``NETWORK_CHUNK_S`` (module doc); the batches posted.

    ``t_start_s``: mission time that is due at the call (the team's first sample);
    ``speed``: replay factor (``inf``: at once). A 429 is retried every 0.2 s, 100 times
    at most.
    """
    if not len(ranges.t_s):
        return 0
    start_wall = clock()
    k = np.floor((ranges.t_s - t_start_s) / NETWORK_CHUNK_S).astype(np.int64)
    edges = np.flatnonzero(np.diff(k)) + 1
    for seq, idx in enumerate(np.split(np.arange(len(k)), edges)):
        t = ranges.t_s[idx] + t_offset_s
        if speed != math.inf:
            delay = start_wall + (float(ranges.t_s[idx[0]]) - t_start_s) / speed - clock()
            if delay > 0:
                sleep(delay)
        body = {"seq": seq, "t_s": t.tolist(), "node_a": ranges.node_a[idx].tolist(),
                "node_b": ranges.node_b[idx].tolist(), "range_m": ranges.range_m[idx].tolist()}
        for _ in range(100):
            try:
                commander.request("POST", f"/missions/{mission_id}/network/ranges", json=body)
                break
            except ServiceError as exc:
                if exc.status != 429:
                    raise
                sleep(0.2)
        else:
            raise ServiceError(429, f"network ranges batch {seq}: still refused after 100 tries")
    return len(edges) + 1


def stream_network(server: str, commander: AgentClient, mission_id: int,
                   agents: list[tuple[TeamMember, int, str]], *, speed: float,
                   network: NetworkRanges | None = None) -> list[AgentClient]:
    """Stream the agents and the node-to-node ranges; the agents' clients when done.

    Every agent with the team's common time shift, ``network`` from a gateway thread.
    """
    members = [m for m, _, _ in agents]
    offset = common_offset(commander, mission_id, members)
    errors: list[BaseException] = []

    def gateway() -> None:
        assert network is not None
        try:
            with AgentClient(server, token) as gw:
                post_network_ranges(gw, mission_id, network, speed=speed, t_offset_s=offset,
                                    t_start_s=min(m.session.time_span()[0] for m in members))
        except BaseException as exc:
            errors.append(exc)

    token = commander.http.headers["Authorization"].removeprefix("Bearer ")
    thread = threading.Thread(target=gateway, daemon=True) if network is not None else None
    if thread is not None:
        thread.start()
    clients = stream_team(server, agents, speed=speed, t_offset_s=offset)
    if thread is not None:
        thread.join()
    if errors:
        raise errors[0]
    return clients
