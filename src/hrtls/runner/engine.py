"""Engines by command-line name: ``--engine local|ray``, ``--workers``, ``--ray-address``."""

from __future__ import annotations

from hrtls.errors import InputError
from hrtls.parallel import Engine, LocalEngine, default_workers

ENGINES = ("local", "ray")


def make_engine(name: str, *, workers: int | None = None,
                ray_address: str | None = None) -> Engine:
    """The engine named on the command line."""
    if name == "local":
        if ray_address is not None:
            raise InputError("--ray-address without --engine ray", where="--ray-address",
                             expected="--engine ray")
        return LocalEngine(workers=default_workers() if workers is None else workers)
    if name == "ray":
        from hrtls.runner.ray_engine import RayEngine

        return RayEngine.connect(address=ray_address, workers=workers)
    raise InputError(f"engine {name!r}", where="--engine", expected=" | ".join(ENGINES))
