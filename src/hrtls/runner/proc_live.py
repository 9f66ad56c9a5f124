"""Live trackers in local worker processes (:mod:`hrtls.runner.shards`, one process a shard).

The trackers then run outside the service process's interpreter lock.

A worker is a spawned Python process serving calls over a pipe (pickled arguments and
results, one call at a time). The service process then keeps only the front end, the host and
the database writes; on a machine with few cores, use about one shard per core left over.
"""

from __future__ import annotations

import multiprocessing as mp
from multiprocessing.connection import Connection
from typing import Any

from hrtls.runner.shards import ShardBody, ShardDied, ShardedRunner

_CONTEXT = mp.get_context("spawn")   # never fork the threads of a running service


def _serve(conn: Connection) -> None:
    """The worker's loop: ``(method, args)`` in, ``(ok, result or exception)`` out."""
    body = ShardBody()
    while True:
        try:
            method, args = conn.recv()
        except EOFError:
            return
        try:
            result = (True, getattr(body, method)(*args))
        except Exception as exc:
            result = (False, exc)
        conn.send(result)


class _ProcessShard:
    """A worker process and the service's end of its pipe."""

    def __init__(self) -> None:
        self._conn, child = _CONTEXT.Pipe()
        self._proc = _CONTEXT.Process(target=_serve, args=(child,), daemon=True,
                                      name="hrtls-shard")
        self._proc.start()
        child.close()

    def call(self, method: str, *args: Any) -> Any:
        self.submit(method, *args)
        return self.result()

    def submit(self, method: str, *args: Any) -> None:
        try:
            self._conn.send((method, args))
        except (EOFError, OSError) as exc:
            raise ShardDied(f"shard process {self._proc.pid} is gone: {exc!r}") from exc

    def result(self) -> Any:
        try:
            ok, result = self._conn.recv()
        except (EOFError, OSError) as exc:
            raise ShardDied(f"shard process {self._proc.pid} is gone: {exc!r}") from exc
        if not ok:
            raise result
        return result

    def kill(self) -> None:
        self._proc.kill()
        self._proc.join(timeout=30)
        self._conn.close()


class ProcessShardRunner(ShardedRunner):
    """:class:`~hrtls.runner.shards.ShardedRunner` on ``n_shards`` local worker processes."""

    def __init__(self, *, n_shards: int) -> None:
        super().__init__(n_shards=n_shards, new_shard=_ProcessShard, option="--process-shards")
