"""Stream a simulated team mission (:mod:`hrtls.sim.team`) to a running supervisor.

The commander's side creates the mission (floors with their plans, landmarks, agents with their
own ingest tokens) over the REST API; then every agent streams its session live through
:class:`hrtls.service.client.AgentClient`, one thread per agent, at ``speed`` times real time.
Session times are shifted so that the data start at the mission time of the stream's start.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import httpx

from hrtls.service.client import AgentClient, ServiceError, replay
from hrtls.sim.team import TeamMission


@dataclass(frozen=True, slots=True)
class StreamedAgent:
    """An agent created on the service for a team member."""

    id: int
    name: str
    kind: str
    token: str


@dataclass
class TeamStream:
    """A mission being streamed: its id, agents, and the threads that feed them."""

    mission_id: int
    t_offset_s: float
    agents: list[StreamedAgent]
    threads: list[threading.Thread] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for every agent's stream to end; True when all ended."""
        for thread in self.threads:
            thread.join(timeout_s)
        return not any(t.is_alive() for t in self.threads)

    @property
    def done(self) -> bool:
        """True when every agent has sent its whole session."""
        return not any(t.is_alive() for t in self.threads)


def _call(http: httpx.Client, method: str, path: str, body: Any = None) -> Any:
    r = http.request(method, "/api/v1" + path, json=body)
    if r.status_code >= 400:
        raise ServiceError(r.status_code, f"{method} {path}: {r.text}")
    return r.json() if r.content else None


def create_team_mission(server: str, commander_token: str, mission: TeamMission
                        ) -> tuple[int, float, list[StreamedAgent]]:
    """Create the mission, its floors, landmarks and agents; (mission id, now_t, agents)."""
    with httpx.Client(base_url=server.rstrip("/"), timeout=30.0,
                      headers={"Authorization": f"Bearer {commander_token}"}) as http:
        floors = [{"index": i, "name": name, "height_m": i * mission.floor_height_m,
                   "plan": mission.floor_plan(i)} for i, name in mission.floors]
        created = _call(http, "POST", "/missions", {
            "name": mission.name, "floor_height_m": mission.floor_height_m, "floors": floors})
        mid = int(created["id"])
        for lm in mission.landmarks:
            _call(http, "POST", f"/missions/{mid}/landmarks",
                  lm.model_dump(mode="json", exclude_none=True))
        agents = []
        for member in mission.members:
            out = _call(http, "POST", f"/missions/{mid}/agents", {
                "name": member.name, "kind": member.kind, "preset": member.preset})
            agents.append(StreamedAgent(int(out["agent"]["id"]), member.name, member.kind,
                                        str(out["token"])))
        now_t = float(_call(http, "GET", f"/missions/{mid}")["now_t"])
    return mid, now_t, agents


def stream_team_mission(server: str, commander_token: str, mission: TeamMission, *,
                        speed: float, on_error: Callable[[str], None] | None = None
                        ) -> TeamStream:
    """Create ``mission`` on the service and start streaming every member (threads)."""
    mid, now_t, agents = create_team_mission(server, commander_token, mission)
    stream = TeamStream(mission_id=mid, t_offset_s=now_t, agents=agents)

    def run(agent: StreamedAgent, member_index: int) -> None:
        member = mission.members[member_index]
        pose = member.session.meta.start_pose
        try:
            with AgentClient(server, agent.token) as client:
                if pose is not None:
                    client.checkin({**pose.model_dump(mode="json"), "t": now_t})
                replay(client, member.session.with_parts(truth=None), speed=speed,
                       t_offset_s=now_t)
        except (ServiceError, httpx.HTTPError) as exc:
            message = f"{agent.name}: {exc}"
            stream.errors.append(message)
            if on_error is not None:
                on_error(message)

    for k, agent in enumerate(agents):
        thread = threading.Thread(target=run, args=(agent, k), name=f"agent {agent.name}",
                                  daemon=True)
        thread.start()
        stream.threads.append(thread)
    return stream
