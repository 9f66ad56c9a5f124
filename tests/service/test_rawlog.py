"""The raw log's group-commit writer on a real database (SQLite and PostgreSQL)."""

from __future__ import annotations

import threading

import httpx
from sqlalchemy import func, select

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
