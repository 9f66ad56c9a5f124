"""Floors in the mission loop (:class:`hrtls.mission.tracker.MissionTracker`).

An agent's floor is that of its causal estimate rows (its tracker's ``floor``: barometer or step
model, never the truth); :class:`FloorLog` keeps the times it changed. A reading keeps the
agent's floor at its time. A node's floor is the floor most of its readings were taken on (ties:
the lowest), :func:`node_floor`; its estimate uses the readings of that floor only (the slab
blocks the radio between floors, so a reading from another floor comes from a wrong floor
estimate). An agent uses a localized node only while it is on the node's floor.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.data.session import SessionMeta

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass
class FloorLog:
    """An agent's floor over time: the row times where it changed and the new floors.

    Before the first logged change the agent is on floor 0 (its start).
    """

    t: list[float] = field(default_factory=list)
    floor: list[int] = field(default_factory=list)

    def add(self, t_s: FloatArray, floor: IntArray) -> None:
        """Rows ``(t_s, floor)`` in time order; they replace logged changes at or after t_s[0]."""
        if not len(t_s):
            return
        keep = int(np.searchsorted(np.asarray(self.t, dtype=np.float64), t_s[0], side="left"))
        del self.t[keep:], self.floor[keep:]
        prev = np.concatenate([[self.now()], floor[:-1]])
        moved = np.flatnonzero(floor != prev)
        self.t.extend(np.asarray(t_s)[moved].tolist())
        self.floor.extend(np.asarray(floor)[moved].astype(int).tolist())

    def now(self) -> int:
        """The floor of the latest row."""
        return self.floor[-1] if self.floor else 0

    def at(self, t_s: FloatArray) -> IntArray:
        """The floor at times ``t_s``: that of the latest row at or before each."""
        floors = np.asarray([0, *self.floor], dtype=np.int64)
        return floors[np.searchsorted(np.asarray(self.t, dtype=np.float64), t_s, side="right")]


def node_floor(floors: Sequence[int] | IntArray) -> int:
    """The floor most readings were taken on (ties: the lowest; 0 without readings)."""
    if not len(floors):
        return 0
    values, counts = np.unique(np.asarray(floors, dtype=np.int64), return_counts=True)
    return int(values[int(np.argmax(counts))])


def on_node_floor(node: NDArray[np.str_], floor: IntArray,
                  earlier: Mapping[str, Mapping[int, int]] | None = None
                  ) -> tuple[NDArray[np.bool_], dict[str, int]]:
    """Which readings are on their node's floor, and each node's floor (:func:`node_floor`).

    ``node``, ``floor``: each reading's node and floor; ``earlier``: per node, readings no
    longer listed (floor -> count) that still count for its floor.
    """
    earlier = earlier or {}
    keep = np.zeros(len(node), dtype=bool)
    floors: dict[str, int] = {}
    for n in np.unique(node).tolist():
        m = node == n
        old = earlier.get(str(n), {})
        counted = np.repeat(np.fromiter(old.keys(), np.int64, len(old)),
                            np.fromiter(old.values(), np.int64, len(old)))
        floors[str(n)] = node_floor(np.concatenate([floor[m], counted]))
        keep[m] = floor[m] == floors[str(n)]
    return keep, floors


def building_floor_height_m(heights_m: Sequence[float]) -> float:
    """The floor height the mission shares nodes with: the agents' first, else the default."""
    default = SessionMeta.model_fields["floor_height_m"].default
    return float(heights_m[0]) if len(heights_m) else float(default)
