"""Routes of the contract not implemented yet: authorised, then 501."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException

from hrtls.service.deps import AgentCaller, Commander, Reader

router = APIRouter(tags=["planned"])


def _planned(what: str) -> HTTPException:
    return HTTPException(501, f"{what} is specified in docs/service-api.md but not "
                              "implemented yet")


@router.get("/missions/{mission_id}/events")
def events(mission_id: int, who: Reader) -> None:
    """Events (planned)."""
    raise _planned("events")


@router.post("/missions/{mission_id}/events/{event_id}/ack")
def ack(mission_id: int, event_id: int, who: Commander) -> None:
    """Acknowledge an event (planned)."""
    raise _planned("event acknowledgement")


@router.get("/missions/{mission_id}/orders")
def orders(mission_id: int, who: Reader) -> None:
    """Orders (planned)."""
    raise _planned("orders")


@router.post("/missions/{mission_id}/orders")
def create_orders(mission_id: int, who: Commander) -> None:
    """Send orders (planned)."""
    raise _planned("orders")


@router.get("/agent/orders")
def agent_orders(who: AgentCaller) -> None:
    """The agent's orders (planned)."""
    raise _planned("agent orders")


@router.post("/agent/orders/{order_id}/receipt")
def receipt(order_id: int, who: AgentCaller) -> None:
    """Delivery receipt (planned)."""
    raise _planned("receipts")
