"""The raw input log's writer: one thread, group commit.

Every accepted batch is stored before it is acknowledged. With one transaction per request, N
agents mean N threads queueing for the database's write lock (SQLite has one writer) and N
commits per batch period. Here the request threads hand their rows to one writer thread, which
inserts everything that arrived meanwhile in one transaction (one executemany, no ORM objects)
and then answers each request.
A duplicate ``(agent_id, seq)`` in a group makes the writer retry that group row by row, so
one duplicate never fails its neighbours.
"""

from __future__ import annotations

import queue
import threading
from concurrent.futures import Future
from dataclasses import dataclass

from sqlalchemy import insert
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session as DbSession
from sqlalchemy.orm import sessionmaker

from hrtls.service.models import RawBatch


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


class RawLogWriter:
    """Stores raw batches for many request threads through one writer thread.

    :meth:`append` blocks until its row is committed: True when stored, False when the
    ``(agent_id, seq)`` was stored before; other database errors are raised in the caller.
    """

    def __init__(self, sessions: sessionmaker[DbSession], *, max_group: int = 512) -> None:
        self._sessions = sessions
        self._max_group = max_group
        self._queue: queue.Queue[tuple[RawRow, Future[bool]] | None] = queue.Queue()
        self._thread: threading.Thread | None = None

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

    def append(self, row: RawRow) -> bool:
        """Store ``row``; False when it is a duplicate."""
        if self._thread is None:
            return self._write_one(row)
        done: Future[bool] = Future()
        self._queue.put((row, done))
        return done.result()

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

    def _write_group(self, group: list[tuple[RawRow, Future[bool]]]) -> None:
        try:
            with self._sessions() as db, db.begin():
                db.execute(insert(RawBatch), [row.values() for row, _ in group])
        except IntegrityError:
            for row, done in group:
                try:
                    done.set_result(self._write_one(row))
                except Exception as exc:
                    done.set_exception(exc)
            return
        except Exception as exc:
            for _, done in group:
                done.set_exception(exc)
            return
        for _, done in group:
            done.set_result(True)

    def _write_one(self, row: RawRow) -> bool:
        try:
            with self._sessions() as db, db.begin():
                db.execute(insert(RawBatch), [row.values()])
        except IntegrityError:
            return False
        return True
