"""Feed a GaitAnalyzer in chunks with a save/restore between them (the live service's path)."""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable, Sequence

import numpy as np

from hrtls.gait.analyzer import GaitAnalyzer, GaitResult


def run_with_restarts(make: Callable[[], GaitAnalyzer], t: np.ndarray, acc: np.ndarray,
                      q: np.ndarray | None, bounds: Sequence[int]) -> GaitResult:
    """Chunks ``[bounds[i], bounds[i+1])``; after each, the state goes through JSON into a
    fresh analyzer from ``make``; the results are joined after the final flush."""
    ga = make()
    parts = []
    for a, b in itertools.pairwise(bounds):
        parts.append(ga.update(t[a:b], acc[a:b], None if q is None else q[a:b]))
        state = json.loads(json.dumps(ga.state(), allow_nan=False))
        ga = make()
        ga.restore(state)
    parts.append(ga.flush())
    return GaitResult.concat(parts)
