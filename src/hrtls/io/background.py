"""Work done on a thread beside the caller's: reading ahead, a value computed meanwhile.

pyarrow's parsers and most numpy loops on large arrays release the GIL, so a table parsed or
written on a thread overlaps with the tracker working on the main one. An exception raised on
the thread is raised again, unchanged (its message names the file, line and field), where the
caller takes the item or the value.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass
from typing import Generic, TypeVar

T = TypeVar("T")

_DONE = object()
"""Put after the last item."""


@dataclass(frozen=True, slots=True)
class _Failed:
    error: BaseException


def read_ahead(items: Iterable[T], *, depth: int = 1, name: str = "hrtls-read-ahead"
               ) -> Generator[T, None, None]:
    """The items of ``items``, produced on a thread up to ``depth`` ahead of the caller.

    The order is kept. An exception of ``items`` is raised here, at the item it failed on;
    closing the iterator early stops the thread after the item it is producing.
    """
    if depth < 1:
        raise ValueError(f"depth = {depth}: expected at least 1")
    ready: queue.Queue[object] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                if not _put(ready, item, stop):
                    return
        except BaseException as error:  # raised again in the caller's thread
            _put(ready, _Failed(error), stop)
            return
        _put(ready, _DONE, stop)

    thread = threading.Thread(target=produce, name=name, daemon=True)
    thread.start()
    try:
        while True:
            item = ready.get()
            if item is _DONE:
                return
            if isinstance(item, _Failed):
                raise item.error
            yield item  # type: ignore[misc]
    finally:
        stop.set()
        while thread.is_alive():  # let a producer blocked on a full queue finish
            with contextlib.suppress(queue.Empty):
                ready.get(timeout=0.05)
        thread.join()


def _put(ready: queue.Queue[object], item: object, stop: threading.Event) -> bool:
    """Put ``item`` once there is room; False when the caller stopped reading."""
    while not stop.is_set():
        try:
            ready.put(item, timeout=0.05)
            return True
        except queue.Full:
            continue
    return False


class Background(Generic[T]):
    """``fn()`` computed on a thread from now; :meth:`result` waits for it or raises its error."""

    def __init__(self, fn: Callable[[], T], *, name: str = "hrtls-background") -> None:
        self._value: list[T] = []
        self._error: list[BaseException] = []

        def run() -> None:
            try:
                self._value.append(fn())
            except BaseException as error:  # raised again by result()
                self._error.append(error)

        self._thread = threading.Thread(target=run, name=name, daemon=True)
        self._thread.start()

    def join(self) -> None:
        """Wait for ``fn()`` to end, whatever it gave."""
        self._thread.join()

    def result(self) -> T:
        """The value of ``fn()`` once computed; its exception, unchanged, if it raised."""
        self._thread.join()
        if self._error:
            raise self._error[0]
        return self._value[0]
