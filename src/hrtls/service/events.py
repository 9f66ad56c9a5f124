"""Stored events: raise (store + push), clear, acknowledge; the contract's Event and Order."""

from __future__ import annotations

import threading
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from hrtls.service.alarms import Raised, zones_of
from hrtls.service.clock import Clock
from hrtls.service.hub import Hub
from hrtls.service.models import EventRow, Floor, Mission, OrderRow


def event_dict(r: EventRow) -> dict[str, Any]:
    """An event as the contract's Event."""
    return {"id": r.id, "mission": r.mission_id, "agent": r.agent_id, "kind": r.kind,
            "severity": r.severity, "t": r.t, "x": r.x, "y": r.y, "floor": r.floor,
            "detail": r.detail, "cleared_t": r.cleared_t, "acknowledged_by": r.acknowledged_by,
            "acknowledged_at": r.acknowledged_at}


def order_dict(r: OrderRow) -> dict[str, Any]:
    """An order as the contract's Order."""
    return {"id": r.id, "mission": r.mission_id, "agent": r.agent_id, "kind": r.kind,
            "text": r.text, "waypoint": r.waypoint, "created_by": r.created_by,
            "created_at": r.created_at, "status": r.status, "delivered_at": r.delivered_at,
            "answered_at": r.answered_at, "answer_text": r.answer_text}


class EventLog:
    """Stores raised events, closes cleared ones, pushes both to the hub."""

    def __init__(self, sessions: sessionmaker[Session], hub: Hub, clock: Clock) -> None:
        self.sessions = sessions
        self.hub = hub
        self.clock = clock
        self._zones: dict[int, list[tuple[str, int, Any]]] = {}
        self._lock = threading.Lock()

    def zones(self, mission_id: int) -> list[tuple[str, int, Any]]:
        """The zones of a mission's floor plans (cached until :meth:`plans_changed`)."""
        with self._lock:
            if mission_id in self._zones:
                return self._zones[mission_id]
        with self.sessions() as db:
            floors = [(f.index, f.plan) for f in db.scalars(
                select(Floor).where(Floor.mission_id == mission_id))]
        zones = zones_of(floors)
        with self._lock:
            self._zones[mission_id] = zones
        return zones

    def plans_changed(self, mission_id: int) -> None:
        """Forget the cached zones of a mission."""
        with self._lock:
            self._zones.pop(mission_id, None)

    def emit(self, mission_id: int, agent_id: int | None, raised: list[Raised],
             where: dict[str, Any] | None) -> list[dict[str, Any]]:
        """Store new events / clear open ones; the changed events (also pushed)."""
        if not raised:
            return []
        changed = []
        with self.sessions() as db, db.begin():
            for r in raised:
                if r.clears is not None:
                    row = db.scalars(select(EventRow).where(
                        EventRow.agent_id == agent_id, EventRow.kind == r.clears,
                        EventRow.cleared_t.is_(None)).order_by(EventRow.id.desc())).first()
                    if row is None:
                        continue
                    row.cleared_t = r.t
                else:
                    row = EventRow(mission_id=mission_id, agent_id=agent_id, kind=r.kind,
                                   severity=r.severity, t=r.t, detail=r.detail,
                                   x=None if where is None else where["x"],
                                   y=None if where is None else where["y"],
                                   floor=None if where is None else where["floor"])
                    db.add(row)
                db.flush()
                changed.append(event_dict(row))
        for e in changed:
            self.hub.add(mission_id, "events", e)
        return changed

    def mission_t(self, mission_id: int) -> float:
        """Mission time now."""
        with self.sessions() as db:
            m = db.get(Mission, mission_id)
        return self.clock() - (0.0 if m is None else m.t0_unix)
