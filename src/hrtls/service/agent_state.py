"""In-memory state of each agent the tracker host serves, and the host's tuning."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any

from hrtls.service.alarms import AgentAlarms
from hrtls.service.batches import Batch
from hrtls.service.seqbook import SeqBook


class Busy(Exception):
    """The agent's queue is full: answer 429 with ``retry_after_s``."""

    def __init__(self, retry_after_s: float) -> None:
        super().__init__(f"queue full, retry after {retry_after_s} s")
        self.retry_after_s = retry_after_s


@dataclass
class HostParams:
    """Tuning of the host (from :class:`hrtls.service.settings.Settings`)."""

    queue_batches: int = 64
    snapshot_every_s: float = 30.0
    backfill_wait_s: float = 2.0
    workers: int = 2


@dataclass
class AgentLive:
    """In-memory state of one agent."""

    agent_id: int
    mission_id: int
    t0_unix: float
    stale_after_s: float
    book: SeqBook
    tracked: bool
    assigned: SeqBook = field(default_factory=SeqBook)
    """Seqs the service numbered (positions of apps without seqs), minus ``ASSIGNED_SEQ_BASE``."""
    lock: threading.Lock = field(default_factory=threading.Lock)
    pending: list[Batch] = field(default_factory=list)
    opened: bool = False
    t_fed: float = -math.inf
    t_final: float = -math.inf
    t_snap: float = -math.inf
    backfill_from: float = math.inf
    backfill_since: float = 0.0
    rebuild_from: float = math.inf
    """A landmark version holds from here: re-run the tracker from the snapshot before it."""
    latest: dict[str, Any] | None = None
    sent_stale: bool | None = None
    dirty: bool = True
    last_receive_unix: float | None = None
    battery: float | None = None
    sockets: int = 0
    scheduled: bool = False
    busy: bool = False
    error: str | None = None
    sos: bool = False
    alarms: AgentAlarms | None = None
    replaying: bool = False

    def stale(self, now_unix: float) -> bool:
        """Stale while a gap is open or nothing arrived for ``stale_after_s``."""
        silent = (self.last_receive_unix is None
                  or now_unix - self.last_receive_unix > self.stale_after_s)
        return (self.book.gap_open or self.assigned.gap_open or self.backfill_from < math.inf
                or silent)

    def status(self, now_unix: float) -> dict[str, Any]:
        """The ``Agent.status`` object of the contract."""
        recent = (self.last_receive_unix is not None
                  and now_unix - self.last_receive_unix <= self.stale_after_s)
        return {"last_data_t": None if not math.isfinite(self.t_fed) else self.t_fed,
                "last_seq": None if self.book.highest < 0 else self.book.highest,
                "acked_through": None if self.book.through < 0 else self.book.through,
                "missing": self.book.missing(), "battery": self.battery,
                "connected": self.sockets > 0 or recent, "error": self.error}
