"""Read side: snapshot, estimates, trails, replay, and the dashboards' WebSocket."""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import MutableMapping
from typing import Annotated, Any

import msgpack
from fastapi import APIRouter, Query, WebSocket, WebSocketDisconnect
from fastapi.concurrency import run_in_threadpool
from sqlalchemy import select

from hrtls.service.deps import (
    DbDep,
    Reader,
    Services,
    ServicesDep,
    agent_or_404,
    bearer_secret,
    mission_or_404,
)
from hrtls.service.estimate_rows import row_dict
from hrtls.service.models import EstimateRow, Mission
from hrtls.service.picture import evenly, trail
from hrtls.service.security import COOKIE_NAME, Principal, Role

router = APIRouter(tags=["live"])

TrailS = Annotated[float, Query(gt=0.0, le=86400.0)]
Floor = Annotated[int | None, Query(ge=-20, le=300)]


@router.get("/missions/{mission_id}/snapshot")
def snapshot(mission_id: int, who: Reader, db: DbDep, services: ServicesDep,
             floor: Floor = None, trail_s: TrailS = 300.0) -> dict[str, Any]:
    """The live picture: agents, latest estimates, events, orders, trails."""
    mission = mission_or_404(db, mission_id)
    return services.picture(db, mission, t=None, floor=floor, trail_s=trail_s)


@router.get("/missions/{mission_id}/replay")
def replay(mission_id: int, who: Reader, db: DbDep, services: ServicesDep,
           t: Annotated[float, Query(allow_inf_nan=False)],
           floor: Floor = None, trail_s: TrailS = 300.0) -> dict[str, Any]:
    """The picture as it was at mission time ``t``."""
    mission = mission_or_404(db, mission_id)
    return services.picture(db, mission, t=t, floor=floor, trail_s=trail_s)


@router.get("/missions/{mission_id}/estimates")
def estimates(mission_id: int, who: Reader, db: DbDep,
              agent: int | None = None,
              t_from: Annotated[float | None, Query(alias="from", allow_inf_nan=False)] = None,
              t_to: Annotated[float | None, Query(alias="to", allow_inf_nan=False)] = None,
              ) -> list[dict[str, Any]]:
    """Stored estimates, oldest first (at most 10000)."""
    mission_or_404(db, mission_id)
    q = select(EstimateRow).where(EstimateRow.mission_id == mission_id)
    if agent is not None:
        q = q.where(EstimateRow.agent_id == agent)
    if t_from is not None:
        q = q.where(EstimateRow.t >= t_from)
    if t_to is not None:
        q = q.where(EstimateRow.t <= t_to)
    return [row_dict(r) for r in db.scalars(q.order_by(EstimateRow.t, EstimateRow.agent_id)
                                            .limit(10000))]


@router.get("/missions/{mission_id}/agents/{agent_id}/trail")
def agent_trail(mission_id: int, agent_id: int, who: Reader, db: DbDep,
                t_from: Annotated[float, Query(alias="from", allow_inf_nan=False)] = -1e12,
                t_to: Annotated[float, Query(alias="to", allow_inf_nan=False)] = 1e12,
                max_points: Annotated[int, Query(ge=1, le=100000)] = 2000,
                ) -> list[dict[str, Any]]:
    """The agent's stored estimates as a trail, thinned evenly to ``max_points``."""
    agent_or_404(db, mission_id, agent_id)
    return evenly(trail(db, agent_id, t_from, t_to), max_points)


# ---------------------------------------------------------------------------- sockets
def decode_ws(message: MutableMapping[str, Any]) -> dict[str, Any] | None:
    """A received text (JSON) or binary (msgpack) frame as an object, None if neither."""
    try:
        if message.get("text") is not None:
            value = json.loads(message["text"], parse_constant=_no_constant)
        elif message.get("bytes") is not None:
            value = msgpack.unpackb(message["bytes"], raw=False)
        else:
            return None
    except Exception:
        return None
    return value if isinstance(value, dict) else None


def _no_constant(name: str) -> None:
    raise ValueError(name)


def _same_origin(ws: WebSocket, services: Services) -> bool:
    origin = ws.headers.get("origin")
    if origin is None:
        return True
    host = ws.headers.get("host", "")
    return origin.split("://", 1)[-1] == host or origin in services.settings.cors_origins


async def authenticate(ws: WebSocket, services: Services,
                       roles: tuple[Role, ...]) -> Principal | None:
    """Accept the socket and authenticate it (header, cookie or first message); None = closed."""
    await ws.accept()
    secret = bearer_secret(ws.headers.get("authorization"))
    if secret is None and ws.cookies.get(COOKIE_NAME):
        if not _same_origin(ws, services):
            await ws.close(4403, "cross-origin socket with a session cookie")
            return None
        secret = ws.cookies.get(COOKIE_NAME)
    if secret is None:
        try:
            first = await asyncio.wait_for(ws.receive(),
                                           timeout=services.settings.ws_auth_timeout_s)
        except TimeoutError:
            await ws.close(4408, "no auth message in time")
            return None
        if first.get("type") == "websocket.disconnect":
            return None
        msg = decode_ws(first)
        if msg is None or msg.get("type") != "auth" or not isinstance(msg.get("token"), str):
            await ws.close(4401, "first message must be {type: auth, token}")
            return None
        secret = msg["token"]
    who = await services.authenticate(secret)
    if who is None:
        await ws.close(4401, "token unknown, revoked or expired")
        return None
    if who.role not in roles:
        await ws.close(4403, f"role {who.role!r} may not open this socket")
        return None
    return who


def _mission_picture(services: Services, mission_id: int,
                     floor: int | None) -> dict[str, Any] | None:
    with services.sessions() as db:
        mission = db.get(Mission, mission_id)
        if mission is None:
            return None
        return services.picture(db, mission, t=None, floor=floor, trail_s=300.0)


@router.websocket("/missions/{mission_id}/ws")
async def mission_socket(ws: WebSocket, mission_id: int, floor: int | None = None) -> None:
    """Live deltas of one mission (docs/service-api.md, "Live WebSocket")."""
    services: Services = ws.app.state.services
    who = await authenticate(ws, services, ("commander", "viewer"))
    if who is None:
        return
    pic = await run_in_threadpool(_mission_picture, services, mission_id, floor)
    if pic is None:
        await ws.close(4404, f"mission {mission_id} not found")
        return
    hub = services.hub
    sub = hub.subscribe(mission_id, floor)
    try:
        await ws.send_json({"type": "hello", "role": who.role, "mission": mission_id,
                            "t": pic["t"]})
        await ws.send_json({"type": "snapshot", **pic})
        sender = asyncio.create_task(_send_loop(ws, sub))
        try:
            while True:
                message = await ws.receive()
                if message.get("type") == "websocket.disconnect":
                    break
                msg = decode_ws(message)
                if msg is None:
                    continue
                if msg.get("type") == "ping":
                    await ws.send_json({"type": "pong", "t": services.mission_time(mission_id)})
                elif msg.get("type") == "subscribe":
                    f = msg.get("floor")
                    sub.floor = f if isinstance(f, int) else None
                    pic = await run_in_threadpool(_mission_picture, services, mission_id,
                                                  sub.floor)
                    await ws.send_json({"type": "snapshot", **(pic or {})})
        finally:
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
    except WebSocketDisconnect:
        pass
    finally:
        hub.unsubscribe(sub)


async def _send_loop(ws: WebSocket, sub: Any) -> None:
    while True:
        delta = await sub.queue.get()
        if sub.overflowed:
            await ws.close(1013, "too slow: reconnect for a fresh snapshot")
            return
        await ws.send_json(delta)

