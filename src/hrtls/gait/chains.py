"""Chaining events into runs across short gaps (walks of steps, walking bouts).

Events (times, increasing) belong to one chain while consecutive events are at most
``max_gap_s`` apart; a longer gap starts a new chain.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.gait._state import FloatArray


def chain_starts(t: FloatArray, *, max_gap_s: float,
                 t_before_s: float = -math.inf) -> NDArray[np.bool_]:
    """Whether each event of ``t`` starts a new chain (``t_before_s``: the last earlier event).

    The first event starts a chain when it follows ``t_before_s`` by more than ``max_gap_s``
    (always for ``-inf``: no earlier event).
    """
    return np.diff(np.asarray(t, dtype=np.float64), prepend=t_before_s) > max_gap_s


def chain_runs(t: FloatArray, *, max_gap_s: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``(starts, ends)``: index ranges ``t[a:b]`` of the chains of ``t`` (half-open)."""
    n = np.asarray(t).shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    starts = np.flatnonzero(chain_starts(t, max_gap_s=max_gap_s)).astype(np.int64)
    ends = np.append(starts[1:], n).astype(np.int64)
    return starts, ends


__all__ = ["chain_runs", "chain_starts"]
