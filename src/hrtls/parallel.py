"""Batch engines: map one picklable function over many independent items.

This core module holds the protocol, the outcome type and the engine of this machine
(:class:`LocalEngine`), so that any layer can take an engine; engines that need a cluster live in
:mod:`hrtls.runner` (``make_engine`` builds one from command-line names).

Every engine returns one :class:`Outcome` per item, in the order of the items, whatever order
the work finished in; a failing item is reported in its outcome and does not stop the others.
Results equal those of a plain loop in one process: each item carries everything its function
needs (seeds included), so where it runs does not change what it computes.
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Generic, Protocol, TypeVar

from hrtls.errors import InputError

T = TypeVar("T")
R = TypeVar("R")

ProgressCallback = Callable[[int, int], None]
"""Called with ``(done, total)`` after each finished item."""

@dataclass(frozen=True)
class Outcome(Generic[R]):
    """What one item gave: its value, or the error that stopped it."""

    index: int
    value: R | None = None
    error: str | None = None
    detail: str = ""

    @property
    def ok(self) -> bool:
        """The item finished without an error."""
        return self.error is None


class Engine(Protocol):
    """Something that maps a function over items (see the module docstring)."""

    @property
    def name(self) -> str:
        """Engine name, as on the command line."""
        ...

    @property
    def workers(self) -> int:
        """Items processed at once."""
        ...

    def map(self, fn: Callable[[T], R], items: Sequence[T], *,
            progress: ProgressCallback | None = None) -> list[Outcome[R]]:
        """Apply ``fn`` to every item; one outcome per item, in item order."""
        ...


def failure(index: int, exc: BaseException) -> Outcome[R]:
    """The outcome of an item whose function raised ``exc``."""
    text = f"{type(exc).__name__}: {exc}"
    detail = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return Outcome(index=index, error=text, detail=detail)


def call_item(fn: Callable[[T], R], index: int, item: T) -> Outcome[R]:
    """``fn(item)`` as the outcome of item ``index`` (an exception becomes a failure)."""
    try:
        return Outcome(index=index, value=fn(item))
    except Exception as exc:  # reported per item; the batch goes on
        return failure(index, exc)


@dataclass(frozen=True, kw_only=True)
class LocalEngine:
    """This machine: ``workers`` = 1 runs in this process, more use a process pool.

    The pool starts its processes with ``spawn`` (no inherited numba or thread state).
    """

    workers: int = 1
    name: str = "local"

    def __post_init__(self) -> None:
        if self.workers < 1:
            raise InputError(f"{self.workers} workers", where="--workers", expected=">= 1")

    def map(self, fn: Callable[[T], R], items: Sequence[T], *,
            progress: ProgressCallback | None = None) -> list[Outcome[R]]:
        """Apply ``fn`` to every item; one outcome per item, in item order."""
        total = len(items)
        out: list[Outcome[R] | None] = [None] * total
        if self.workers == 1 or total <= 1:
            for i, item in enumerate(items):
                out[i] = call_item(fn, i, item)
                if progress is not None:
                    progress(i + 1, total)
            return [o for o in out if o is not None]
        with ProcessPoolExecutor(max_workers=min(self.workers, total),
                                 mp_context=get_context("spawn")) as pool:
            pending: dict[Future[Outcome[R]], int] = {
                pool.submit(call_item, fn, i, item): i for i, item in enumerate(items)}
            done = 0
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    i = pending.pop(fut)
                    try:
                        out[i] = fut.result()
                    except Exception as exc:  # the worker process itself died
                        out[i] = failure(i, exc)
                    done += 1
                    if progress is not None:
                        progress(done, total)
        return [o for o in out if o is not None]


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def values_or_raise(outcomes: Sequence[Outcome[R]], *, where: str) -> list[R]:
    """The values of all-or-nothing work; the first failure is raised with its traceback."""
    for o in outcomes:
        if not o.ok:
            raise RuntimeError(f"{where}: item {o.index} failed: {o.error}\n{o.detail}")
    return [o.value for o in outcomes]  # type: ignore[misc]
