"""The mission picture: latest estimates, trails, agents; live (snapshot) or at a past time."""

from __future__ import annotations

import math
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from hrtls.service.estimate_rows import row_dict
from hrtls.service.events import event_dict, order_dict
from hrtls.service.host import TrackerHost
from hrtls.service.hub import for_floor
from hrtls.service.models import Agent, EstimateRow, EventRow, Mission, OrderRow
from hrtls.service.views import agent_out

TRAIL_SPACING_S = 0.5


def agent_json(row: Agent, host: TrackerHost | None, now_unix: float) -> dict[str, Any]:
    """An agent with its live status when the host has it."""
    out = agent_out(row).model_dump()
    live = None if host is None else host.agent(row.id)
    if live is not None:
        out["status"] = live.status(now_unix)
    return out


def thin(points: list[dict[str, Any]], spacing_s: float) -> list[dict[str, Any]]:
    """At most one point per ``spacing_s`` (the first of each spell), last point kept."""
    out: list[dict[str, Any]] = []
    for p in points:
        if not out or p["t"] - out[-1]["t"] >= spacing_s:
            out.append(p)
    if points and out[-1] is not points[-1]:
        out.append(points[-1])
    return out


def evenly(points: list[dict[str, Any]], max_points: int) -> list[dict[str, Any]]:
    """At most ``max_points`` points evenly spread over ``points`` (first and last kept)."""
    n = len(points)
    if n <= max_points:
        return points
    if max_points == 1:
        return [points[-1]]
    step = (n - 1) / (max_points - 1)
    return [points[round(i * step)] for i in range(max_points)]


def trail_point(r: EstimateRow) -> dict[str, Any]:
    """A trail point: time, position, floor and the 1-sigma radius of the worst axis."""
    tr, det = r.cxx + r.cyy, r.cxx * r.cyy - r.cxy * r.cxy
    lam = 0.5 * tr + math.sqrt(max(0.0, 0.25 * tr * tr - det))
    return {"t": r.t, "x": r.x, "y": r.y, "z": r.z, "floor": r.floor,
            "sigma_m": math.sqrt(max(0.0, lam))}


def trail(db: Session, agent_id: int, t_from: float, t_to: float) -> list[dict[str, Any]]:
    """Stored estimates of an agent with ``t_from <= t <= t_to`` as trail points."""
    rows = db.scalars(select(EstimateRow).where(
        EstimateRow.agent_id == agent_id, EstimateRow.t >= t_from, EstimateRow.t <= t_to)
        .order_by(EstimateRow.t))
    return [trail_point(r) for r in rows]


def latest_row(db: Session, agent_id: int, t_max: float) -> EstimateRow | None:
    """The newest stored estimate of an agent at or before ``t_max``."""
    return db.scalars(select(EstimateRow).where(EstimateRow.agent_id == agent_id,
                                                EstimateRow.t <= t_max)
                      .order_by(EstimateRow.t.desc()).limit(1)).first()


def events_at(db: Session, mission_id: int, t: float | None) -> list[dict[str, Any]]:
    """Open (unacknowledged or uncleared) events plus the last 100; as they were at ``t``."""
    q = select(EventRow).where(EventRow.mission_id == mission_id)
    if t is not None:
        q = q.where(EventRow.t <= t)
    rows = list(db.scalars(q.order_by(EventRow.id)))
    last = {r.id for r in rows[-100:]}
    out = []
    for r in rows:
        e = event_dict(r)
        if t is not None:
            if e["acknowledged_at"] is not None and e["acknowledged_at"] > t:
                e["acknowledged_at"] = e["acknowledged_by"] = None
            if e["cleared_t"] is not None and e["cleared_t"] > t:
                e["cleared_t"] = None
        if r.id in last or e["acknowledged_at"] is None or e["cleared_t"] is None:
            out.append(e)
    return out


def orders_at(db: Session, mission_id: int, t: float | None) -> list[dict[str, Any]]:
    """The last 200 orders (created at or before ``t``)."""
    q = select(OrderRow).where(OrderRow.mission_id == mission_id)
    if t is not None:
        q = q.where(OrderRow.created_at <= t)
    rows = list(db.scalars(q.order_by(OrderRow.id.desc()).limit(200)))
    return [order_dict(r) for r in reversed(rows)]


def picture(db: Session, mission: Mission, *, host: TrackerHost | None, now_unix: float,
            t: float | None, floor: int | None, trail_s: float) -> dict[str, Any]:
    """``snapshot`` (``t`` None: live, host estimates) or ``replay`` (stored rows up to ``t``)."""
    agents = list(db.scalars(select(Agent).where(Agent.mission_id == mission.id)
                             .order_by(Agent.id)))
    t_now = now_unix - mission.t0_unix
    t_pic = t_now if t is None else t
    estimates: list[dict[str, Any]] = []
    trails: dict[str, list[dict[str, Any]]] = {}
    for a in agents:
        est = None
        if t is None and host is not None:
            live = host.agent(a.id)
            if live is not None and live.latest is not None:
                est = {**live.latest, "stale": live.stale(now_unix)}
        if est is None:
            row = latest_row(db, a.id, t_pic)
            if row is not None:
                est = row_dict(row)
                if t is None:
                    est["stale"] = True
        if est is not None:
            estimates.append(est)
        end = t_pic if est is None else max(t_pic, est["t"])
        trails[str(a.id)] = thin(trail(db, a.id, t_pic - trail_s, end), TRAIL_SPACING_S)
    out = {"mission": mission.id, "t": t_pic,
           "agents": [agent_json(a, host if t is None else None, now_unix) for a in agents],
           "estimates": estimates, "events": events_at(db, mission.id, t),
           "orders": orders_at(db, mission.id, t), "trails": trails}
    return for_floor(out, floor)
