"""Live trackers on Ray actors: agents hashed onto shard actors (optional: ``hrtls[ray]``).

Each shard actor holds an :class:`~hrtls.service.runner.InProcessRunner` for the agents hashed
onto it (``agent_id % n_shards``), so the tracking is the same code as in-process. The runner
keeps, per agent, what it needs to rebuild the agent elsewhere: its spec, the last snapshot the
host took, and the feeds (batches, grouped as they were fed) since then. When a shard actor dies
(``RayActorError``), a new actor is started, every agent of the shard is opened from its last
snapshot and re-fed its feeds since (their rows were already published and are dropped), and the
feed that failed is repeated. Trackers are deterministic and a restore is exact, so the rows
after recovery equal those of an uninterrupted run, with no batch lost or fed twice.

State lives in three places: the trackers in the shard actors (lost with them), the recovery
copy in the service process (bounded by the host's snapshot period), and the database (raw log
and snapshots, which survive the service itself).
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from hrtls.errors import InputError
from hrtls.runner.ray_engine import _import_ray

if TYPE_CHECKING:
    from hrtls.service.batches import Batch
    from hrtls.service.runner import AgentSpec, Rows


class _Shard:
    """The actor body: one in-process runner (imported on the worker)."""

    def __init__(self) -> None:
        from hrtls.service.runner import InProcessRunner

        self._runner = InProcessRunner()

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        self._runner.open(spec, state, t_final)

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        return self._runner.feed(agent_id, batches)

    def replay(self, agent_id: int, feeds: list[list[Batch]]) -> None:
        for batches in feeds:
            self._runner.feed(agent_id, batches)

    def snapshot(self, agent_id: int) -> bytes | None:
        return self._runner.snapshot(agent_id)

    def close(self, agent_id: int) -> None:
        self._runner.close(agent_id)

    def pid(self) -> int:
        return os.getpid()


@dataclass
class _Recovery:
    spec: AgentSpec
    state: bytes | None
    t_final: float
    feeds: list[list[Batch]] = field(default_factory=list)


class RayShardRunner:
    """:class:`~hrtls.service.runner.TrackerRunner` on ``n_shards`` Ray actors.

    Build it with :meth:`connect`; ``address`` joins a running cluster (``"auto"`` or
    ``"ray://head:10001"``), otherwise a local Ray starts with ``num_cpus``.
    """

    def __init__(self, *, n_shards: int, ray: Any) -> None:
        self._ray = ray
        self._actor_class = ray.remote(num_cpus=0, max_restarts=0)(_Shard)
        self._shards = [self._actor_class.remote() for _ in range(n_shards)]
        self._locks = [threading.Lock() for _ in range(n_shards)]
        self._agents: dict[int, _Recovery] = {}
        self.recoveries = 0

    @classmethod
    def connect(cls, *, n_shards: int, address: str | None = None,
                num_cpus: int | None = None) -> RayShardRunner:
        """Start or join Ray and create the shard actors."""
        if n_shards < 1:
            raise InputError(f"{n_shards} shards", where="--ray-shards", expected=">= 1")
        ray = _import_ray()
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                      "configure_logging": False}
            if address is not None:
                kwargs["address"] = address
            elif num_cpus is not None:
                kwargs["num_cpus"] = num_cpus
            ray.init(**kwargs)
        return cls(n_shards=n_shards, ray=ray)

    @property
    def n_shards(self) -> int:
        """Number of shard actors."""
        return len(self._shards)

    def shard_of(self, agent_id: int) -> int:
        """The shard an agent lives on (stable across restarts of the service)."""
        return agent_id % len(self._shards)

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        """Open the agent on its shard and keep the recovery copy."""
        self._agents[spec.agent_id] = _Recovery(spec, state, t_final)
        self._call(spec.agent_id, "open", spec, state, t_final)

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        """Feed on the agent's shard; the feed is kept until the next snapshot."""
        rows: Rows = self._call(agent_id, "feed", agent_id, batches)
        self._agents[agent_id].feeds.append(batches)
        return rows

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
        """Kill a shard actor (fault tests and drills); the next call on it recovers.

        Returns the killed actor's process id.
        """
        with self._locks[shard]:
            actor = self._shards[shard]
            pid = int(self._ray.get(actor.pid.remote()))
            self._ray.kill(actor, no_restart=True)
        return pid

    def shutdown(self) -> None:
        """Kill every shard actor."""
        for actor in self._shards:
            self._ray.kill(actor, no_restart=True)
        self._shards = []

    def _call(self, agent_id: int, method: str, *args: Any, recover: bool = True) -> Any:
        """One call on the agent's shard, recovering the shard once if its actor died.

        Calls on one shard are serialised (its lock), so a recovery never races a feed;
        different shards work in parallel.
        """
        shard = self.shard_of(agent_id)
        with self._locks[shard]:
            try:
                return self._ray.get(getattr(self._shards[shard], method).remote(*args))
            except self._ray.exceptions.RayActorError:
                if not recover:
                    return None
                self._recover(shard)
                return self._ray.get(getattr(self._shards[shard], method).remote(*args))

    def _recover(self, shard: int) -> None:
        """A new actor for ``shard``; its agents from their last snapshot plus later feeds."""
        self.recoveries += 1
        actor = self._actor_class.remote()
        self._shards[shard] = actor
        pending = []
        for agent_id, rec in self._agents.items():
            if self.shard_of(agent_id) != shard:
                continue
            pending.append(actor.open.remote(rec.spec, rec.state, rec.t_final))
            pending.append(actor.replay.remote(agent_id, rec.feeds))
        self._ray.get(pending)
