"""The tracker's record of the corrections that moved its position.

For every update that changed the horizontal position (a tag group, a tag bearing, a position
fix, an RSS reading or scan, a range, the magnetic heading measurement; in Python or in the
compiled event loop) the log keeps the time of the output row that holds the corrected state,
the event's kind (:mod:`hrtls.pipeline.schedule` codes), its source (landmark id(s)) and the
horizontal mean and covariance just before and just after it. A reader (the mission's range-SLAM
smoother, :mod:`hrtls.mission.graph`) removes the position jumps from the rows to recover the
dead reckoning, and turns each correction into a factor on the position.

Like the output rows, the records are not part of a snapshot: a restored tracker numbers its
records on from the count at the snapshot (:meth:`CorrectionLog.since` by index), so a reader
that read every record before the snapshot reads none twice.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.pipeline.schedule import BEARING, RANGE, RSS, TAGS

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SMOOTHED = 7
"""Kind of a record of the mission smoother's feedback (:mod:`hrtls.mission.feedback`), after
the :mod:`hrtls.pipeline.schedule` event kinds."""


@dataclass(frozen=True, eq=False)
class Corrections:
    """Corrections of the horizontal position, in order.

    ``t`` (N,): time of the output row holding the corrected state, s; ``kind`` (N,): the
    event's kind (:data:`hrtls.pipeline.schedule.FIX`, ``RSS``, ``TAGS``, ``RANGE``, ``BEARING``,
    ``MAGNETIC``); ``source`` (N,): landmark id(s), comma-separated; ``mean0_m`` / ``mean1_m``
    (N, 2): position before / after, m; ``cov0_m2`` / ``cov1_m2`` (N, 2, 2): its covariance
    before / after, m^2; ``next_index``: the index to read from next time.
    """

    t: FloatArray
    kind: IntArray
    source: NDArray[np.str_]
    mean0_m: FloatArray
    cov0_m2: FloatArray
    mean1_m: FloatArray
    cov1_m2: FloatArray
    next_index: int

    def __len__(self) -> int:
        return len(self.t)


class CorrectionLog:
    """Accumulated correction records, in blocks; ``base``: records before a restore."""

    def __init__(self, base: int = 0) -> None:
        self.base = base
        self.t: list[FloatArray] = []
        self.kind: list[IntArray] = []
        self.source: list[NDArray[np.str_]] = []
        self.before: list[FloatArray] = []
        self.after: list[FloatArray] = []

    def count(self) -> int:
        """Records so far, those before a restore included."""
        return self.base + sum(len(t) for t in self.t)

    def add_block(self, t: FloatArray, kind: IntArray, source: NDArray[np.str_],
                  before: FloatArray, after: FloatArray) -> None:
        """Records of one run: ``before`` / ``after`` (N, 5) rows ``[x, y, P00, P01, P11]``."""
        if len(t):
            self.t.append(np.asarray(t, np.float64))
            self.kind.append(np.asarray(kind, np.int64))
            self.source.append(np.asarray(source).astype(str))
            self.before.append(np.asarray(before, np.float64).reshape(-1, 5))
            self.after.append(np.asarray(after, np.float64).reshape(-1, 5))

    def add(self, t: float, kind: int, source: str, x0: FloatArray, p0: FloatArray,
            x1: FloatArray, p1: FloatArray) -> None:
        """One record when the position moved: states and covariances before and after."""
        if x1[0] == x0[0] and x1[1] == x0[1]:
            return
        self.add_block(np.array([t]), np.array([kind]), np.array([source]),
                       row5(x0, p0)[None, :], row5(x1, p1)[None, :])

    def since(self, index: int) -> Corrections:
        """The records from number ``index`` on (those before a restore are gone)."""
        if len(self.t) > 1:
            for name in ("t", "kind", "source", "before", "after"):
                setattr(self, name, [np.concatenate(getattr(self, name))])
        n = self.count()
        k = max(index - self.base, 0)
        if not self.t:
            e = np.zeros(0)
            return Corrections(e, np.zeros(0, np.int64), np.zeros(0, str), np.zeros((0, 2)),
                               np.zeros((0, 2, 2)), np.zeros((0, 2)), np.zeros((0, 2, 2)), n)
        b, a = self.before[0][k:], self.after[0][k:]
        return Corrections(self.t[0][k:], self.kind[0][k:], self.source[0][k:], b[:, :2],
                           _cov(b), a[:, :2], _cov(a), n)


def row5(x: FloatArray, p: FloatArray) -> FloatArray:
    """``[x, y, P00, P01, P11]`` of a state and its covariance."""
    return np.array([x[0], x[1], p[0, 0], p[0, 1], p[1, 1]], np.float64)


def _cov(rows: FloatArray) -> FloatArray:
    out = np.empty((len(rows), 2, 2))
    out[:, 0, 0] = rows[:, 2]
    out[:, 0, 1] = out[:, 1, 0] = rows[:, 3]
    out[:, 1, 1] = rows[:, 4]
    return out


def source_of(kind: int, payload: Any) -> str:
    """The landmark id(s) of a slow event's payload (:mod:`hrtls.pipeline.schedule` kinds)."""
    if kind == TAGS:
        return ",".join(str(i) for i in payload)
    if kind in (BEARING, RANGE):
        return str(payload[0])
    if kind == RSS:   # ("reading", anchor, ...) or ("scan", readings)
        return str(payload[1]) if payload[0] == "reading" else ",".join(payload[1].anchor)
    return ""

