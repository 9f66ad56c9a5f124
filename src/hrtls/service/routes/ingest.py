"""Ingest: numbered batches of an agent over HTTP POST and WebSocket (JSON or msgpack)."""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
from collections.abc import MutableMapping
from typing import Annotated, Any

import msgpack
from fastapi import APIRouter, HTTPException, Query, Request, WebSocket, WebSocketDisconnect
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from hrtls.service.adapters import sensorlogger_batch
from hrtls.service.batches import BatchError, decode_body, parse_batch, validation_errors
from hrtls.service.deps import UNAUTHORIZED, AgentCaller, Services, ServicesDep, bearer_secret
from hrtls.service.host import Busy
from hrtls.service.limits import retry_after_header
from hrtls.service.routes.live import authenticate, decode_ws
from hrtls.service.routes.orders import ReceiptIn, answer, deliver
from hrtls.service.security import Principal

router = APIRouter(tags=["ingest"])


def check_rate(services: Services, who: Principal) -> None:
    """429 when the agent exceeds its request rate."""
    wait = services.agent_rate.take(who.agent_id)
    if wait > 0:
        raise HTTPException(429, f"agent {who.agent_id} exceeds "
                                 f"{services.settings.rate_per_agent_hz:g} requests/s",
                            headers=retry_after_header(wait))


async def store(services: Services, who: Principal, value: dict[str, Any], *, body: bytes,
                content_type: str) -> dict[str, Any]:
    """Validate and accept one batch of the calling agent; the ack once the raw log has it."""
    assert who.agent_id is not None
    batch = parse_batch(value)
    try:
        return await services.host.accept_async(who.agent_id, batch, body=body,
                                                content_type=content_type, source="batch")
    except KeyError:
        raise HTTPException(404, f"agent {who.agent_id} no longer exists") from None


def _refused(exc: BatchError | Busy, who: Principal) -> JSONResponse:
    """The HTTP answer to a refused batch: its status, or 429 and Retry-After when busy."""
    if isinstance(exc, Busy):
        return JSONResponse({"detail": f"agent {who.agent_id}: {exc}"}, status_code=429,
                            headers=retry_after_header(exc.retry_after_s))
    return JSONResponse({"detail": exc.detail}, status_code=exc.status)


@router.post("/ingest")
async def ingest(request: Request, who: AgentCaller, services: ServicesDep) -> JSONResponse:
    """Accept one batch of the calling agent (idempotent per ``seq``)."""
    check_rate(services, who)
    content_type = request.headers.get("content-type", "")
    body = await request.body()
    try:
        value = decode_body(body, content_type)
        ack = await store(services, who, value, body=body,
                          content_type=content_type.split(";")[0].strip())
    except (BatchError, Busy) as exc:
        return _refused(exc, who)
    return JSONResponse(ack)


@router.websocket("/ingest/ws")
async def ingest_socket(ws: WebSocket) -> None:
    """An agent's socket: batches in, acks (and orders) out."""
    services: Services = ws.app.state.services
    who = await authenticate(ws, services, ("agent",))
    if who is None or who.agent_id is None:
        return
    live = await run_in_threadpool(services.host.agent, who.agent_id)
    if live is None:
        await ws.close(4404, "agent not found")
        return
    live.sockets += 1
    send_lock = asyncio.Lock()

    async def send(obj: dict[str, Any]) -> None:
        async with send_lock:
            await ws.send_json(obj)

    pusher = asyncio.create_task(_push_orders(send, services, who.agent_id))
    try:
        while True:
            message = await ws.receive()
            if message.get("type") == "websocket.disconnect":
                break
            msg = decode_ws(message)
            if msg is None:
                await send({"type": "error", "status": 400,
                                    "detail": "frame is neither a JSON nor a msgpack object"})
                continue
            kind = msg.get("type")
            if kind == "ping":
                await send({"type": "pong", "t": services.mission_time(live.mission_id)})
                continue
            if kind == "receipt":
                await send(await _receipt(services, who, msg))
                continue
            if kind != "batch" or not isinstance(msg.get("batch"), dict):
                await send({"type": "error", "status": 422,
                            "detail": "expected {type: batch, batch: {...}}, receipt or ping"})
                continue
            await send(await _ws_batch(services, who, msg["batch"], message))
    except WebSocketDisconnect:
        pass
    finally:
        live.sockets -= 1
        pusher.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await pusher


async def _ws_batch(services: Services, who: Principal, value: dict[str, Any],
                    message: MutableMapping[str, Any]) -> dict[str, Any]:
    seq = value.get("seq")
    wait = services.agent_rate.take(who.agent_id)
    if wait > 0:
        return {"type": "error", "seq": seq, "status": 429, "retry_after_s": wait,
                "detail": "rate limit"}
    binary = message.get("bytes") is not None
    body = msgpack.packb(value) if binary else json.dumps(value).encode()
    try:
        ack = await store(services, who, value, body=body,
                          content_type="application/msgpack" if binary else "application/json")
    except BatchError as exc:
        return {"type": "error", "seq": seq, "status": exc.status, "detail": exc.detail}
    except Busy as exc:
        return {"type": "error", "seq": seq, "status": 429, "retry_after_s": exc.retry_after_s,
                "detail": str(exc)}
    except HTTPException as exc:
        return {"type": "error", "seq": seq, "status": exc.status_code, "detail": exc.detail}
    return {"type": "ack", **ack}


async def _receipt(services: Services, who: Principal, msg: dict[str, Any]) -> dict[str, Any]:
    assert who.agent_id is not None
    order_id = msg.get("order")
    try:
        body = ReceiptIn.model_validate({k: v for k, v in msg.items()
                                         if k not in ("type", "order")})
        if not isinstance(order_id, int):
            raise HTTPException(422, "receipt needs an integer 'order'")
        await run_in_threadpool(answer, services, who.agent_id, order_id, body)
    except ValidationError as exc:
        return {"type": "error", "order": order_id, "status": 422,
                "detail": validation_errors(exc)}
    except HTTPException as exc:
        return {"type": "error", "order": order_id, "status": exc.status_code,
                "detail": exc.detail}
    return {"type": "receipt_ack", "order": order_id}


ORDER_POLL_S = 0.25


async def _push_orders(send: Any, services: Services, agent_id: int) -> None:
    """Send the agent's open orders on connect, then each new one (marked delivered)."""
    last_id, seen = 0, None
    while True:
        version = services.order_versions.get(agent_id, 0)
        if version != seen:
            seen = version
            orders = await run_in_threadpool(deliver, services, agent_id, last_id)
            for o in orders:
                last_id = max(last_id, o["id"])
                if o["answered_at"] is None:
                    await send({"type": "order", "order": o})
        await asyncio.sleep(ORDER_POLL_S)


def _basic_password(authorization: str | None) -> str | None:
    """The password of an ``Authorization: Basic ...`` header value."""
    scheme, _, value = (authorization or "").partition(" ")
    if scheme.lower() != "basic":
        return None
    try:
        _, sep, password = base64.b64decode(value.strip(), validate=True).decode().partition(":")
    except (ValueError, UnicodeDecodeError):
        return None
    return password if sep and password else None


async def app_agent(request: Request, services: Services, token: str | None) -> Principal:
    """The agent of a phone app's request: Bearer header, Basic-auth password or ``?token=``.

    Apps that can only set a URL put the token in the query (it then shows in proxy logs).
    """
    header = request.headers.get("authorization")
    secret = bearer_secret(header) or _basic_password(header) or token
    who = None if secret is None else await services.authenticate(secret)
    if who is None:
        raise HTTPException(401, "token unknown, revoked or expired (Bearer, Basic password "
                                 "or ?token=)", headers=UNAUTHORIZED)
    if who.role != "agent" or who.agent_id is None or who.mission_id is None:
        raise HTTPException(403, f"role {who.role!r} may not do this (needs agent)")
    return who


@router.post("/ingest/sensorlogger")
async def sensorlogger(request: Request, services: ServicesDep,
                       token: Annotated[str | None, Query(max_length=200)] = None
                       ) -> JSONResponse:
    """Sensor Logger's HTTP push (the app cannot set headers: the token may be a query)."""
    who = await app_agent(request, services, token)
    assert who.agent_id is not None and who.mission_id is not None
    check_rate(services, who)
    body = await request.body()
    t0 = services.mission_t0(who.mission_id)
    try:
        value = decode_body(body, "application/json")
        batch = await run_in_threadpool(sensorlogger_batch, value, t0_unix=t0)
        ack = await run_in_threadpool(
            services.host.accept, who.agent_id, batch, body=body,
            content_type=f"application/json; t0_unix={t0!r}", source="sensorlogger")
    except (BatchError, Busy) as exc:
        return _refused(exc, who)
    return JSONResponse(ack)
