"""The raw log's group-commit writer on a real database (SQLite and PostgreSQL)."""

from __future__ import annotations

import threading

import httpx
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from hrtls.service.db import make_engine, session_factory
from hrtls.service.models import RawBatch
from hrtls.service.rawlog import RawLogWriter, RawRow

from .conftest import Live, new_agent, new_mission


def _row(agent_id: int, seq: int) -> RawRow:
    return RawRow(agent_id=agent_id, seq=seq, received_unix=1.0e9 + seq, t_first=float(seq),
                  t_last=seq + 0.5, source="batch", content_type="application/json",
                  body=b'{"seq": %d}' % seq)


def test_many_threads_store_each_seq_once_and_duplicates_answer_false(
        live: Live, commander: httpx.Client) -> None:
    mission = new_mission(commander)["id"]
    agent_id = new_agent(commander, mission)["agent"]["id"]
    engine = make_engine(live.settings.db_url)
    writer = RawLogWriter(session_factory(engine), max_group=16)
    writer.start()
    results: dict[tuple[int, int], bool] = {}
    lock = threading.Lock()

    def send(thread: int) -> None:
        for seq in range(40):  # every thread sends every seq: one of them stores it
            ok = writer.append(_row(agent_id, seq))
            with lock:
                results[(thread, seq)] = ok

    threads = [threading.Thread(target=send, args=(k,)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    writer.stop()
    try:
        for seq in range(40):
            assert sum(results[(k, seq)] for k in range(6)) == 1, seq
        with session_factory(engine)() as db:
            rows = db.execute(select(RawBatch.seq, RawBatch.body).where(
                RawBatch.agent_id == agent_id).order_by(RawBatch.seq)).all()
        assert [r.seq for r in rows] == list(range(40))
        assert all(r.body == b'{"seq": %d}' % r.seq for r in rows)
    finally:
        engine.dispose()


def test_stopped_writer_stores_directly(live: Live, commander: httpx.Client) -> None:
    mission = new_mission(commander)["id"]
    agent_id = new_agent(commander, mission)["agent"]["id"]
    engine = make_engine(live.settings.db_url)
    writer = RawLogWriter(session_factory(engine))
    try:
        assert writer.append(_row(agent_id, 7)) is True
        assert writer.append(_row(agent_id, 7)) is False
        with session_factory(engine)() as db:
            n = db.scalar(select(func.count()).select_from(RawBatch).where(
                RawBatch.agent_id == agent_id))
        assert n == 1
    finally:
        engine.dispose()


def test_deferred_writes_commit_in_order_with_the_raw_rows(
        live: Live, commander: httpx.Client) -> None:
    mission = new_mission(commander)["id"]
    agent_id = new_agent(commander, mission)["agent"]["id"]
    engine = make_engine(live.settings.db_url)
    writer = RawLogWriter(session_factory(engine), max_group=8)
    seen: list[int] = []   # raw rows committed before each deferred write ran

    def count(db: Session) -> None:
        seen.append(db.scalar(select(func.count()).select_from(RawBatch).where(
            RawBatch.agent_id == agent_id)) or 0)

    def fail(db: Session) -> None:
        raise RuntimeError("a broken deferred write")

    writer.start()
    try:
        futures = []
        for seq in range(30):
            futures.append(writer.submit(_row(agent_id, seq)))
            if seq % 10 == 9:
                writer.defer(count)
        writer.flush()
        assert writer.unwritten() == 0
        assert [f.result() for f in futures] == [True] * 30
        assert seen == [10, 20, 30]
        # a failing write or a duplicate fails alone, its neighbours are stored
        before = writer.submit(_row(agent_id, 30))
        failing = writer.defer(fail)
        duplicate = writer.submit(_row(agent_id, 3))
        after = writer.submit(_row(agent_id, 31))
        writer.defer(count)
        writer.flush()
        assert before.result() and after.result() and duplicate.result() is False
        assert isinstance(failing.exception(), RuntimeError)
        assert seen[-1] == 32
    finally:
        writer.stop()
        engine.dispose()
