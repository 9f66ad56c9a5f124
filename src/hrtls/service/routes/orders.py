"""Orders of the commander to agents, delivery and receipts (HTTP; the agent socket pushes)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Query
from pydantic import Field, model_validator
from sqlalchemy import select
from sqlalchemy.orm import Session

from hrtls.service.deps import (
    AgentCaller,
    Commander,
    DbDep,
    Reader,
    Services,
    ServicesDep,
    mission_or_404,
)
from hrtls.service.events import order_dict
from hrtls.service.models import Agent, Mission, OrderRow
from hrtls.service.schemas import Strict

router = APIRouter(tags=["orders"])

FINAL = ("done", "rejected")


class WaypointIn(Strict):
    """Where a robot should go (mission metres)."""

    x: float
    y: float
    floor: int = Field(ge=-20, le=300)


class OrderIn(Strict):
    """Body of ``POST /missions/{m}/orders``."""

    kind: Literal["evacuate", "checkin", "goto", "text"]
    agents: list[int] | None = Field(default=None, max_length=1000)
    floor: int | None = Field(default=None, ge=-20, le=300)
    text: str | None = Field(default=None, max_length=2000)
    waypoint: WaypointIn | None = None

    @model_validator(mode="after")
    def _needs(self) -> OrderIn:
        if self.kind == "goto" and self.waypoint is None:
            raise ValueError("a goto order needs a waypoint {x, y, floor}")
        if self.kind == "text" and not self.text:
            raise ValueError("a text order needs text")
        return self


class ReceiptIn(Strict):
    """Body of ``POST /agent/orders/{id}/receipt``."""

    status: Literal["delivered", "accepted", "done", "rejected"]
    text: str | None = Field(default=None, max_length=2000)


def _addressed(db: Session, services: Services, mission_id: int, body: OrderIn) -> list[int]:
    ids = list(db.scalars(select(Agent.id).where(Agent.mission_id == mission_id)
                          .order_by(Agent.id)))
    if body.agents is not None:
        unknown = sorted(set(body.agents) - set(ids))
        if unknown:
            raise HTTPException(404, f"agents {unknown} not in mission {mission_id}")
        return sorted(set(body.agents))
    if body.floor is not None:
        out = []
        for aid in ids:
            live = services.host.agent(aid)
            if live is not None and live.latest is not None and live.latest["floor"] == body.floor:
                out.append(aid)
        return out
    return ids


@router.post("/missions/{mission_id}/orders", status_code=201)
def create_orders(mission_id: int, body: OrderIn, who: Commander, db: DbDep,
                  services: ServicesDep) -> list[dict[str, Any]]:
    """One order per addressed agent (agents, else floor, else everyone)."""
    mission = mission_or_404(db, mission_id)
    now_t = services.clock() - mission.t0_unix
    rows = [OrderRow(mission_id=mission_id, agent_id=aid, kind=body.kind, text=body.text,
                     waypoint=None if body.waypoint is None else body.waypoint.model_dump(),
                     created_by=who.label, created_at=now_t, status="pending")
            for aid in _addressed(db, services, mission_id, body)]
    db.add_all(rows)
    db.commit()
    out = [order_dict(r) for r in rows]
    for o in out:
        services.hub.add(mission_id, "orders", o)
        services.order_versions[o["agent"]] = services.order_versions.get(o["agent"], 0) + 1
    return out


@router.get("/missions/{mission_id}/orders")
def list_orders(mission_id: int, who: Reader, db: DbDep, agent: int | None = None,
                status: str | None = None) -> list[dict[str, Any]]:
    """Orders of a mission, oldest first (at most 1000)."""
    mission_or_404(db, mission_id)
    q = select(OrderRow).where(OrderRow.mission_id == mission_id)
    if agent is not None:
        q = q.where(OrderRow.agent_id == agent)
    if status is not None:
        q = q.where(OrderRow.status == status)
    return [order_dict(r) for r in db.scalars(q.order_by(OrderRow.id).limit(1000))]


def deliver(services: Services, agent_id: int, after: int) -> list[dict[str, Any]]:
    """The agent's orders with id > ``after``; pending ones become delivered (pushed)."""
    with services.sessions() as db, db.begin():
        rows = list(db.scalars(select(OrderRow).where(OrderRow.agent_id == agent_id,
                                                      OrderRow.id > after)
                               .order_by(OrderRow.id)))
        if not rows:
            return []
        mission = db.get(Mission, rows[0].mission_id)
        now_t = services.clock() - (0.0 if mission is None else mission.t0_unix)
        for r in rows:
            if r.status == "pending":
                r.status = "delivered"
                r.delivered_at = now_t
        out = [order_dict(r) for r in rows]
    for o in out:
        services.hub.add(o["mission"], "orders", o)
    return out


def answer(services: Services, agent_id: int, order_id: int, body: ReceiptIn) -> dict[str, Any]:
    """Record the agent's receipt of its order."""
    with services.sessions() as db, db.begin():
        row = db.get(OrderRow, order_id)
        if row is None or row.agent_id != agent_id:
            raise HTTPException(404, f"order {order_id} not found for this agent")
        if row.status in FINAL:
            raise HTTPException(409, f"order {order_id} is {row.status} already")
        mission = db.get(Mission, row.mission_id)
        now_t = services.clock() - (0.0 if mission is None else mission.t0_unix)
        if row.delivered_at is None:
            row.delivered_at = now_t
        row.status = body.status
        row.answered_at = now_t
        row.answer_text = body.text
        out = order_dict(row)
    services.hub.add(out["mission"], "orders", out)
    return out


@router.get("/agent/orders")
def agent_orders(who: AgentCaller, services: ServicesDep,
                 after: Annotated[int, Query(ge=0)] = 0) -> list[dict[str, Any]]:
    """The calling agent's orders after ``after`` (polling)."""
    assert who.agent_id is not None
    return deliver(services, who.agent_id, after)


@router.post("/agent/orders/{order_id}/receipt")
def receipt(order_id: int, body: ReceiptIn, who: AgentCaller,
            services: ServicesDep) -> dict[str, Any]:
    """Delivery receipt / answer of the calling agent."""
    assert who.agent_id is not None
    return answer(services, who.agent_id, order_id, body)
