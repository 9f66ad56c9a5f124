"""The tracker host: accepts an agent's batches, feeds its tracker in time order, stores rows.

Every accepted batch is first committed to the raw log (so an ack is never lost), then queued.
Worker threads feed each agent's queue to its tracker through a :class:`TrackerRunner`. A batch
older than what the tracker has consumed (back-fill after a radio gap) triggers a re-run: the
newest snapshot before it is restored and the raw log is replayed from there in time order; the
re-run waits while a sequence gap is still open (up to ``backfill_wait_s``). After a restart the
same re-run restores every agent from its newest snapshot.
"""

from __future__ import annotations

import asyncio
import logging
import math
import queue
import threading
from collections.abc import Callable
from typing import Any

from sqlalchemy import delete, insert, select
from sqlalchemy.orm import Session as DbSession
from sqlalchemy.orm import sessionmaker

from hrtls.data.session import SessionMeta
from hrtls.service.adapters import decode_sensorlogger
from hrtls.service.agent_state import AgentLive, Busy, HostParams
from hrtls.service.alarms import AgentAlarms, AlarmProfile
from hrtls.service.batches import Batch, BatchError, decode_body, parse_batch
from hrtls.service.clock import Clock
from hrtls.service.estimate_rows import estimate_dict, rows_to_db
from hrtls.service.events import EventLog
from hrtls.service.landmark_versions import versions_of
from hrtls.service.models import Agent, EstimateRow, Mission, RawBatch, TrackerSnapshot
from hrtls.service.positions import SOURCES as POSITION_SOURCES
from hrtls.service.positions import decode_position
from hrtls.service.rawlog import RawLogWriter, RawRow
from hrtls.service.runner import AgentSpec, FeedFailed, Rows, StaleSnapshot, TrackerRunner
from hrtls.service.seqbook import ASSIGNED_SEQ_BASE, SeqBook

log = logging.getLogger(__name__)

Decoder = Callable[[bytes, str], Batch]


def decode_batch(body: bytes, content_type: str) -> Batch:
    """The hrtls batch in a JSON or msgpack body."""
    return parse_batch(decode_body(body, content_type))


DECODERS: dict[str, Decoder] = {"batch": decode_batch, "sensorlogger": decode_sensorlogger,
                                 **dict.fromkeys(POSITION_SOURCES, decode_position)}
"""Raw-log ``source`` -> how its stored bodies become batches (replay, export)."""

REPLAY_PAGE = 200
FEED_MANY_MAX = 128
"""Agents a worker takes from the queue and feeds in one runner call."""
KEEP_SNAPSHOTS = 20
GOLDEN_FRACTION = (math.sqrt(5.0) - 1.0) / 2.0


class TrackerHost:
    """Per-agent queues, worker threads and the runner that holds the trackers."""

    def __init__(self, *, sessions: sessionmaker[DbSession], clock: Clock,
                 runner: TrackerRunner, params: HostParams, events: EventLog) -> None:
        self.sessions = sessions
        self.events = events
        self.clock = clock
        self.runner = runner
        self.params = params
        self._agents: dict[int, AgentLive] = {}
        self._lock = threading.Lock()
        self._work: queue.Queue[int | None] = queue.Queue()
        self._threads: list[threading.Thread] = []
        self.raw_log = RawLogWriter(sessions)

    # ------------------------------------------------------------------ life cycle
    def start(self) -> None:
        """Start the workers and schedule every agent with stored data (restore)."""
        self.raw_log.start()
        for i in range(self.params.workers):
            th = threading.Thread(target=self._worker, name=f"hrtls-tracker-{i}", daemon=True)
            th.start()
            self._threads.append(th)
        with self.sessions() as db:
            ids = list(db.scalars(select(RawBatch.agent_id).distinct()))
        for agent_id in ids:
            live = self.agent(agent_id)
            if live is not None:
                self._schedule(live)

    def stop(self) -> None:
        """Stop the workers (queued work is dropped; it is in the raw log)."""
        for _ in self._threads:
            self._work.put(None)
        for th in self._threads:
            th.join(timeout=30)
        self._threads.clear()
        self.raw_log.stop()

    def idle(self) -> bool:
        """Whether no agent has queued or running work (for tests and benchmarks)."""
        with self._lock:
            agents = list(self._agents.values())
        return all(not a.pending and not a.busy and not a.scheduled
                   and a.backfill_from == math.inf for a in agents) \
            and self.raw_log.unwritten() == 0

    # ------------------------------------------------------------------ agents
    def agent(self, agent_id: int) -> AgentLive | None:
        """The live state of an agent (loaded from the database the first time)."""
        with self._lock:
            live = self._agents.get(agent_id)
        if live is not None:
            return live
        with self.sessions() as db:
            row = db.get(Agent, agent_id)
            if row is None:
                return None
            mission = db.get(Mission, row.mission_id)
            assert mission is not None
            book, assigned = SeqBook(), SeqBook()
            for seq in db.scalars(select(RawBatch.seq).where(RawBatch.agent_id == agent_id)):
                if seq >= ASSIGNED_SEQ_BASE:
                    assigned.add(seq - ASSIGNED_SEQ_BASE)
                else:
                    book.add(seq)
            last = db.scalars(select(RawBatch.received_unix).where(
                RawBatch.agent_id == agent_id).order_by(RawBatch.id.desc())).first()
            live = AgentLive(agent_id, row.mission_id, mission.t0_unix, mission.stale_after_s,
                             book, row.start_pose is not None, assigned=assigned,
                             last_receive_unix=last,
                             alarms=AgentAlarms(AlarmProfile(**mission.alarm_profile)))
        with self._lock:
            return self._agents.setdefault(agent_id, live)

    def agents_of(self, mission_id: int) -> list[AgentLive]:
        """The loaded agents of a mission."""
        with self._lock:
            return [a for a in self._agents.values() if a.mission_id == mission_id]

    def checked_in(self, agent_id: int) -> None:
        """The agent's start pose is set: track everything stored so far."""
        live = self.agent(agent_id)
        if live is None:
            return
        with live.lock:
            live.tracked = True
            live.opened = False
        self._schedule(live)

    def mission_changed(self, mission_id: int) -> None:
        """Stale-time or floor height changed: reload the agents' settings lazily."""
        with self.sessions() as db:
            mission = db.get(Mission, mission_id)
        if mission is None:
            return
        for live in self.agents_of(mission_id):
            live.stale_after_s = mission.stale_after_s
            if live.alarms is not None:
                live.alarms.profile = AlarmProfile(**mission.alarm_profile)

    def landmarks_changed(self, mission_id: int, t: float | None) -> None:
        """A landmark version holds from mission time ``t`` (None: the start).

        Every loaded agent of the mission re-runs from its snapshot before ``t`` (its later
        snapshots lack the version), in its worker, as a back-fill does.
        """
        t_from = -math.inf if t is None else t
        for live in self.agents_of(mission_id):
            with live.lock:
                live.rebuild_from = min(live.rebuild_from, t_from)
                self._schedule_locked(live)

    # ------------------------------------------------------------------ ingest
    def accept(self, agent_id: int, batch: Batch, *, body: bytes, content_type: str,
               source: str, assigned: bool = False) -> dict[str, Any]:
        """Store ``batch`` in the raw log and queue it; the ack (idempotent).

        ``assigned``: the service numbered the batch (:meth:`next_assigned_seq`); client seqs
        are below ``ASSIGNED_SEQ_BASE``, so both kinds of source can feed one agent.
        """
        live = self.agent(agent_id)
        if live is None:
            raise KeyError(agent_id)
        admitted = self._admit(live, batch, body=body, content_type=content_type,
                               source=source, assigned=assigned)
        if isinstance(admitted, dict):
            return admitted
        return self._accepted(live, batch, admitted, self.raw_log.append(admitted),
                              assigned=assigned)

    async def accept_async(self, agent_id: int, batch: Batch, *, body: bytes,
                           content_type: str, source: str) -> dict[str, Any]:
        """:meth:`accept` for the event loop: waits for the raw log without holding a thread."""
        live = self._agents.get(agent_id)
        if live is None:
            live = await asyncio.to_thread(self.agent, agent_id)
        if live is None:
            raise KeyError(agent_id)
        admitted = self._admit(live, batch, body=body, content_type=content_type,
                               source=source, assigned=False)
        if isinstance(admitted, dict):
            return admitted
        stored = await asyncio.wrap_future(self.raw_log.submit(admitted))
        return self._accepted(live, batch, admitted, stored, assigned=False)

    def _admit(self, live: AgentLive, batch: Batch, *, body: bytes, content_type: str,
               source: str, assigned: bool) -> RawRow | dict[str, Any]:
        """The raw row to store, or the ack of a duplicate (:class:`Busy`: queue full)."""
        if (batch.seq >= ASSIGNED_SEQ_BASE) != assigned:
            raise BatchError(422, f"seq must be below {ASSIGNED_SEQ_BASE} (higher seqs are "
                                  "numbered by the service)")
        book, key = self._book(live, batch.seq)
        with live.lock:
            if key in book:
                return self._ack(live, batch.seq, "duplicate")
            if len(live.pending) >= self.params.queue_batches:
                raise Busy(1.0)
        span = batch.time_span()
        return RawRow(agent_id=live.agent_id, seq=batch.seq, received_unix=self.clock(),
                      t_first=None if span is None else span[0],
                      t_last=None if span is None else span[1],
                      source=source, content_type=content_type, body=body)

    def _accepted(self, live: AgentLive, batch: Batch, row: RawRow, stored: bool, *,
                  assigned: bool) -> dict[str, Any]:
        """Queue a batch the raw log has stored (``stored`` False: it had it already)."""
        book, key = self._book(live, batch.seq)
        with live.lock:
            book.add(key)
            if not stored:
                return self._ack(live, batch.seq, "duplicate")
            live.last_receive_unix = row.received_unix
            if batch.status is not None and batch.status.battery is not None:
                live.battery = batch.status.battery
            if batch.sos:
                live.sos = True
            live.pending.append(batch)
            live.dirty = True
            ack = self._ack(live, batch.seq, "accepted")
        self._schedule(live)
        return ack

    @staticmethod
    def _book(live: AgentLive, seq: int) -> tuple[SeqBook, int]:
        """The seq book a seq is kept in and its key there."""
        if seq >= ASSIGNED_SEQ_BASE:
            return live.assigned, seq - ASSIGNED_SEQ_BASE
        return live.book, seq

    def duplicate_ack(self, agent_id: int, seq: int) -> dict[str, Any]:
        """The ack of a batch stored before as ``seq``."""
        live = self.agent(agent_id)
        if live is None:
            raise KeyError(agent_id)
        with live.lock:
            return self._ack(live, seq, "duplicate")

    def next_assigned_seq(self, agent_id: int) -> int:
        """The next seq the service numbers a batch of ``agent_id`` with (callers serialise)."""
        live = self.agent(agent_id)
        if live is None:
            raise KeyError(agent_id)
        with live.lock:
            return ASSIGNED_SEQ_BASE + live.assigned.highest + 1

    @staticmethod
    def _ack(live: AgentLive, seq: int, status: str) -> dict[str, Any]:
        if seq >= ASSIGNED_SEQ_BASE:
            return {"seq": seq, "status": status,
                    "acked_through": ASSIGNED_SEQ_BASE + live.assigned.through,
                    "missing": [[ASSIGNED_SEQ_BASE + a, ASSIGNED_SEQ_BASE + b]
                                for a, b in live.assigned.missing()]}
        return {"seq": seq, "status": status, "acked_through": live.book.through,
                "missing": live.book.missing()}

    # ------------------------------------------------------------------ publishing
    def take_changes(self) -> list[tuple[AgentLive, dict[str, Any] | None]]:
        """Agents whose estimate or status changed since the last call, with the estimate."""
        now = self.clock()
        with self._lock:
            agents = list(self._agents.values())
        out = []
        for live in agents:
            self._judge_silence(live, now)
            with live.lock:
                stale = live.stale(now)
                if live.backfill_from < math.inf and not live.busy and not live.scheduled \
                        and now - live.backfill_since >= self.params.backfill_wait_s:
                    self._schedule_locked(live)
                if not live.dirty and stale == live.sent_stale:
                    continue
                live.dirty = False
                live.sent_stale = stale
                est = None if live.latest is None else {**live.latest, "stale": stale}
                out.append((live, est))
        return out

    def _judge_silence(self, live: AgentLive, now: float) -> None:
        if live.alarms is None or live.last_receive_unix is None:
            return
        silent = now - live.last_receive_unix
        quiet = silent if silent >= live.alarms.profile.silent_s else None
        raised = live.alarms.on_silence(now - live.t0_unix, quiet)
        self.events.emit(live.mission_id, live.agent_id, raised, live.latest)

    # ------------------------------------------------------------------ work
    def _schedule(self, live: AgentLive) -> None:
        with live.lock:
            self._schedule_locked(live)

    def _schedule_locked(self, live: AgentLive) -> None:
        if not live.scheduled:
            live.scheduled = True
            self._work.put(live.agent_id)

    def _worker(self) -> None:
        """Take the queued agents (up to ``FEED_MANY_MAX``), prepare each, feed them together."""
        while True:
            agent_id = self._work.get()
            if agent_id is None:
                return
            ids = [agent_id]
            while len(ids) < FEED_MANY_MAX:
                try:
                    more = self._work.get_nowait()
                except queue.Empty:
                    break
                if more is None:   # stop: leave it for the next get (this or another worker)
                    self._work.put(None)
                    break
                ids.append(more)
            claimed = [c for c in map(self._claim, ids) if c is not None]
            feeds: dict[int, tuple[AgentLive, list[Batch]]] = {}
            for live, items in claimed:
                try:
                    fresh = self._process(live, items)
                except Exception as exc:
                    self._failed(live, exc)
                    continue
                if fresh:
                    feeds[live.agent_id] = (live, fresh)
            if feeds:
                self._feed_all(feeds)
            for live, _ in claimed:
                with live.lock:
                    live.busy = False
                    if live.pending:
                        self._schedule_locked(live)

    def _claim(self, agent_id: int) -> tuple[AgentLive, list[Batch]] | None:
        """The agent and its queued batches, now busy (None: gone or another worker has it)."""
        live = self._agents.get(agent_id)
        if live is None:
            return None
        with live.lock:
            live.scheduled = False
            if live.busy:   # another worker has it; it re-schedules when done
                return None
            live.busy = True
            items, live.pending = live.pending, []
        return live, items

    @staticmethod
    def _failed(live: AgentLive, exc: Exception) -> None:
        log.error("tracker of agent %s failed", live.agent_id, exc_info=exc)
        live.error = str(exc) if isinstance(exc, FeedFailed) else f"{type(exc).__name__}: {exc}"
        live.dirty = True

    def _process(self, live: AgentLive, items: list[Batch]) -> list[Batch] | None:
        """Judge the batches, re-run the tracker if needed; the fresh batches to feed."""
        if live.alarms is not None:
            raised = []
            for b in sorted(items, key=lambda b: (b.time_span() or (math.inf, 0.0))[0]):
                raised += live.alarms.on_batch(b)
            self.events.emit(live.mission_id, live.agent_id, raised, live.latest)
        if not live.tracked:
            with self.sessions() as db:
                row = db.get(Agent, live.agent_id)
                live.tracked = row is not None and row.start_pose is not None
            if not live.tracked:
                return None
        if not live.opened or live.rebuild_from < math.inf:
            with live.lock:
                t_from = min(live.rebuild_from, live.backfill_from) if live.opened else math.inf
                live.rebuild_from = live.backfill_from = math.inf
            self._rebuild(live, t_from)
            return None
        timed = sorted((b for b in items if b.time_span() is not None),
                       key=lambda b: (b.time_span() or (0.0, 0.0))[0])
        fresh = []
        for b in timed:
            t_first = (b.time_span() or (0.0, 0.0))[0]
            if t_first <= live.t_fed:
                live.backfill_from = min(live.backfill_from, t_first)
                live.backfill_since = self.clock()
            else:
                fresh.append(b)
        if live.backfill_from < math.inf:
            waited = self.clock() - live.backfill_since >= self.params.backfill_wait_s
            if not live.book.gap_open or waited:
                t_from = live.backfill_from
                live.backfill_from = math.inf
                self._rebuild(live, t_from)
                return None
        return fresh

    def _spec(self, db: DbSession, agent_id: int) -> AgentSpec:
        agent = db.get(Agent, agent_id)
        assert agent is not None
        mission = db.get(Mission, agent.mission_id)
        assert mission is not None
        meta = SessionMeta.model_validate({
            "start_pose": agent.start_pose, "placement": agent.placement,
            "mounting_q_bd": agent.mounting_q_bd, "user": agent.user,
            "floor_height_m": mission.floor_height_m, "channel": mission.channel,
            "georeference": mission.georeference})
        landmarks, versions = versions_of(db, mission.id)
        return AgentSpec(agent_id, agent.preset, meta.model_dump(mode="json"), landmarks,
                         versions, kind=agent.kind)

    def _restore(self, live: AgentLive, t_from: float) -> tuple[float, float]:
        """Open the agent from its newest snapshot before ``t_from``; (t_data, t_final).

        ``t_from`` -inf: from no snapshot; -inf is returned without one. Rows after the
        snapshot are cut. A snapshot that lacks a landmark version from before its data
        (written while the change was on its way) is dropped and the one before it taken.
        """
        aid = live.agent_id
        self.raw_log.flush()   # the agent's estimates and snapshots handed in so far
        while True:
            with self.sessions() as db, db.begin():
                if t_from < math.inf:
                    old = delete(TrackerSnapshot).where(TrackerSnapshot.agent_id == aid)
                    if t_from > -math.inf:
                        old = old.where(TrackerSnapshot.t_data >= t_from)
                    db.execute(old)
                snap = db.scalars(select(TrackerSnapshot).where(TrackerSnapshot.agent_id == aid)
                                  .order_by(TrackerSnapshot.t_data.desc())).first()
                state = None if snap is None else snap.state
                t_data = -math.inf if snap is None else snap.t_data
                t_final = -math.inf if snap is None else snap.t_final
                cut = delete(EstimateRow).where(EstimateRow.agent_id == aid)
                if snap is not None:
                    cut = cut.where(EstimateRow.t > t_final)
                db.execute(cut)
                spec = self._spec(db, aid)
            self.runner.close(aid)
            try:
                self.runner.open(spec, state, t_final)
            except StaleSnapshot:
                log.warning("agent %s: snapshot at %.3f s lacks a landmark version; taking the "
                            "one before", aid, t_data)
                t_from = t_data
                continue
            return t_data, t_final

    def _rebuild(self, live: AgentLive, t_from: float) -> None:
        """Restore the newest snapshot before ``t_from`` and replay the raw log after it."""
        aid = live.agent_id
        t_data, t_final = self._restore(live, t_from)
        live.replaying = True
        live.opened = True
        live.t_fed = live.t_snap = t_data
        live.t_final = t_final
        done = 0
        replayed: set[int] = set()
        while True:
            with self.sessions() as db:
                q = select(RawBatch.seq, RawBatch.source, RawBatch.content_type,
                           RawBatch.body).where(RawBatch.agent_id == aid,
                                                RawBatch.t_first.is_not(None))
                if t_data > -math.inf:
                    q = q.where(RawBatch.t_first > t_data)
                page = db.execute(q.order_by(RawBatch.t_first, RawBatch.seq)
                                  .offset(done).limit(REPLAY_PAGE)).all()
            if not page:
                break
            done += len(page)
            replayed.update(r.seq for r in page)
            batches = [DECODERS[r.source](r.body, r.content_type) for r in page]
            for i in range(0, len(batches), 20):
                self._feed(live, batches[i:i + 20])
        with live.lock:   # batches stored while replaying were replayed already
            live.pending = [b for b in live.pending if b.seq not in replayed]
            live.replaying = False

    def _feed_all(self, feeds: dict[int, tuple[AgentLive, list[Batch]]]) -> None:
        """Feed several agents through one runner call (one message per shard)."""
        try:
            results = self.runner.feed_many({aid: b for aid, (_, b) in feeds.items()})
        except Exception as exc:
            for live, _ in feeds.values():
                self._failed(live, exc)
            return
        for aid, (live, batches) in feeds.items():
            rows = results[aid]
            try:
                if isinstance(rows, Exception):
                    raise rows
                self._fed(live, batches, rows)
            except Exception as exc:
                self._failed(live, exc)

    def _feed(self, live: AgentLive, batches: list[Batch]) -> None:
        self._fed(live, batches, self.runner.feed(live.agent_id, batches))

    def _fed(self, live: AgentLive, batches: list[Batch], rows: Rows) -> None:
        """Keep what a feed of ``batches`` produced: rows, estimate, the next snapshot."""
        spans = [b.time_span() for b in batches]
        live.t_fed = max([live.t_fed, *(s[1] for s in spans if s is not None)])
        self._store(live, rows)
        if rows.provisional is None:   # no tracker yet (or no new row): nothing to keep
            return
        period = self.params.snapshot_every_s
        if live.t_snap == -math.inf:
            live.t_snap = live.t_fed - period * snapshot_phase(live.agent_id)
        elif live.t_fed - live.t_snap >= period:
            self._snapshot(live)

    def _store(self, live: AgentLive, rows: Rows) -> None:
        now = self.clock()
        received_t = now - live.t0_unix
        stale = live.stale(now)
        if rows.final is not None and len(rows.final):
            values = rows_to_db(live.mission_id, live.agent_id, rows.final, stale=stale,
                                 received_t=received_t)
            self.raw_log.defer(lambda db: _write_estimates(db, values))
        live.t_final = rows.t_final
        latest_rows = rows.provisional if rows.provisional is not None else rows.final
        if latest_rows is not None and len(latest_rows):
            est = estimate_dict(live.agent_id, latest_rows, len(latest_rows) - 1, stale=stale,
                                received_t=received_t)
            with live.lock:
                live.latest = est
                live.dirty = True
            if live.alarms is not None and not live.replaying:
                raised = live.alarms.on_estimate(est, self.events.zones(live.mission_id))
                self.events.emit(live.mission_id, live.agent_id, raised, est)

    def _snapshot(self, live: AgentLive) -> None:
        """Take the tracker's state now; it is written after the estimates before it."""
        state = self.runner.snapshot(live.agent_id)
        if state is None:
            return
        row = {"agent_id": live.agent_id, "t_data": live.t_fed, "t_final": live.t_final,
               "created_unix": self.clock(), "state": state}
        self.raw_log.defer(lambda db: _write_snapshot(db, row))
        live.t_snap = live.t_fed


def snapshot_phase(agent_id: int) -> float:
    """Where in the snapshot period an agent's snapshots fall, in [0, 1).

    Agents that start together would otherwise all snapshot in the same tick (a burst of
    tracker states to serialise and write every period); the golden-ratio sequence spreads any
    run of agent ids evenly over the period. The first snapshot comes after at most one period
    of data, as without the phase.
    """
    return (agent_id * GOLDEN_FRACTION) % 1.0


def _write_estimates(db: DbSession, values: list[dict[str, Any]]) -> None:
    db.execute(insert(EstimateRow), values)


def _write_snapshot(db: DbSession, row: dict[str, Any]) -> None:
    """Store a snapshot and drop the agent's snapshots beyond the newest ``KEEP_SNAPSHOTS``."""
    aid = row["agent_id"]
    db.execute(insert(TrackerSnapshot), [row])
    old = list(db.scalars(select(TrackerSnapshot.id).where(TrackerSnapshot.agent_id == aid)
                          .order_by(TrackerSnapshot.t_data.desc()).offset(KEEP_SNAPSHOTS)))
    if old:
        db.execute(delete(TrackerSnapshot).where(TrackerSnapshot.id.in_(old)))
