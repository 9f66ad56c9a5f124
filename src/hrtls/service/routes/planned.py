"""Routes of the contract not implemented yet: authorised, then 501."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException

from hrtls.service.deps import AgentCaller, Commander, Reader

router = APIRouter(tags=["planned"])


def _planned(what: str) -> HTTPException:
    return HTTPException(501, f"{what} is specified in docs/service-api.md but not "
                              "implemented yet")


@router.get("/missions/{mission_id}/snapshot")
def snapshot(mission_id: int, who: Reader) -> None:
    """Live picture (planned)."""
    raise _planned("the mission snapshot")


@router.get("/missions/{mission_id}/estimates")
def estimates(mission_id: int, who: Reader) -> None:
    """Published estimates (planned)."""
    raise _planned("estimates")


@router.get("/missions/{mission_id}/agents/{agent_id}/trail")
def trail(mission_id: int, agent_id: int, who: Reader) -> None:
    """Trail of one agent (planned)."""
    raise _planned("trails")


@router.get("/missions/{mission_id}/replay")
def replay(mission_id: int, who: Reader) -> None:
    """Picture at a past time (planned)."""
    raise _planned("replay")


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


@router.post("/ingest")
def ingest(who: AgentCaller) -> None:
    """Batch ingest (planned)."""
    raise _planned("ingest")
