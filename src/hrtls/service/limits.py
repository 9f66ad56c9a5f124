"""Request size limit (ASGI middleware) and per-agent rate limits (token buckets)."""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass, field
from typing import Any

from hrtls.service.clock import Clock

ASGIApp = Any


class BodyLimit:
    """Refuse HTTP bodies larger than ``max_bytes`` with 413 (declared or streamed)."""

    def __init__(self, app: ASGIApp, *, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        """Pass the request on, or answer 413 once the body is too large."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        for name, value in scope.get("headers", []):
            if name == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    await _too_large(send, "Content-Length is not a number", status=400)
                    return
                if declared > self.max_bytes:
                    await _too_large(send, f"request body of {declared} bytes exceeds the "
                                           f"limit of {self.max_bytes} bytes")
                    return
        seen = 0
        answered = False

        async def limited_receive() -> dict[str, Any]:
            nonlocal seen, answered
            if answered:
                return {"type": "http.disconnect"}
            message: dict[str, Any] = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_bytes:
                    answered = True
                    await _too_large(send, f"request body exceeds the limit of "
                                           f"{self.max_bytes} bytes")
                    return {"type": "http.disconnect"}
            return message

        async def guarded_send(message: dict[str, Any]) -> None:
            if not answered:
                await send(message)

        await self.app(scope, limited_receive, guarded_send)


async def _too_large(send: Any, detail: str, *, status: int = 413) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


@dataclass
class _Bucket:
    tokens: float
    t: float


@dataclass
class RateLimiter:
    """Token buckets per key: ``rate_hz`` sustained, ``burst`` at once."""

    rate_hz: float
    burst: float
    clock: Clock
    _buckets: dict[Any, _Bucket] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self, key: Any) -> float:
        """0 when allowed (one token taken), else the seconds to wait for the next token."""
        now = self.clock()
        with self._lock:
            b = self._buckets.get(key)
            if b is None:
                b = self._buckets[key] = _Bucket(self.burst, now)
            b.tokens = min(self.burst, b.tokens + max(0.0, now - b.t) * self.rate_hz)
            b.t = now
            if b.tokens >= 1.0:
                b.tokens -= 1.0
                return 0.0
            return (1.0 - b.tokens) / self.rate_hz


def retry_after_header(wait_s: float) -> dict[str, str]:
    """``Retry-After`` in whole seconds (at least 1)."""
    return {"Retry-After": str(max(1, math.ceil(wait_s)))}
