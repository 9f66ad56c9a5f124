"""The agent side: number, buffer and send batches; stream a recorded session live.

:class:`AgentClient` keeps every batch until the service acknowledges it. During a radio gap
the batches stay in its outbox; when the link is back it sends the newest batch first (so the
commander sees the present) and then back-fills the rest oldest first. Resending is always
safe: the service acknowledges a ``seq`` it already has as a duplicate.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import msgpack

from hrtls.data import Session
from hrtls.pipeline.chunks import split_session
from hrtls.service.batches import from_chunk

Sleep = Callable[[float], None]


class ServiceError(RuntimeError):
    """The service refused a request for good (not a gap, not back-pressure)."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(f"HTTP {status}: {detail}")
        self.status = status
        self.detail = detail


@dataclass
class SendStats:
    """What the client did."""

    sent: int = 0
    acked: int = 0
    duplicates: int = 0
    retries_429: int = 0
    gaps: int = 0
    order: list[int] = field(default_factory=list)


FORMATS = ("msgpack", "msgpack-rows", "json")
"""Batch formats of the client: msgpack with numeric columns as binary column blocks (the
default, cheapest for the service), msgpack with lists, JSON (lists)."""


def encode(batch: dict[str, Any], fmt: str) -> tuple[bytes, str]:
    """Body and content type of a batch."""
    if fmt in ("msgpack", "msgpack-rows"):
        return msgpack.packb(batch), "application/msgpack"
    return json.dumps(batch).encode(), "application/json"


class AgentClient:
    """One agent's connection to the service over HTTP POST (``/api/v1/ingest``)."""

    def __init__(self, server: str, token: str, *, fmt: str = "msgpack", timeout_s: float = 30.0,
                 first_seq: int = 0, sleep: Sleep = time.sleep,
                 transport: httpx.BaseTransport | None = None) -> None:
        if fmt not in FORMATS:
            raise ValueError(f"fmt {fmt!r}: one of {', '.join(FORMATS)}")
        self.fmt = fmt
        self.blocks = fmt == "msgpack"
        """Whether :func:`replay` sends numeric columns as column blocks."""
        self.http = httpx.Client(base_url=server.rstrip("/"), timeout=timeout_s,
                                 headers={"Authorization": f"Bearer {token}"},
                                 transport=transport)
        self.next_seq = first_seq
        self.outbox: dict[int, bytes] = {}
        self.stats = SendStats()
        self._sleep = sleep
        self._in_gap = False
        self._content_type = encode({}, fmt)[1]

    def close(self) -> None:
        """Close the HTTP connection."""
        self.http.close()

    def __enter__(self) -> AgentClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ API
    def request(self, method: str, path: str, **kwargs: Any) -> Any:
        """A JSON API call; :class:`ServiceError` on refusal."""
        r = self.http.request(method, "/api/v1" + path, **kwargs)
        if r.status_code >= 400:
            raise ServiceError(r.status_code, _detail(r))
        return r.json() if r.content else None

    def whoami(self) -> dict[str, Any]:
        """The agent and mission this token belongs to."""
        return dict(self.request("GET", "/auth/whoami"))

    def checkin(self, pose: dict[str, Any]) -> dict[str, Any]:
        """Check in at a known start pose (mission time ``t``)."""
        who = self.whoami()
        return dict(self.request("POST", f"/missions/{who['mission']}/agents/{who['agent']}"
                                         "/checkin", json=pose))

    # ------------------------------------------------------------------ sending
    def submit(self, batch: dict[str, Any]) -> int:
        """Number ``batch`` (its ``seq`` is set here), buffer it and try to send; its seq."""
        seq = self.next_seq
        self.next_seq += 1
        body, _ = encode({**batch, "seq": seq}, self.fmt)
        self.outbox[seq] = body
        self.flush()
        return seq

    def flush(self, *, max_wait_s: float = 30.0) -> bool:
        """Send what is buffered (newest first after a gap); True when the outbox is empty."""
        if not self.outbox:
            return True
        seqs = sorted(self.outbox)
        if self._in_gap and len(seqs) > 1:
            seqs = [seqs[-1], *seqs[:-1]]
        waited = 0.0
        for seq in seqs:
            while True:
                outcome = self._post(seq)
                if outcome == "ok":
                    break
                if outcome == "gap":
                    if not self._in_gap:
                        self.stats.gaps += 1
                    self._in_gap = True
                    return False
                wait = float(outcome)
                if waited + wait > max_wait_s:
                    return False
                self.stats.retries_429 += 1
                self._sleep(wait)
                waited += wait
        self._in_gap = False
        return not self.outbox

    def _post(self, seq: int) -> str:
        try:
            r = self.http.post("/api/v1/ingest", content=self.outbox[seq],
                               headers={"Content-Type": self._content_type})
        except httpx.TransportError:
            return "gap"
        self.stats.sent += 1
        self.stats.order.append(seq)
        if r.status_code == 429:
            return r.headers.get("retry-after", "1")
        if r.status_code >= 500:
            return "gap"
        if r.status_code >= 400:
            raise ServiceError(r.status_code, f"batch {seq}: {_detail(r)}")
        ack = r.json()
        self.stats.acked += 1
        if ack.get("status") == "duplicate":
            self.stats.duplicates += 1
        del self.outbox[seq]
        return "ok"


def _detail(r: httpx.Response) -> str:
    try:
        return str(r.json().get("detail", r.text))
    except ValueError:
        return r.text


def session_batches(session: Session, *, chunk_s: float = 0.5, t_offset_s: float = 0.0,
                    blocks: bool = False) -> Iterator[tuple[float, dict[str, Any]]]:
    """``(t_end, batch)`` per ``chunk_s`` window of a session, times shifted by ``t_offset_s``.

    ``blocks``: numeric columns as binary column blocks (msgpack only).
    """
    for chunk in split_session(session, chunk_s):
        batch = from_chunk(chunk, seq=0, t_offset_s=t_offset_s, blocks=blocks)
        del batch["seq"]
        yield _chunk_end(chunk) + t_offset_s, batch


def _chunk_end(chunk: Session) -> float:
    """Last sample time of a chunk's sensors and observations (not its ground truth)."""
    ends = [float(p.t[-1]) for p in (chunk.pressure, chunk.fixes, chunk.rss, chunk.tags,
                                     chunk.ranges) if p is not None and len(p.t)]
    if chunk.imu is not None:
        ends.append(float(chunk.imu.accel.t[-1]))
    return max(ends)


def replay(client: AgentClient, session: Session, *, speed: float, t_offset_s: float,
           chunk_s: float = 0.5, clock: Callable[[], float] = time.monotonic,
           sleep: Sleep = time.sleep, on_batch: Callable[[int], None] | None = None) -> None:
    """Stream ``session`` as a live agent: each chunk when its last sample is due.

    ``speed`` is the replay factor (1 = real time, 10 = ten times faster, ``inf`` = as fast as
    the service acknowledges).
    """
    start_wall = clock()
    t_start = None
    for t_end, batch in session_batches(session, chunk_s=chunk_s, t_offset_s=t_offset_s,
                                        blocks=client.blocks):
        if t_start is None:
            t_start = t_end - chunk_s
        if speed != float("inf"):
            due = start_wall + (t_end - t_start) / speed
            delay = due - clock()
            if delay > 0:
                sleep(delay)
        seq = client.submit(batch)
        if on_batch is not None:
            on_batch(seq)
    client.flush()
