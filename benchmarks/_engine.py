"""``--engine``, ``--workers``, ``--ray-address``: benchmarks looping over seeds or files.

The options are those of ``benchmarks/wsn.py`` and ``hrtls wsn experiment``: ``--engine local``
(the default) with ``--workers`` processes (default: all cores; ``--workers 1`` runs in this
process) or ``--engine ray``. Each benchmark maps a module-level function over its items (seeds,
files, cases) and prints its tables from the results in item order, so the tables do not depend
on the engine or the number of workers. A failed item is printed to stderr with its traceback
and left out of the tables; the benchmark then exits with status 1 (:meth:`Batch.finish`).

Each map starts its own pool, whose processes take seconds to import hrtls and load the
compiled kernels: for short runs ``--workers 1`` is faster.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from hrtls.parallel import Engine
from hrtls.runner import make_engine

T = TypeVar("T")
R = TypeVar("R")


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"0-9"``, ``"100,105"`` or ``"0-4,100-104"``."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def add_engine_options(ap: argparse.ArgumentParser) -> None:
    """The engine options of ``benchmarks/wsn.py``."""
    ap.add_argument("--engine", default="local", help="local | ray (same numbers either way)")
    ap.add_argument("--workers", type=int, default=None, help="items at once (default: cores)")
    ap.add_argument("--ray-address", default=None)


@dataclass
class Batch:
    """An engine and the items that failed on it so far."""

    engine: Engine
    failed: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, args: argparse.Namespace) -> Batch:
        """The engine named by :func:`add_engine_options`' options."""
        return cls(make_engine(args.engine, workers=args.workers, ray_address=args.ray_address))

    def map(self, fn: Callable[[T], R], items: Sequence[T], *,
            label: Callable[[T], str] = repr) -> list[tuple[T, R]]:
        """``(item, fn(item))`` of the items that succeeded, in item order.

        A failed item is printed to stderr (``label(item)``, error, traceback) and recorded.
        """
        out: list[tuple[T, R]] = []
        for item, o in zip(items, self.engine.map(fn, items), strict=True):
            if o.ok:
                out.append((item, o.value))  # type: ignore[arg-type]
                continue
            self.failed.append(label(item))
            print(f"{label(item)} failed, left out of the tables: {o.error}\n{o.detail}",
                  file=sys.stderr, flush=True)
        return out

    def values(self, fn: Callable[[T], R], items: Sequence[T], *,
               label: Callable[[T], str] = repr) -> list[R]:
        """The values of :meth:`map`."""
        return [v for _, v in self.map(fn, items, label=label)]

    def finish(self) -> None:
        """Exit with status 1 when an item failed."""
        if self.failed:
            raise SystemExit(f"{len(self.failed)} item(s) failed: {', '.join(self.failed)}")
