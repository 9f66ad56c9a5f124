"""Ingest of phone tracking apps' positions: OsmAnd (Traccar Client) and OwnTracks HTTP mode.

Both become GNSS fixes of the calling agent (:mod:`hrtls.service.positions`). The service
numbers the batches: per agent, one position at a time is checked against the stored ones
(same device time and coordinates: a duplicate, acknowledged again), numbered and stored.
"""

from __future__ import annotations

import json
import threading
from typing import Annotated, Any
from urllib.parse import parse_qsl

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse
from sqlalchemy import select

from hrtls.service import positions as pos
from hrtls.service.batches import BatchError
from hrtls.service.deps import Services, ServicesDep
from hrtls.service.host import Busy
from hrtls.service.limits import retry_after_header
from hrtls.service.models import Mission, RawBatch
from hrtls.service.routes.ingest import app_agent, check_rate
from hrtls.service.security import Principal

router = APIRouter(tags=["ingest"])

MAX_MESSAGE_BYTES = 16 * 1024
"""A position message is a few hundred bytes; larger ones are refused (413)."""

_locks: dict[int, threading.Lock] = {}
_locks_guard = threading.Lock()


def _agent_lock(agent_id: int) -> threading.Lock:
    with _locks_guard:
        return _locks.setdefault(agent_id, threading.Lock())


def _mission_frame(services: Services, mission_id: int) -> tuple[float, dict[str, Any]]:
    """The mission's ``t0_unix`` and georeference (409 without one)."""
    with services.sessions() as db:
        mission = db.get(Mission, mission_id)
    if mission is None:
        raise HTTPException(404, f"mission {mission_id} no longer exists")
    if mission.georeference is None:
        raise HTTPException(409, f"mission {mission_id} has no georeference: GNSS positions "
                                 "cannot be placed in its frame (a commander sets it with "
                                 f"PATCH /api/v1/missions/{mission_id} {{\"georeference\": "
                                 "{\"lat_deg\", \"lon_deg\"}})")
    return mission.t0_unix, dict(mission.georeference)


def _stored_twin(services: Services, agent_id: int, t: float,
                 position: pos.Position) -> int | None:
    """The seq of a stored position at the same device time: None, or 409 if it differs."""
    with services.sessions() as db:
        rows = db.execute(select(RawBatch.seq, RawBatch.body).where(
            RawBatch.agent_id == agent_id, RawBatch.source.in_(pos.SOURCES),
            RawBatch.t_first == t)).all()
    for row in rows:
        if pos.same_position(row.body, position):
            return int(row.seq)
    if rows:
        raise HTTPException(409, f"a different position at the same device time "
                                 f"{pos.iso_time(position.time_unix)} is stored already "
                                 f"(seq {rows[0].seq})")
    return None


def accept_position(services: Services, who: Principal, protocol: str, text: str,
                    parsed: pos.Parsed) -> dict[str, Any]:
    """Number, store and queue one position of the calling agent; the ack."""
    assert who.agent_id is not None and who.mission_id is not None
    ignored = {"ignored_fields": list(parsed.ignored_fields)} if parsed.ignored_fields else {}
    if parsed.position is None:
        return {"status": "ignored", "reason": parsed.ignored_reason, **ignored}
    position = parsed.position
    t0, georeference = _mission_frame(services, who.mission_id)
    now = services.clock()
    if position.time_unix > now + pos.PARAMS.max_future_s:
        raise BatchError(422, f"time {pos.iso_time(position.time_unix)} is more than "
                              f"{pos.PARAMS.max_future_s:g} s ahead of the server clock "
                              f"({pos.iso_time(now)}): check the phone's clock")
    if position.time_unix < t0:
        return {"status": "ignored", **ignored,
                "reason": f"time {pos.iso_time(position.time_unix)} is before the mission "
                          f"started ({pos.iso_time(t0)})"}
    t = position.time_unix - t0
    source = pos.PROTOCOLS[protocol]
    with _agent_lock(who.agent_id):
        twin = _stored_twin(services, who.agent_id, t, position)
        if twin is not None:
            return {**services.host.duplicate_ack(who.agent_id, twin), **ignored}
        while True:   # another service process on the same database may take a seq first
            seq = services.host.next_assigned_seq(who.agent_id)
            batch = pos.fix_batch(position, seq=seq, t0_unix=t0, georeference=georeference)
            body = pos.envelope(protocol, text, seq=seq, t0_unix=t0, georeference=georeference)
            ack = services.host.accept(who.agent_id, batch, body=body,
                                       content_type=pos.ENVELOPE_TYPE, source=source,
                                       assigned=True)
            if ack["status"] == "accepted":
                assert batch.fixes is not None
                return {**ack, "t": t, "x": batch.fixes.x[0], "y": batch.fixes.y[0], **ignored}


async def _ingest(request: Request, services: Services, token: str | None, protocol: str,
                  text: str) -> dict[str, Any]:
    """Authorise, parse and accept one message (errors as HTTPException)."""
    who = await app_agent(request, services, token)
    check_rate(services, who)
    try:
        parsed = pos.parse(protocol, text)
        return await run_in_threadpool(accept_position, services, who, protocol, text, parsed)
    except BatchError as exc:
        raise HTTPException(exc.status, exc.detail) from None
    except Busy as exc:
        raise HTTPException(429, f"agent {who.agent_id}: {exc}",
                            headers=retry_after_header(exc.retry_after_s)) from None
    except KeyError:
        raise HTTPException(404, f"agent {who.agent_id} no longer exists") from None


async def _body_text(request: Request) -> str:
    body = await request.body()
    if len(body) > MAX_MESSAGE_BYTES:
        raise HTTPException(413, f"position message of {len(body)} bytes; at most "
                                 f"{MAX_MESSAGE_BYTES}")
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError:
        raise HTTPException(400, "body is not UTF-8 text") from None


Token = Annotated[str | None, Query(max_length=200)]


@router.api_route("/ingest/osmand", methods=["GET", "POST"])
async def osmand(request: Request, services: ServicesDep, token: Token = None) -> JSONResponse:
    """OsmAnd protocol (Traccar Client): query or form parameters, or its JSON body."""
    query = request.url.query
    if len(query) > MAX_MESSAGE_BYTES:
        raise HTTPException(413, f"query of {len(query)} bytes; at most {MAX_MESSAGE_BYTES}")
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    text = await _body_text(request) if request.method == "POST" else ""
    if text.strip() and (kind == "application/json"
                         or (kind == "" and text.lstrip().startswith("{"))):
        ack = await _ingest(request, services, token, "osmand-json", text)
        return JSONResponse(ack)
    if text.strip() and kind not in ("application/x-www-form-urlencoded", ""):
        raise HTTPException(415, f"Content-Type {kind!r}: send query parameters, a form "
                                 "(application/x-www-form-urlencoded) or application/json")
    pairs = parse_qsl(query, keep_blank_values=True) + parse_qsl(text, keep_blank_values=True)
    ack = await _ingest(request, services, token, "osmand-query", pos.query_text(pairs))
    return JSONResponse(ack)


@router.post("/ingest/owntracks")
async def owntracks(request: Request, services: ServicesDep,
                    token: Token = None) -> JSONResponse:
    """OwnTracks HTTP mode: one message per POST; answers ``[]`` (no messages for the app).

    The ack travels in the ``X-Hrtls-Ack`` header (JSON), since the body must be a list.
    """
    text = await _body_text(request)
    ack = await _ingest(request, services, token, "owntracks", text)
    return JSONResponse([], headers={"X-Hrtls-Ack": json.dumps(ack)})
