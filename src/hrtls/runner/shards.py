"""Live trackers on shard workers: agents hashed onto workers that each hold a runner.

Each shard worker holds an :class:`~hrtls.service.runner.InProcessRunner` for the agents hashed
onto it (``agent_id % n_shards``), so the tracking is the same code as in-process; the workers
are Ray actors (:mod:`hrtls.runner.ray_live`) or local processes (:mod:`hrtls.runner.proc_live`).
The runner keeps, per agent, what it needs to rebuild the agent elsewhere: its spec, the last
snapshot the host took, and the feeds (batches, grouped as they were fed) since then. When a
shard worker dies (:class:`ShardDied`), a new worker is started, every agent of the shard is
opened from its last snapshot and re-fed its feeds since (their rows were already published and
are dropped), and the call that failed is repeated. Trackers are deterministic and a restore is
exact, so the rows after recovery equal those of an uninterrupted run, with no batch lost or fed
twice.

State lives in three places: the trackers in the shard workers (lost with them), the recovery
copy in the service process (bounded by the host's snapshot period), and the database (raw log
and snapshots, which survive the service itself).
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from hrtls.errors import InputError

if TYPE_CHECKING:
    from hrtls.service.batches import Batch
    from hrtls.service.runner import AgentSpec, Rows


class ShardDied(RuntimeError):
    """The shard worker is gone (its process died or was killed)."""


class ShardBody:
    """What a shard worker runs: one in-process runner (imported in the worker)."""

    def __init__(self) -> None:
        from hrtls.service.runner import InProcessRunner

        self._runner = InProcessRunner()

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        """Open an agent (fresh or from ``state``)."""
        self._runner.open(spec, state, t_final)

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        """Feed an agent; its new rows."""
        return self._runner.feed(agent_id, batches)

    def feed_many(self, feeds: dict[int, list[Batch]]) -> dict[int, Rows | Exception]:
        """Feed several agents; per agent its rows or what its tracker raised."""
        return self._runner.feed_many(feeds)

    def replay(self, agent_id: int, feeds: list[list[Batch]]) -> None:
        """Feed again what an agent was fed since its snapshot (rows dropped)."""
        for batches in feeds:
            self._runner.feed(agent_id, batches)

    def snapshot(self, agent_id: int) -> bytes | None:
        """An agent's state."""
        return self._runner.snapshot(agent_id)

    def close(self, agent_id: int) -> None:
        """Forget an agent."""
        self._runner.close(agent_id)

    def pid(self) -> int:
        """The worker's process id."""
        return os.getpid()


class Shard(Protocol):
    """A handle on one shard worker."""

    def call(self, method: str, *args: Any) -> Any:
        """Run ``ShardBody.method(*args)`` on the worker; :class:`ShardDied` when it is gone."""

    def submit(self, method: str, *args: Any) -> None:
        """Start ``ShardBody.method(*args)`` on the worker (one call at a time)."""

    def result(self) -> Any:
        """The result of the submitted call (:class:`ShardDied` when the worker is gone)."""

    def kill(self) -> None:
        """End the worker at once (no clean-up)."""


@dataclass
class _Recovery:
    spec: AgentSpec
    state: bytes | None
    t_final: float
    feeds: list[list[Batch]] = field(default_factory=list)


class ShardedRunner:
    """:class:`~hrtls.service.runner.TrackerRunner` on ``n_shards`` workers from ``new_shard``."""

    def __init__(self, *, n_shards: int, new_shard: Callable[[], Shard], option: str) -> None:
        if n_shards < 1:
            raise InputError(f"{n_shards} shards", where=option, expected=">= 1")
        self._new_shard = new_shard
        self._shards = [new_shard() for _ in range(n_shards)]
        self._locks = [threading.Lock() for _ in range(n_shards)]
        self._agents: dict[int, _Recovery] = {}
        self.recoveries = 0

    @property
    def n_shards(self) -> int:
        """Number of shard workers."""
        return len(self._locks)

    def shard_of(self, agent_id: int) -> int:
        """The shard an agent lives on (stable across restarts of the service)."""
        return agent_id % len(self._locks)

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        """Open the agent on its shard and keep the recovery copy."""
        self._agents[spec.agent_id] = _Recovery(spec, state, t_final)
        self._call(spec.agent_id, "open", spec, state, t_final)

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        """Feed on the agent's shard; the feed is kept until the next snapshot."""
        rows: Rows = self._call(agent_id, "feed", agent_id, batches)
        self._agents[agent_id].feeds.append(batches)
        return rows

    def feed_many(self, feeds: dict[int, list[Batch]]) -> dict[int, Rows | Exception]:
        """Feed several agents with one call per shard, the shards working in parallel.

        Each feed that produced rows is kept for recovery, as with :meth:`feed`.
        """
        by_shard: dict[int, dict[int, list[Batch]]] = {}
        for agent_id, batches in feeds.items():
            by_shard.setdefault(self.shard_of(agent_id), {})[agent_id] = batches
        out: dict[int, Rows | Exception] = {}
        with contextlib.ExitStack() as held:
            for shard in sorted(by_shard):   # one lock order: no deadlock between callers
                held.enter_context(self._locks[shard])
            submitted = {}
            for shard, sub in by_shard.items():
                try:
                    self._shards[shard].submit("feed_many", sub)
                    submitted[shard] = True
                except ShardDied:
                    submitted[shard] = False
            for shard, sub in by_shard.items():
                out.update(self._shard_result(shard, sub, submitted=submitted[shard]))
        for agent_id, rows in out.items():
            if not isinstance(rows, Exception):
                self._agents[agent_id].feeds.append(feeds[agent_id])
        return out

    def _shard_result(self, shard: int, sub: dict[int, list[Batch]], *,
                      submitted: bool) -> dict[int, Rows | Exception]:
        """The submitted ``feed_many`` of a shard; recovered and repeated if its worker died."""
        try:
            if submitted:
                result: dict[int, Rows | Exception] = self._shards[shard].result()
                return result
        except ShardDied:
            pass
        self._recover(shard)
        again: dict[int, Rows | Exception] = self._shards[shard].call("feed_many", sub)
        return again

    def snapshot(self, agent_id: int) -> bytes | None:
        """The agent's state; it becomes the recovery point (earlier feeds are dropped)."""
        state: bytes | None = self._call(agent_id, "snapshot", agent_id)
        rec = self._agents[agent_id]
        if state is not None:
            rec.state, rec.feeds = state, []
        return state

    def close(self, agent_id: int) -> None:
        """Forget the agent here and on its shard."""
        if self._agents.pop(agent_id, None) is not None:
            self._call(agent_id, "close", agent_id, recover=False)

    def kill_shard(self, shard: int) -> int:
        """Kill a shard worker (fault tests and drills); the next call on it recovers.

        Returns the killed worker's process id.
        """
        with self._locks[shard]:
            worker = self._shards[shard]
            pid = int(worker.call("pid"))
            worker.kill()
        return pid

    def shutdown(self) -> None:
        """Kill every shard worker."""
        for worker in self._shards:
            worker.kill()
        self._shards = []

    def _call(self, agent_id: int, method: str, *args: Any, recover: bool = True) -> Any:
        """One call on the agent's shard, recovering the shard once if its worker died.

        Calls on one shard are serialised (its lock), so a recovery never races a feed;
        different shards work in parallel.
        """
        shard = self.shard_of(agent_id)
        with self._locks[shard]:
            try:
                return self._shards[shard].call(method, *args)
            except ShardDied:
                if not recover:
                    return None
                self._recover(shard)
                return self._shards[shard].call(method, *args)

    def _recover(self, shard: int) -> None:
        """A new worker for ``shard``; its agents from their last snapshot plus later feeds."""
        self.recoveries += 1
        worker = self._new_shard()
        self._shards[shard] = worker
        for agent_id, rec in self._agents.items():
            if self.shard_of(agent_id) == shard:
                worker.call("open", rec.spec, rec.state, rec.t_final)
                worker.call("replay", agent_id, rec.feeds)
