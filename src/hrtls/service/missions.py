"""Whole missions: stream a simulated team live (``hrtls mission simulate``) and export one."""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import Session
from hrtls.data.observations import PositionFixes
from hrtls.errors import InputError
from hrtls.service.client import AgentClient, replay

TEAMS: dict[str, list[tuple[str, str, dict[str, Any], int]]] = {
    "inderst_two_users": [("Rescuer A", "inderst_two_users", {"user": "A"}, 0),
                          ("Rescuer B", "inderst_two_users", {"user": "B"}, 1)],
    "inderst_multifloor": [("Rescuer 1", "inderst_multifloor", {}, 0),
                           ("Rescuer 2", "inderst_multifloor", {}, 1),
                           ("Robot 1", "inderst_multifloor", {}, 2)],
    "office": [("Rescuer A", "office_random_walk", {"duration_s": 300.0}, 0),
               ("Rescuer B", "office_random_walk", {"duration_s": 300.0}, 1)],
}
"""Simulated teams: name -> (agent name, scenario, options, seed); a name starting with
``Robot`` is a robot that reports odometry instead of an IMU."""

ROBOT_RATE_HZ = 10.0
ROBOT_DRIFT_M_PER_SQRT_S = 0.02
ROBOT_SIGMA_M = 0.3


@dataclass(frozen=True)
class TeamMember:
    """One simulated agent: its name, kind, session and tracker preset."""

    name: str
    kind: str
    session: Session
    preset: str = "default"


def robot_session(session: Session, *, seed: int) -> Session:
    """A robot driving the path of ``session``: odometry poses that drift as a random walk.

    The odometry is the robot's own sensor: the true path plus an accumulating error of
    ``ROBOT_DRIFT_M_PER_SQRT_S`` (a wheel-odometry drift), reported at ``ROBOT_RATE_HZ``.
    """
    truth = session.truth
    if truth is None:
        raise InputError("no ground truth", where="robot simulation",
                         expected="a simulated session (its path is the robot's route)")
    rng = np.random.default_rng(seed)
    t = np.arange(truth.t[0], truth.t[-1], 1.0 / ROBOT_RATE_HZ)
    xyz = truth.position_at(t)
    step = ROBOT_DRIFT_M_PER_SQRT_S * math.sqrt(1.0 / ROBOT_RATE_HZ)
    drift = np.cumsum(rng.normal(0.0, step, (len(t), 2)), axis=0)
    xyz[:, :2] += drift
    fixes = PositionFixes(t, xyz, np.full(len(t), ROBOT_SIGMA_M), has_z=True, name="odometry")
    return Session(meta=session.meta, fixes=fixes, landmarks=session.landmarks,
                   truth=session.truth)


def team(name: str) -> list[TeamMember]:
    """The simulated sessions of a team of :data:`TEAMS`."""
    from hrtls.sim.scenarios import run_scenario

    if name not in TEAMS:
        raise InputError(f"unknown mission {name!r}", where="hrtls mission simulate NAME",
                         expected="one of " + ", ".join(TEAMS))
    out = []
    for agent_name, scenario, options, seed in TEAMS[name]:
        session = run_scenario(scenario, seed=seed, **options).session
        if agent_name.startswith("Robot"):
            out.append(TeamMember(agent_name, "robot", robot_session(session, seed=seed)))
        else:
            out.append(TeamMember(agent_name, "rescuer", session))
    return out


def create_mission(commander: AgentClient, name: str, members: list[TeamMember]
                   ) -> tuple[int, list[tuple[TeamMember, int, str]]]:
    """Create the mission, its landmarks and agents; (mission id, [(member, agent id, token)])."""
    meta = members[0].session.meta
    body: dict[str, Any] = {"name": name, "floor_height_m": meta.floor_height_m}
    if meta.channel is not None:
        body["channel"] = meta.channel.model_dump()
    mission = commander.request("POST", "/missions", json=body)
    mid = int(mission["id"])
    seen: set[str] = set()
    for m in members:
        for lm in m.session.landmarks.values():
            if lm.id not in seen:
                seen.add(lm.id)
                commander.request("POST", f"/missions/{mid}/landmarks",
                                  json=lm.model_dump(mode="json", exclude_none=True))
    agents = []
    for m in members:
        sm = m.session.meta
        created = commander.request("POST", f"/missions/{mid}/agents", json={
            "name": m.name, "kind": m.kind, "preset": m.preset, "placement": sm.placement,
            "mounting_q_bd": None if sm.mounting_q_bd is None else list(sm.mounting_q_bd),
            "user": {"height_m": sm.user.height_m, "step_model": sm.user.step_model}})
        agents.append((m, int(created["agent"]["id"]), str(created["token"])))
    return mid, agents


def stream_agent(server: str, token: str, session: Session, *, speed: float,
                 on_batch: Callable[[int], None] | None = None,
                 t_offset_s: float | None = None) -> AgentClient:
    """Check in at the session's start pose and stream it live.

    The session's start is now, or its times are shifted by ``t_offset_s``.
    """
    client = AgentClient(server, token)
    who = client.whoami()
    offset = float(who["mission_t"]) - session.time_span()[0] if t_offset_s is None \
        else t_offset_s
    pose = (session.meta.start_pose.model_dump() if session.meta.start_pose is not None
            else {"x": 0.0, "y": 0.0})
    pose["t"] = (pose.get("t") or session.time_span()[0]) + offset
    client.checkin(pose)
    replay(client, session, speed=speed, t_offset_s=offset, on_batch=on_batch)
    return client


def stream_team(server: str, agents: list[tuple[TeamMember, int, str]], *, speed: float,
                on_batch: Callable[[str, int], None] | None = None,
                t_offset_s: float | None = None) -> list[AgentClient]:
    """Stream every agent in its own thread; the clients when all are done.

    ``t_offset_s``: one time shift for every agent (their common timeline kept), else each
    agent's start is now.
    """
    clients: list[AgentClient] = []
    errors: list[BaseException] = []

    def run(member: TeamMember, token: str) -> None:
        try:
            cb = None if on_batch is None else (lambda seq: on_batch(member.name, seq))
            clients.append(stream_agent(server, token, member.session, speed=speed,
                                        on_batch=cb, t_offset_s=t_offset_s))
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(m, tok), daemon=True) for m, _, tok in agents]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    if errors:
        raise errors[0]
    return clients


def export_mission(db_url: str, mission_id: int, out_dir: Path) -> list[Path]:
    """One session folder per agent (readable by ``hrtls track``) plus the service's results.

    ``mission.json`` makes the folder a mission folder (:mod:`hrtls.io.mission`, tracked offline
    by ``hrtls mission track``): it lists the agents that sent data (named by their name when
    that is unique and usable as a folder name, else ``agent-<id>``); what the service knew
    (id, time origin, georeference, channel, floor height, events, orders) is under
    ``"service"``. Sessions hold the landmarks of the mission's start; the versions written
    later are in ``landmark_updates.json``, each from its time on, as the live trackers had them.
    A mission with a declared sensor network gets ``network.json``: the node ids, each with the
    mission estimator's newest estimate under ``"service"``, and ``network_ranges.csv`` when its
    nodes sent ranges between themselves.
    """
    from sqlalchemy import select

    from hrtls.io.mission import LANDMARK_UPDATES_FILE, MISSION_FILE, mission_json
    from hrtls.io.session import write_session
    from hrtls.service.db import make_engine, session_factory
    from hrtls.service.events import event_dict, order_dict
    from hrtls.service.exporting import agent_session, estimates_csv
    from hrtls.service.landmark_versions import versions_of
    from hrtls.service.models import Agent, EventRow, Mission, OrderRow
    from hrtls.service.views import agent_out

    engine = make_engine(db_url)
    written = []
    try:
        with session_factory(engine)() as db:
            mission = db.get(Mission, mission_id)
            if mission is None:
                raise InputError(f"mission {mission_id} not found", where="hrtls mission export",
                                 expected="a mission id of this database (see GET /missions)")
            out_dir.mkdir(parents=True, exist_ok=True)
            agents = list(db.scalars(select(Agent).where(Agent.mission_id == mission_id)
                                     .order_by(Agent.id)))
            with_data: set[int] = set()
            for a in agents:
                folder = out_dir / f"agent-{a.id}"
                session = agent_session(db, mission, a)
                if session is not None:
                    write_session(session, folder, overwrite=True)
                    with_data.add(a.id)
                else:
                    folder.mkdir(parents=True, exist_ok=True)
                (folder / "service_estimates.csv").write_text(estimates_csv(db, a.id))
                (folder / "agent.json").write_text(
                    json.dumps(agent_out(a).model_dump(), indent=2))
                written.append(folder)
            events = [event_dict(r) for r in db.scalars(
                select(EventRow).where(EventRow.mission_id == mission_id).order_by(EventRow.id))]
            orders = [order_dict(r) for r in db.scalars(
                select(OrderRow).where(OrderRow.mission_id == mission_id).order_by(OrderRow.id))]
            service = {"id": mission.id, "name": mission.name, "t0_unix": mission.t0_unix,
                       "georeference": mission.georeference, "channel": mission.channel,
                       "floor_height_m": mission.floor_height_m, "events": events,
                       "orders": orders}
            _write_network(db, mission_id, out_dir)
            _, timed = versions_of(db, mission_id)
            if timed:
                (out_dir / LANDMARK_UPDATES_FILE).write_text(json.dumps(list(timed), indent=2))
            (out_dir / MISSION_FILE).write_text(mission_json(
                _entries(agents, with_data), name=mission.name, service=service,
                notes=[f"agent {a.name!r} (id {a.id}) sent no data" for a in agents
                       if a.id not in with_data]))
    finally:
        engine.dispose()
    return written


def _write_network(db: Any, mission_id: int, out_dir: Path) -> None:
    """``network.json`` and ``network_ranges.csv`` of a mission with a declared network.

    The ids, each with its estimate; the ranges between its nodes the service stored.
    """
    from hrtls.io.mission import (
        NETWORK_FILE,
        NetworkModel,
        NodeEntry,
        write_network_ranges,
    )
    from hrtls.service.mission_runner import network_nodes
    from hrtls.service.network_log import all_ranges

    nodes = network_nodes(db, mission_id)
    if nodes is None:
        return
    model = NetworkModel(nodes=[NodeEntry(id=n["id"], service={k: v for k, v in n.items()
                                                              if k != "id"}) for n in nodes])
    (out_dir / NETWORK_FILE).write_text(model.model_dump_json(indent=2, exclude_none=True)
                                        + "\n", encoding="utf-8")
    ranges = all_ranges(db, mission_id)
    if len(ranges):
        write_network_ranges(out_dir, ranges)


def _entries(agents: list[Any], with_data: set[int]) -> list[tuple[str, Any, str]]:
    """``mission.json`` entries (name, kind, folder) of the agents that sent data."""
    from hrtls.io.mission import is_folder_name

    names = [a.name for a in agents if a.id in with_data]
    out = []
    for a in agents:
        if a.id not in with_data:
            continue
        usable = names.count(a.name) == 1 and is_folder_name(a.name)
        out.append((a.name if usable else f"agent-{a.id}", a.kind, f"agent-{a.id}"))
    return out
