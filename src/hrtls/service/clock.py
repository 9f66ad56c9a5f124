"""Wall clock of the service (Unix seconds), replaceable in tests that replay time."""

from __future__ import annotations

import time
from collections.abc import Callable

Clock = Callable[[], float]


def wall_clock() -> float:
    """Unix time, s."""
    return time.time()
