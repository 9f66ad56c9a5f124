"""Events: list and acknowledge."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query
from sqlalchemy import select

from hrtls.service.deps import Commander, DbDep, Reader, ServicesDep, mission_or_404
from hrtls.service.events import event_dict
from hrtls.service.models import EventRow

router = APIRouter(tags=["events"])


@router.get("/missions/{mission_id}/events")
def list_events(mission_id: int, who: Reader, db: DbDep,
                after: Annotated[int, Query(ge=0)] = 0, kind: str | None = None,
                agent: int | None = None, unacknowledged: bool = False,
                ) -> list[dict[str, Any]]:
    """Events of a mission, oldest first (at most 1000)."""
    mission_or_404(db, mission_id)
    q = select(EventRow).where(EventRow.mission_id == mission_id, EventRow.id > after)
    if kind is not None:
        q = q.where(EventRow.kind == kind)
    if agent is not None:
        q = q.where(EventRow.agent_id == agent)
    if unacknowledged:
        q = q.where(EventRow.acknowledged_at.is_(None))
    return [event_dict(r) for r in db.scalars(q.order_by(EventRow.id).limit(1000))]


@router.post("/missions/{mission_id}/events/{event_id}/ack")
def acknowledge(mission_id: int, event_id: int, who: Commander, db: DbDep,
                services: ServicesDep) -> dict[str, Any]:
    """Acknowledge an event (who and when); a second acknowledgement keeps the first."""
    mission = mission_or_404(db, mission_id)
    row = db.get(EventRow, event_id)
    if row is None or row.mission_id != mission_id:
        raise HTTPException(404, f"event {event_id} not found in mission {mission_id}")
    if row.acknowledged_at is None:
        row.acknowledged_by = who.label
        row.acknowledged_at = services.clock() - mission.t0_unix
        db.commit()
        services.hub.add(mission_id, "events", event_dict(row))
    return event_dict(row)
