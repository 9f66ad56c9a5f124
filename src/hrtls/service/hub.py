"""Live deltas to the dashboards: collect changes from any thread, push them per mission."""

from __future__ import annotations

import asyncio
import threading
from dataclasses import dataclass, field
from typing import Any

KINDS = ("agents", "estimates", "events", "orders", "nodes")
QUEUE_MESSAGES = 256


@dataclass(eq=False)
class Subscriber:
    """One dashboard socket: its mission, floor filter and outgoing queue."""

    mission_id: int
    floor: int | None
    queue: asyncio.Queue[dict[str, Any]] = field(
        default_factory=lambda: asyncio.Queue(QUEUE_MESSAGES))
    overflowed: bool = False


def for_floor(delta: dict[str, Any], floor: int | None) -> dict[str, Any]:
    """``delta`` with estimates, events and trails limited to ``floor`` (agents all kept)."""
    if floor is None:
        return delta
    out = dict(delta)
    out["estimates"] = [e for e in delta.get("estimates", []) if e.get("floor") == floor]
    out["events"] = [e for e in delta.get("events", []) if e.get("floor") in (floor, None)]
    if "trails" in delta:
        out["trails"] = {k: [p for p in v if p.get("floor") == floor]
                         for k, v in delta["trails"].items()}
    return out


class Hub:
    """Changes collected from worker threads and routes, flushed as one delta per mission."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: dict[int, dict[str, dict[Any, dict[str, Any]]]] = {}
        self._subs: dict[int, set[Subscriber]] = {}

    def add(self, mission_id: int, kind: str, item: dict[str, Any]) -> None:
        """Queue a changed object for the next delta (the newest version per id wins)."""
        key = item.get("agent") if kind == "estimates" else item.get("id")
        with self._lock:
            self._pending.setdefault(mission_id, {k: {} for k in KINDS})[kind][key] = item

    def take(self) -> dict[int, dict[str, list[dict[str, Any]]]]:
        """Everything queued since the last call, per mission."""
        with self._lock:
            pending, self._pending = self._pending, {}
        return {m: {k: list(v.values()) for k, v in kinds.items()}
                for m, kinds in pending.items()}

    def subscribe(self, mission_id: int, floor: int | None) -> Subscriber:
        """A new subscriber of ``mission_id`` (call from the event loop)."""
        sub = Subscriber(mission_id, floor)
        self._subs.setdefault(mission_id, set()).add(sub)
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        """Remove a subscriber."""
        self._subs.get(sub.mission_id, set()).discard(sub)

    def subscribers(self, mission_id: int) -> int:
        """Number of sockets of a mission."""
        return len(self._subs.get(mission_id, ()))

    def publish(self, mission_id: int, delta: dict[str, Any]) -> None:
        """Send ``delta`` to every subscriber of the mission (event loop only).

        A subscriber whose queue is full is marked ``overflowed`` and closed by its socket
        task (the dashboard reconnects and receives a fresh snapshot).
        """
        for sub in list(self._subs.get(mission_id, ())):
            try:
                sub.queue.put_nowait(for_floor(delta, sub.floor))
            except asyncio.QueueFull:
                sub.overflowed = True
