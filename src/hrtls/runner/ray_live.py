"""Live trackers on Ray actors (optional: ``hrtls[ray]``).

:mod:`hrtls.runner.shards` with one shard actor per shard, wherever Ray places it (this machine
or a cluster).
"""

from __future__ import annotations

from typing import Any

from hrtls.errors import InputError
from hrtls.runner.ray_engine import _import_ray
from hrtls.runner.shards import ShardBody, ShardDied, ShardedRunner


class _RayShard:
    """A shard actor."""

    def __init__(self, ray: Any, actor_class: Any) -> None:
        self._ray = ray
        self._actor = actor_class.remote()
        self._pending: Any = None

    def call(self, method: str, *args: Any) -> Any:
        self.submit(method, *args)
        return self.result()

    def submit(self, method: str, *args: Any) -> None:
        self._pending = getattr(self._actor, method).remote(*args)

    def result(self) -> Any:
        ref, self._pending = self._pending, None
        try:
            return self._ray.get(ref)
        except self._ray.exceptions.RayActorError as exc:
            raise ShardDied(str(exc)) from exc

    def kill(self) -> None:
        self._ray.kill(self._actor, no_restart=True)


class RayShardRunner(ShardedRunner):
    """:class:`~hrtls.runner.shards.ShardedRunner` on ``n_shards`` Ray actors.

    Build it with :meth:`connect`; ``address`` joins a running cluster (``"auto"`` or
    ``"ray://head:10001"``), otherwise a local Ray starts with ``num_cpus``.
    """

    def __init__(self, *, n_shards: int, ray: Any) -> None:
        actor_class = ray.remote(num_cpus=0, max_restarts=0)(ShardBody)
        super().__init__(n_shards=n_shards, new_shard=lambda: _RayShard(ray, actor_class),
                         option="--ray-shards")

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
