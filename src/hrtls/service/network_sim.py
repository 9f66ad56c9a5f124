"""A simulated networked mission streamed live (``hrtls mission simulate inderst_hybrid_mission``).

The simulator's mission (:mod:`hrtls.sim.mission`: rescuers, robots, dropped range nodes) becomes
a service mission with its agents, the known tags as landmarks and the nodes declared as its
sensor network (``PUT /missions/{id}/network``), so the service runs the mission estimator.
Every agent streams with one common time shift (their relative timing is the simulator's;
for a fresh mission no shift: the mission's time is the simulator's).
The agents get their sessions without ground truth.
"""

from __future__ import annotations

import math
from typing import Any

from hrtls.service.client import AgentClient
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


def stream_network(server: str, commander: AgentClient, mission_id: int,
                   agents: list[tuple[TeamMember, int, str]], *, speed: float
                   ) -> list[AgentClient]:
    """Stream every agent live with the team's common time shift; the clients when done."""
    offset = common_offset(commander, mission_id, [m for m, _, _ in agents])
    return stream_team(server, agents, speed=speed, t_offset_s=offset)
