"""Landmarks updated during a mission (Inderst Sec. 3.2: "information updated during rescue tasks").

A location message can change while the team is inside: a tag is found moved, a node destroyed,
a hazard reported next to a landmark. Each new version carries its time in ``updated`` (s, on
the session clock) and holds for every reading from that time on:

* readings are cut at the update times (:meth:`LandmarkVersions.cut`), so the readings queued
  before an update keep the version they were queued with and the later ones get the new one;
* the observations looked up when they are applied (tag groups, bearings, single ranges and
  RSS readings) take the version in force at their own time (:meth:`LandmarkVersions.at`), even
  when the update was applied before them;
* a ``destroyed`` landmark corrects nothing from its time on (its readings are skipped with
  that reason); ``hazard`` is information for the people, not for the filter.

The versions applied so far and the ones still pending are plain JSON, kept in snapshots.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Iterator
from typing import Any

from hrtls.data import Landmark, Session
from hrtls.errors import InputError
from hrtls.pipeline.chunks import aligned_imu, session_window

__all__ = ["LandmarkVersions"]


class LandmarkVersions:
    """Pending and applied versions of the landmarks that changed after the start."""

    def __init__(self) -> None:
        self.pending: list[Landmark] = []
        self.history: dict[str, list[tuple[float, Landmark | None]]] = {}

    def add(self, landmarks: Iterable[Landmark], *, t_now: float) -> None:
        """Queue new versions; each needs its time ``updated`` (s), not before ``t_now``."""
        for lm in landmarks:
            if lm.updated is None or not math.isfinite(lm.updated):
                raise InputError(f"landmark {lm.id!r} without 'updated'", where="landmark update",
                                 expected="the time (s, session clock) the new version holds from")
            if lm.updated < t_now:
                raise InputError(f"landmark {lm.id!r} updated at {lm.updated:.3f} s",
                                 where="landmark update",
                                 expected=f"a time not before the data already tracked "
                                          f"({t_now:.3f} s)")
            self.pending.append(lm)
        self.pending.sort(key=lambda v: float(v.updated or 0.0))

    def knows(self, version: Landmark) -> bool:
        """Whether a version of that landmark at that time is pending or applied."""
        t_u = version.updated
        return any(v.id == version.id and v.updated == t_u for v in self.pending) \
            or any(t == t_u for t, _ in self.history.get(version.id, ())[1:])

    def cut(self, chunk: Session, t_end: float) -> Iterator[tuple[Session | None, list[Landmark]]]:
        """The chunk cut at the pending update times before ``t_end`` (its last time, s).

        Yields ``(piece, due)``: the part of the chunk before the next update time (None when
        empty) and the versions to apply after it; the last piece comes with no versions.
        """
        rest: Session | None = chunk
        if self.pending and float(self.pending[0].updated or 0.0) <= t_end \
                and chunk.imu is not None:
            # gyroscope / magnetometer on the accelerometer's times before cutting, as the
            # uncut chunk is consumed (interpolating inside each piece differs at the cut)
            rest = chunk.with_parts(imu=aligned_imu(chunk.imu))
        while self.pending and float(self.pending[0].updated or 0.0) <= t_end and rest:
            t_u = float(self.pending[0].updated or 0.0)
            due = [v for v in self.pending if float(v.updated or 0.0) == t_u]
            self.pending = self.pending[len(due):]
            yield session_window(rest, -math.inf, t_u), due
            rest = session_window(rest, t_u, math.inf)
        yield rest, []

    def applied(self, version: Landmark, previous: Landmark | None) -> str:
        """Record that ``version`` replaced ``previous`` (None: new); a note for the report."""
        t_u = float(version.updated or 0.0)
        steps = self.history.setdefault(version.id, [(-math.inf, previous)])
        steps.append((t_u, None if version.status == "destroyed" else version))
        text = f"landmark {version.id!r} "
        if version.status == "destroyed":
            return text + f"destroyed at {t_u:.2f} s: its readings no longer correct"
        text += f"{'added' if previous is None else 'updated'} at {t_u:.2f} s"
        if previous is not None and version.position is not None \
                and previous.position is not None:
            text += f" (moved {math.dist(version.position, previous.position):.2f} m)"
        return text + (f"; hazard nearby: {version.hazard}" if version.hazard else "")

    def _step(self, landmark_id: str, t: float) -> int | None:
        """Index of the version in force at ``t`` in the landmark's history (None: none)."""
        steps = self.history.get(landmark_id)
        if steps is None:
            return None
        return max(bisect.bisect_right(steps, t, key=lambda s: s[0]) - 1, 0)

    def at(self, current: dict[str, Landmark], landmark_id: str, t: float) -> Landmark | None:
        """The version of ``landmark_id`` in force at ``t`` (None: unknown or destroyed)."""
        k = self._step(landmark_id, t)
        return current.get(landmark_id) if k is None else self.history[landmark_id][k][1]

    def destroyed_at(self, landmark_id: str, t: float) -> bool:
        """Whether ``landmark_id`` was destroyed at ``t``."""
        k = self._step(landmark_id, t)
        return bool(k) and self.history[landmark_id][k or 0][1] is None

    def state(self) -> dict[str, Any]:
        """Plain state for a snapshot."""
        def dump(v: Landmark | None) -> dict[str, Any] | None:
            return None if v is None else v.model_dump(mode="json")

        return {"pending": [v.model_dump(mode="json") for v in self.pending],
                "history": {k: [[None if math.isinf(t) else t, dump(v)] for t, v in steps]
                            for k, steps in self.history.items()}}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state`."""
        def load(v: dict[str, Any] | None) -> Landmark | None:
            return None if v is None else Landmark.model_validate(v)

        self.pending = [Landmark.model_validate(v) for v in state["pending"]]
        self.history = {k: [(-math.inf if t is None else float(t), load(v)) for t, v in steps]
                        for k, steps in state["history"].items()}
