"""``feed_many``: agents fed in one call equal agents fed one by one, in and out of process."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from tests.service.streams import office

from hrtls.runner.proc_live import ProcessShardRunner
from hrtls.service.batches import Batch, parse_batch
from hrtls.service.client import session_batches
from hrtls.service.runner import AgentSpec, FeedFailed, InProcessRunner, Rows

AGENTS = {1: 3, 2: 4, 3: 5}
"""Agent id -> seed of its simulated walk."""


def _spec(agent_id: int, seed: int) -> AgentSpec:
    s = office(20.0, seed)
    return AgentSpec(agent_id, "default", s.meta.model_dump(mode="json"),
                     tuple(lm.model_dump(mode="json", exclude_none=True)
                           for lm in s.landmarks.values()))


def _batches(seed: int) -> list[Batch]:
    s = office(20.0, seed).with_parts(truth=None)
    return [parse_batch({**b, "seq": i})
            for i, (_, b) in enumerate(session_batches(s, chunk_s=0.5, blocks=True))]


def _collect(out: dict[int, list[Rows]], results: dict[int, Rows | Exception]) -> None:
    for aid, rows in results.items():
        assert not isinstance(rows, Exception), rows
        out.setdefault(aid, []).append(rows)


def _final(rows: list[Rows]) -> dict[str, np.ndarray]:
    finals = [r.final for r in rows if r.final is not None]
    last = [r.provisional for r in rows if r.provisional is not None][-1]
    return {"t": np.concatenate([f.t for f in finals] + [last.t]),
            "xyz": np.concatenate([f.xyz for f in finals] + [last.xyz]),
            "cov": np.concatenate([f.cov_xy for f in finals] + [last.cov_xy])}


def _reference() -> dict[int, dict[str, np.ndarray]]:
    runner = InProcessRunner()
    out: dict[int, list[Rows]] = {}
    for aid, seed in AGENTS.items():
        runner.open(_spec(aid, seed), None, -np.inf)
        for b in _batches(seed):
            out.setdefault(aid, []).append(runner.feed(aid, [b]))
    return {aid: _final(rows) for aid, rows in out.items()}


def _rounds(runner: Any, *, kill_at: int | None = None) -> dict[int, dict[str, np.ndarray]]:
    """Every agent's batch ``k`` in round ``k``, two batches of agent 3 in some rounds."""
    streams = {aid: _batches(seed) for aid, seed in AGENTS.items()}
    for aid, seed in AGENTS.items():
        runner.open(_spec(aid, seed), None, -np.inf)
    out: dict[int, list[Rows]] = {}
    k = 0
    while any(streams.values()):
        if k == kill_at:
            runner.kill_shard(runner.shard_of(2))
        feeds = {}
        for aid, left in streams.items():
            take = 2 if aid == 3 and k % 3 == 0 else 1
            if left:
                feeds[aid], streams[aid] = left[:take], left[take:]
        _collect(out, runner.feed_many(feeds))
        k += 1
    return {aid: _final(rows) for aid, rows in out.items()}


def _assert_equal(a: dict[int, dict[str, np.ndarray]],
                  b: dict[int, dict[str, np.ndarray]]) -> None:
    assert a.keys() == b.keys()
    for aid in a:
        assert len(a[aid]["t"]) > 10
        for k in a[aid]:
            np.testing.assert_array_equal(a[aid][k], b[aid][k], err_msg=f"agent {aid} {k}")


def test_in_process_feed_many_equals_feeding_one_by_one() -> None:
    _assert_equal(_rounds(InProcessRunner()), _reference())


@pytest.mark.parametrize("kill_at", [None, 17])
def test_process_shards_feed_many_equals_in_process(kill_at: int | None) -> None:
    """Two worker processes; a shard killed mid-stream recovers without loss or double feed."""
    runner = ProcessShardRunner(n_shards=2)
    try:
        got = _rounds(runner, kill_at=kill_at)
        assert runner.recoveries == (0 if kill_at is None else 1)
    finally:
        runner.shutdown()
    _assert_equal(got, _reference())


@pytest.mark.parametrize("make", [InProcessRunner, lambda: ProcessShardRunner(n_shards=2)])
def test_a_failing_agent_does_not_stop_the_others(make: Any) -> None:
    runner = make()
    try:
        runner.open(_spec(1, 3), None, -np.inf)
        # agent 2 was never opened: its feed fails on its shard, agent 1's goes on
        b = _batches(3)[:2]
        out = runner.feed_many({1: b, 2: b})
    finally:
        if isinstance(runner, ProcessShardRunner):
            runner.shutdown()
    assert isinstance(out[1], Rows)
    assert isinstance(out[2], FeedFailed) and "KeyError" in str(out[2])
