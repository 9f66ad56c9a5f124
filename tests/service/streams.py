"""Simulated sessions and missions for the service tests."""

from __future__ import annotations

import functools
import math
from typing import Any

import httpx
import numpy as np

from hrtls.data import Session
from hrtls.pipeline import Tracker, preset
from hrtls.service.client import AgentClient, session_batches
from hrtls.sim.scenarios import run_scenario

API = "/api/v1"


@functools.cache
def office(duration_s: float = 40.0, seed: int = 3) -> Session:
    """A short office walk with beacons, tags and radio nodes (ground truth included)."""
    return run_scenario("office_random_walk", seed=seed, duration_s=duration_s).session


@functools.cache
def offline_rows(duration_s: float = 40.0, seed: int = 3) -> Any:
    """The offline trajectory of :func:`office` with the default preset."""
    return Tracker(preset("default")).run(office(duration_s, seed)).trajectory


def mission_for(commander: httpx.Client, session: Session, *,
                name: str = "Rescuer A") -> tuple[int, int, str]:
    """A mission with the session's channel and landmarks and one agent; (mission, agent, token)."""
    meta = session.meta
    body: dict[str, Any] = {"name": "sim", "floor_height_m": meta.floor_height_m}
    if meta.channel is not None:
        body["channel"] = meta.channel.model_dump()
    r = commander.post(f"{API}/missions", json=body)
    assert r.status_code == 201, r.text
    mid = r.json()["id"]
    for lm in session.landmarks.values():
        data = lm.model_dump(mode="json", exclude_none=True)
        r = commander.post(f"{API}/missions/{mid}/landmarks", json=data)
        assert r.status_code == 201, r.text
    user = {"height_m": meta.user.height_m, "step_model": meta.user.step_model}
    r = commander.post(f"{API}/missions/{mid}/agents", json={
        "name": name, "placement": meta.placement,
        "mounting_q_bd": None if meta.mounting_q_bd is None else list(meta.mounting_q_bd),
        "user": user})
    assert r.status_code == 201, r.text
    agent = r.json()
    return mid, agent["agent"]["id"], agent["token"]


def start_pose(session: Session) -> dict[str, Any]:
    assert session.meta.start_pose is not None
    return session.meta.start_pose.model_dump()


def stored(commander: httpx.Client, mission: int, agent: int) -> dict[str, np.ndarray]:
    rows = commander.get(f"{API}/missions/{mission}/estimates", params={"agent": agent}).json()
    return {"t": np.array([r["t"] for r in rows]),
            "xy": np.array([[r["x"], r["y"]] for r in rows]).reshape(-1, 2),
            "cov": np.array([r["cov_xy"] for r in rows]).reshape(-1, 2, 2)}


def stream_agents(url: str, agents: list[Any], offset: float, *, t_from: float = -math.inf,
                  t_to: float = math.inf,
                  first_seq: dict[int, int] | None = None) -> dict[int, int]:
    """Send each agent's batches ending in (t_from, t_to], agents interleaved by time.

    ``agents`` holds (simulated member, agent id, token); a first part (``first_seq`` None) checks
    every agent in at its start pose. Returns each agent's next seq, for the following part.
    """
    clients, batches = {}, []
    for m, aid, token in agents:
        c = AgentClient(url, token, first_seq=(first_seq or {}).get(aid, 0))
        if first_seq is None:
            pose = m.session.meta.start_pose.model_dump()
            pose["t"] = (pose.get("t") or m.session.time_span()[0]) + offset
            c.checkin(pose)
        clients[aid] = c
        batches += [(t, aid, b) for t, b in session_batches(m.session, t_offset_s=offset)
                    if t_from < t <= t_to]
    for _, aid, b in sorted(batches, key=lambda x: x[0]):
        clients[aid].submit(b)
    out = {}
    for aid, c in clients.items():
        assert c.flush(max_wait_s=30) and c.outbox == {}
        out[aid] = c.next_seq
        c.close()
    return out
