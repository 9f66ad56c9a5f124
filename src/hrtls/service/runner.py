"""Where the agents' trackers run: a small interface and the in-process implementation.

The host (:mod:`hrtls.service.host`) decides *what* to feed (order, re-runs, snapshots); a
runner only keeps one :class:`hrtls.pipeline.Tracker` per agent and does the work. Arguments
and results are plain picklable values (:class:`AgentSpec`, :class:`~hrtls.service.batches.Batch`,
bytes, :class:`Rows`), so another implementation can keep the trackers elsewhere (e.g. one Ray
actor per agent) behind the same methods.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import msgpack
import numpy as np

from hrtls.data import Landmark, Session
from hrtls.data.series import ImuStream, SensorSeries
from hrtls.data.session import SessionMeta
from hrtls.errors import InputError
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.live import ready_to_start
from hrtls.pipeline.output import Estimates
from hrtls.service.batches import Batch, to_chunk
from hrtls.service.settings import Settings


@dataclass(frozen=True)
class AgentSpec:
    """What a tracker of one agent is built from: preset, session metadata, landmarks (JSON).

    ``landmarks`` hold from the start; ``versions`` (each with its ``updated`` time, in time
    order) from their times on (:mod:`hrtls.service.landmark_versions`). ``kind``: ``rescuer``
    or ``robot`` (when its tracker starts: :func:`hrtls.pipeline.live.ready_to_start`).
    """

    agent_id: int
    preset: str
    meta: dict[str, Any]
    landmarks: tuple[dict[str, Any], ...] = ()
    versions: tuple[dict[str, Any], ...] = ()
    kind: str = "rescuer"


@dataclass(frozen=True)
class Rows:
    """Output of one feed: rows that are final and the provisional last row (may change)."""

    final: Estimates | None
    provisional: Estimates | None
    t_final: float


class FeedFailed(RuntimeError):
    """An agent's tracker raised in :meth:`TrackerRunner.feed_many` (the message names it)."""


class StaleSnapshot(Exception):
    """A snapshot lacks a landmark version from before the data it had consumed."""




@dataclass
class _Agent:
    tracker: Tracker | None
    preset: str
    meta: SessionMeta
    landmarks: dict[str, Landmark]
    versions: list[Landmark]
    t_final: float = -math.inf
    held: list[Session] = field(default_factory=list)
    carried: Estimates | None = None
    robot: bool = False


class TrackerRunner(Protocol):
    """Hosts one tracker per agent."""

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        """Prepare agent ``spec.agent_id``: fresh (``state`` None) or restored from ``state``."""

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        """Consume ``batches`` (in time order) and return the rows they produced."""

    def feed_many(self, feeds: dict[int, list[Batch]]) -> dict[int, Rows | Exception]:
        """:meth:`feed` for several agents at once: per agent its rows or what it raised."""

    def snapshot(self, agent_id: int) -> bytes | None:
        """The agent's tracker state (None before its tracker started)."""

    def close(self, agent_id: int) -> None:
        """Forget the agent."""


def make_runner(settings: Settings) -> TrackerRunner:
    """The runner ``settings.engine`` names: here, worker processes or Ray (``hrtls[ray]``)."""
    if settings.engine == "local":
        return InProcessRunner()
    if settings.engine == "processes":
        from hrtls.runner.proc_live import ProcessShardRunner

        return ProcessShardRunner(n_shards=settings.process_shards)
    from hrtls.runner.ray_live import RayShardRunner

    return RayShardRunner.connect(n_shards=settings.ray_shards, address=settings.ray_address)


def _slice(e: Estimates, sl: slice) -> Estimates:
    return Estimates(e.t[sl], e.xyz[sl], e.heading_rad[sl], e.cov_xy[sl], e.var_heading[sl],
                     e.activity[sl], e.since_correction_s[sl], e.floor[sl])


class InProcessRunner:
    """Trackers in this process (the default)."""

    def __init__(self) -> None:
        self._agents: dict[int, _Agent] = {}

    def open(self, spec: AgentSpec, state: bytes | None, t_final: float) -> None:
        """Fresh tracker (started by the first chunk with a motion source) or restored."""
        meta = SessionMeta.model_validate(spec.meta)
        landmarks = {d["id"]: Landmark.model_validate(d) for d in spec.landmarks}
        versions = [Landmark.model_validate(d) for d in spec.versions]
        preset(spec.preset)  # an unknown name fails here, not at the first batch
        tracker, carried = None, None
        if state is not None:
            d = msgpack.unpackb(state, raw=False)
            tracker = Tracker.restore(d["tracker"])
            tracker.keep_attitude = False
            t_final = d["t_final"]
            carried = None if d["carried"] is None else _unpack_rows(d["carried"])
            new = [v for v in versions if not tracker.engine.versions.knows(v)]
            try:
                tracker.update_landmarks(new)
            except InputError as exc:
                raise StaleSnapshot(f"agent {spec.agent_id}: {exc}") from exc
        self._agents[spec.agent_id] = _Agent(tracker, spec.preset, meta, landmarks, versions,
                                             t_final, carried=carried,
                                             robot=spec.kind == "robot")

    def feed(self, agent_id: int, batches: list[Batch]) -> Rows:
        """Feed the chunks of ``batches``; rows after the last final row.

        The tracker starts once ``RATE_SAMPLES`` accelerometer samples are in
        (:func:`hrtls.pipeline.live.ready_to_start`; its nominal rate
        is their median spacing, as offline); the chunks until then are held and then fed.
        """
        a = self._agents[agent_id]
        for batch in batches:
            chunk = to_chunk(batch, a.meta, a.landmarks)
            if chunk is None:
                continue
            if a.tracker is not None:
                a.tracker.update(chunk)
                continue
            a.held.append(chunk)
            if _ready(a.held, robot=a.robot):
                a.tracker = Tracker(preset(a.preset), keep_attitude=False)
                a.tracker.start_session(_start_session(a.held))
                a.tracker.update_landmarks(a.versions)
                for held in a.held:
                    a.tracker.update(held)
                a.held = []
        if a.tracker is None:
            return Rows(None, None, a.t_final)
        rows = a.tracker.estimates_since(a.t_final)
        if a.carried is not None:
            # the row that was provisional at the snapshot is hidden after a restore unless a
            # row at its time replaces it: report it as the uninterrupted tracker would
            if len(rows) == 0:
                return Rows(None, a.carried, a.t_final)
            if rows.t[0] > a.carried.t[0]:
                rows = _concat(a.carried, rows)
            a.carried = None
        if len(rows) == 0:
            return Rows(None, None, a.t_final)
        final = _slice(rows, slice(0, len(rows) - 1)) if len(rows) > 1 else None
        if final is not None:
            a.t_final = float(final.t[-1])
        return Rows(final, _slice(rows, slice(len(rows) - 1, None)), a.t_final)

    def feed_many(self, feeds: dict[int, list[Batch]]) -> dict[int, Rows | Exception]:
        """Feed each agent; its rows, or the exception its tracker raised (others go on)."""
        return feed_each(self.feed, feeds)

    def snapshot(self, agent_id: int) -> bytes | None:
        """The tracker state with the rows not yet final, or None before the tracker started."""
        a = self._agents[agent_id]
        if a.tracker is None:
            return None
        rows = a.tracker.estimates_since(a.t_final)
        if a.carried is not None and (len(rows) == 0 or rows.t[0] > a.carried.t[0]):
            rows = _concat(a.carried, rows)
        carried = None if len(rows) == 0 else _pack_rows(_slice(rows, slice(len(rows) - 1,
                                                                            None)))
        return bytes(msgpack.packb({"tracker": a.tracker.snapshot(), "t_final": a.t_final,
                                    "carried": carried}))

    def close(self, agent_id: int) -> None:
        """Drop the agent's tracker."""
        self._agents.pop(agent_id, None)


def feed_each(feed: Callable[[int, list[Batch]], Rows],
              feeds: dict[int, list[Batch]]) -> dict[int, Rows | Exception]:
    """``feed`` per agent; one whose tracker raises gets :class:`FeedFailed`, the rest go on."""
    out: dict[int, Rows | Exception] = {}
    for agent_id, batches in feeds.items():
        try:
            out[agent_id] = feed(agent_id, batches)
        except Exception as exc:   # as text: any exception crosses a process boundary
            out[agent_id] = FeedFailed(f"{type(exc).__name__}: {exc}")
    return out


_FIELDS = ("t", "xyz", "heading_rad", "cov_xy", "var_heading", "activity",
           "since_correction_s", "floor")


def _concat(a: Estimates, b: Estimates) -> Estimates:
    return Estimates(*(np.concatenate([getattr(a, f), getattr(b, f)]) for f in _FIELDS))


def _pack_rows(e: Estimates) -> dict[str, Any]:
    return {f: getattr(e, f).tolist() for f in _FIELDS}


def _unpack_rows(d: dict[str, Any]) -> Estimates:
    ints = ("activity", "floor")
    return Estimates(*(np.asarray(d[f], dtype=np.int64 if f in ints else np.float64)
                       for f in _FIELDS))


def _ready(held: list[Session], *, robot: bool) -> bool:
    n_acc = sum(len(c.imu.accel.t) for c in held if c.imu is not None)
    poses = sum(len(c.fixes.t) for c in held if c.fixes is not None) if robot else None
    return ready_to_start(accel_samples=n_acc,
                          span_s=held[-1].time_span()[1] - held[0].time_span()[0],
                          robot_poses=poses)


def _start_session(held: list[Session]) -> Session:
    """The first chunk with the held accelerometer times: what ``start_session`` reads."""
    first = held[0]
    imus = [c.imu for c in held if c.imu is not None]
    if not imus:
        return first
    acc = SensorSeries(np.concatenate([i.accel.t for i in imus]),
                       np.concatenate([i.accel.values for i in imus]), "accelerometer")
    gyro = None if imus[0].gyro is None else SensorSeries(acc.t, np.zeros_like(acc.values))
    mag = None if imus[0].mag is None else SensorSeries(acc.t, np.zeros_like(acc.values))
    return first.with_parts(imu=ImuStream(acc, gyro, mag, check_units=False))


def activity_label(code: int) -> str:
    """Lower-case activity name of a code (``unknown`` for unknown codes)."""
    from hrtls.data import Activity

    try:
        return Activity(int(code)).label
    except ValueError:
        return "unknown"


def finite_or_none(value: float) -> float | None:
    """JSON-friendly: None for inf/NaN."""
    return float(value) if np.isfinite(value) else None
