"""The database writer: one thread, group commit of the raw log and of the derived rows.

Every accepted batch is stored before it is acknowledged. With one transaction per request, N
agents mean N threads queueing for the database's write lock (SQLite has one writer) and N
commits per batch period. Here the request threads hand their rows to one writer thread, which
inserts everything that arrived meanwhile in one transaction (one executemany, no ORM objects)
and then answers each request.
A duplicate ``(agent_id, seq)`` in a group makes the writer retry that group row by row, so
one duplicate never fails its neighbours.

The trackers' derived rows (estimates, snapshots) ride in the same groups as *deferred writes*:
functions of a session run in the order they were handed in, in the transaction of their group
(or a later one), so a snapshot is never committed before the estimates that precede it. A
derived write may still be lost by a crash; the restart rebuilds it from the newest committed
snapshot and the raw log.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from sqlalchemy import insert
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session as DbSession
from sqlalchemy.orm import sessionmaker

from hrtls.service.models import RawBatch

log = logging.getLogger(__name__)

Write = Callable[[DbSession], None]
"""A deferred write: statements run in the writer's open transaction."""


@dataclass(frozen=True, slots=True)
class RawRow:
    """One batch as received (the columns of :class:`~hrtls.service.models.RawBatch`)."""

    agent_id: int
    seq: int
    received_unix: float
    t_first: float | None
    t_last: float | None
    source: str
    content_type: str
    body: bytes

    def values(self) -> dict[str, object]:
        """The column values of this batch."""
        return {"agent_id": self.agent_id, "seq": self.seq, "received_unix": self.received_unix,
                "t_first": self.t_first, "t_last": self.t_last, "source": self.source,
                "content_type": self.content_type, "body": self.body}


_Item = tuple[RawRow | Write, "Future[Any]"]
"""A raw row (answered True/False) or a deferred write (answered None), and its future."""


class RawLogWriter:
    """Stores raw batches and deferred writes of many threads through one writer thread.

    :meth:`submit` hands a row in and returns at once; its future is True when stored, False
    when the ``(agent_id, seq)`` was stored before, or holds the database error.
    :meth:`append` waits for that answer.
    """

    def __init__(self, sessions: sessionmaker[DbSession], *, max_group: int = 512) -> None:
        self._sessions = sessions
        self._max_group = max_group
        self._queue: queue.Queue[_Item | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._unwritten = 0

    def start(self) -> None:
        """Start the writer thread (idempotent)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="hrtls-rawlog", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        """Write what is queued, then stop the thread."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join(timeout=60)
            self._thread = None
        while True:  # rows handed in while the thread was stopping
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return
            if item is not None:
                self._write_group([item])

    def submit(self, row: RawRow) -> Future[bool]:
        """Hand ``row`` to the writer; the future answers False for a duplicate."""
        done: Future[bool] = Future()
        self._put((row, done))
        return done

    def append(self, row: RawRow) -> bool:
        """Store ``row``; False when it is a duplicate."""
        return self.submit(row).result()

    def defer(self, write: Write) -> Future[None]:
        """Run ``write`` in a coming group transaction, after everything handed in before."""
        done: Future[None] = Future()
        self._put((write, done))
        return done

    def flush(self) -> None:
        """Wait until everything handed in so far is committed."""
        self.defer(lambda db: None).result()

    def unwritten(self) -> int:
        """Rows and writes handed in and not yet committed (or failed)."""
        with self._lock:
            return self._unwritten

    def _put(self, item: _Item) -> None:
        with self._lock:
            self._unwritten += 1
        if self._thread is None:
            self._write_group([item])
        else:
            self._queue.put(item)

    # ------------------------------------------------------------------ writer thread
    def _run(self) -> None:
        while True:
            first = self._queue.get()
            if first is None:
                return
            group = [first]
            stop = False
            while len(group) < self._max_group:
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    break
                if item is None:
                    stop = True
                    break
                group.append(item)
            self._write_group(group)
            if stop:
                return

    def _write_group(self, group: list[_Item]) -> None:
        try:
            self._commit(group)
        except Exception:
            for item in group:   # alone, so that one failure does not fail its neighbours
                try:
                    self._commit([item])
                except IntegrityError as exc:
                    self._answer(item, False if isinstance(item[0], RawRow) else exc)
                except Exception as exc:
                    self._answer(item, exc)
                else:
                    self._answer(item, True)
        else:
            for item in group:
                self._answer(item, True)
        finally:
            with self._lock:
                self._unwritten -= len(group)

    def _commit(self, group: list[_Item]) -> None:
        """One transaction: the items in order, consecutive raw rows in one executemany."""
        with self._sessions() as db, db.begin():
            rows: list[dict[str, object]] = []
            for what, _ in group:
                if isinstance(what, RawRow):
                    rows.append(what.values())
                    continue
                if rows:
                    db.execute(insert(RawBatch), rows)
                    rows = []
                what(db)
            if rows:
                db.execute(insert(RawBatch), rows)

    @staticmethod
    def _answer(item: _Item, result: bool | Exception) -> None:
        what, done = item
        if isinstance(result, Exception):
            if not isinstance(what, RawRow):
                log.error("deferred database write failed: %s", result)
            done.set_exception(result)
        else:
            done.set_result(result if isinstance(what, RawRow) else None)
