"""Ray tasks as a batch engine (optional: ``pip install 'hrtls[ray]'``).

``RayEngine.connect()`` starts a local Ray instance (``num_cpus`` = ``workers``) or joins a
cluster (``address="auto"`` or ``"ray://head:10001"``, see docs/scale-out.md). One task per item;
the function and its item are shipped by Ray's serializer, so both must be importable on the
workers (the ``hrtls`` package installed there).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from hrtls.errors import InputError
from hrtls.parallel import Outcome, ProgressCallback, call_item, failure

T = TypeVar("T")
R = TypeVar("R")


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise InputError("Ray is not installed", where="--engine ray",
                         expected="pip install 'hrtls[ray]'") from None
    return ray


@dataclass(frozen=True, kw_only=True)
class RayEngine:
    """Ray tasks; ``workers`` caps the tasks in flight (default: the cluster's CPUs)."""

    workers: int
    address: str | None = None
    name: str = "ray"

    @classmethod
    def connect(cls, *, address: str | None = None, workers: int | None = None) -> RayEngine:
        """Join ``address`` (a running cluster) or start a local Ray with ``workers`` CPUs."""
        ray = _import_ray()
        if workers is not None and workers < 1:
            raise InputError(f"{workers} workers", where="--workers", expected=">= 1")
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                      "configure_logging": False}
            if address is None:
                if workers is not None:
                    kwargs["num_cpus"] = workers
            else:
                kwargs["address"] = address
            ray.init(**kwargs)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        return cls(workers=workers or max(cpus, 1), address=address)

    def map(self, fn: Callable[[T], R], items: Sequence[T], *,
            progress: ProgressCallback | None = None) -> list[Outcome[R]]:
        """Apply ``fn`` to every item as Ray tasks; one outcome per item, in item order."""
        ray = _import_ray()
        task = ray.remote(num_cpus=1, max_retries=0)(call_item)
        total = len(items)
        out: list[Outcome[R] | None] = [None] * total
        fn_ref = ray.put(fn)
        queue = list(enumerate(items))[::-1]
        running: dict[Any, int] = {}
        done = 0
        while queue or running:
            while queue and len(running) < self.workers:
                i, item = queue.pop()
                running[task.remote(fn_ref, i, item)] = i
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                i = running.pop(ref)
                try:
                    out[i] = ray.get(ref)
                except Exception as exc:  # the task's worker died
                    out[i] = failure(i, exc)
                done += 1
                if progress is not None:
                    progress(done, total)
        return [o for o in out if o is not None]
