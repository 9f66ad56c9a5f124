"""Per-agent buffers of a live mission: data arrive in parts, windows are cut from them.

:class:`AgentBuffer` holds one agent's data not yet consumed by the mission's windows (a
:class:`~hrtls.data.Session` with the agent's metadata and landmarks), its latest data time and
the clock reading of its latest part (silence). :func:`merge` joins two parts of one agent in
time order; :func:`split_at` cuts a part at the processed horizon (what is before it is late).

The IMU of a part must come aligned (gyroscope and magnetometer on the accelerometer's times),
as a live device delivers it; :class:`AgentBuffer` aligns a part that is not (within the part).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Set
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.pipeline.chunks import aligned_imu, session_window
from hrtls.pipeline.live import ready_to_start

DATA_PARTS = ("imu", "pressure", "orientation", "fixes", "rss", "tags", "ranges")
"""Session parts a buffer merges (ground truth and checkpoints are kept from the first part)."""


@dataclass(frozen=True)
class LateData:
    """Samples of ``agent`` older than the processed horizon: the mission did not use them.

    ``t_first_s``, ``t_last_s``: time span of the late samples; ``horizon_s``: end of the last
    processed window; ``samples``: how many samples and observations were late.
    """

    agent: str
    t_first_s: float
    t_last_s: float
    horizon_s: float
    samples: int


def _order(t: NDArray[np.float64], unique: bool) -> NDArray[np.int64]:
    """Indices putting ``t`` in time order (stable); the first of equal times when ``unique``."""
    idx = np.argsort(t, kind="stable")
    if unique and len(idx) > 1:
        keep = np.ones(len(idx), dtype=bool)
        keep[1:] = np.diff(t[idx]) > 0
        idx = idx[keep]
    return np.asarray(idx, dtype=np.int64)


def _series(a: SensorSeries | None, b: SensorSeries | None, idx: NDArray[np.int64],
            t: NDArray[np.float64]) -> SensorSeries | None:
    if a is None or b is None:
        return None
    return SensorSeries(t, np.concatenate([a.values, b.values])[idx], a.name)


def _merge_imu(a: ImuStream, b: ImuStream) -> ImuStream:
    t = np.concatenate([a.accel.t, b.accel.t])
    idx = _order(t, unique=True)
    ts = t[idx]
    acc = _series(a.accel, b.accel, idx, ts)
    assert acc is not None
    return ImuStream(acc, _series(a.gyro, b.gyro, idx, ts), _series(a.mag, b.mag, idx, ts),
                     check_units=False)


def _merge_part(name: str, a: object, b: object) -> object:
    """Part ``name`` of two sessions joined in time order."""
    if a is None or b is None:
        return b if a is None else a
    if isinstance(a, ImuStream) and isinstance(b, ImuStream):
        return _merge_imu(a, b)
    if isinstance(a, SensorSeries) and isinstance(b, SensorSeries):
        t = np.concatenate([a.t, b.t])
        idx = _order(t, unique=True)
        return _series(a, b, idx, t[idx])
    if isinstance(a, OrientationSeries) and isinstance(b, OrientationSeries):
        t = np.concatenate([a.t, b.t])
        idx = _order(t, unique=True)
        return OrientationSeries(t[idx], np.concatenate([a.q, b.q])[idx], a.name)
    if isinstance(a, PositionFixes) and isinstance(b, PositionFixes):
        t = np.concatenate([a.t, b.t])
        idx = _order(t, unique=True)
        return PositionFixes(t[idx], np.concatenate([a.xyz, b.xyz])[idx],
                             np.concatenate([a.sigma_m, b.sigma_m])[idx], a.has_z, a.name)
    if isinstance(a, RssReadings) and isinstance(b, RssReadings):
        idx = _order(np.concatenate([a.t, b.t]), unique=False)
        return RssReadings(np.concatenate([a.t, b.t])[idx],
                           np.concatenate([a.anchor, b.anchor])[idx],
                           np.concatenate([a.rss_dbm, b.rss_dbm])[idx], a.name)
    if isinstance(a, TagDetections) and isinstance(b, TagDetections):
        idx = _order(np.concatenate([a.t, b.t]), unique=False)
        return TagDetections(np.concatenate([a.t, b.t])[idx],
                             np.concatenate([a.tag, b.tag])[idx], a.name)
    if isinstance(a, RangeMeasurements) and isinstance(b, RangeMeasurements):
        idx = _order(np.concatenate([a.t, b.t]), unique=False)
        return RangeMeasurements(np.concatenate([a.t, b.t])[idx],
                                 np.concatenate([a.node, b.node])[idx],
                                 np.concatenate([a.range_m, b.range_m])[idx],
                                 np.concatenate([a.sigma_m, b.sigma_m])[idx], a.name)
    raise TypeError(f"cannot merge {name} parts of types {type(a).__name__}, "
                    f"{type(b).__name__}")


def merge(a: Session, b: Session) -> Session:
    """The data of ``a`` and ``b`` (one agent) in time order; metadata and landmarks of ``a``."""
    return a.with_parts(**{k: _merge_part(k, getattr(a, k), getattr(b, k)) for k in DATA_PARTS})


def n_samples(s: Session) -> int:
    """Samples and observations of a session (IMU rows counted once)."""
    n = 0 if s.imu is None else len(s.imu.accel.t)
    for k in DATA_PARTS[1:]:
        part = getattr(s, k)
        if part is not None:
            n += len(part.t)
    return n


def split_at(s: Session, t_s: float) -> tuple[Session | None, Session | None]:
    """``(before, from)``: the data with ``t < t_s`` and those with ``t >= t_s``."""
    if s.time_span()[0] >= t_s:
        return None, s
    return session_window(s, -math.inf, t_s), session_window(s, t_s, math.inf)


def _aligned(s: Session) -> Session:
    imu = s.imu
    if imu is None:
        return s
    same = all(x is None or (len(x.t) == len(imu.accel.t) and np.array_equal(x.t, imu.accel.t))
               for x in (imu.gyro, imu.mag))
    return s if same else s.with_parts(imu=aligned_imu(imu))


class AgentBuffer:
    """One agent's data not yet processed (see module doc)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.data: Session | None = None
        self.t_last = -math.inf
        self.t_first = math.inf
        self.heard_s = -math.inf
        self.ended = False

    def add(self, part: Session, *, horizon_s: float, now_s: float) -> LateData | None:
        """Buffer ``part``; its samples before ``horizon_s`` are returned as late, not kept."""
        late, part_ok = split_at(_aligned(part), horizon_s)
        self.heard_s = max(self.heard_s, now_s)
        out = None
        if late is not None:
            a, b = late.time_span()
            out = LateData(self.name, a, b, horizon_s, n_samples(late))
        if part_ok is None:
            return out
        a, b = part_ok.time_span()
        self.t_first = min(self.t_first, a)
        self.t_last = max(self.t_last, b)
        if self.data is None:
            self.data = part_ok
        else:
            kept = split_at(self.data, horizon_s)[1]
            self.data = part_ok if kept is None else merge(kept, part_ok)
        return out

    def window(self, t_start: float, t_end: float) -> Session | None:
        """The buffered data with ``t_start <= t < t_end``."""
        return None if self.data is None else session_window(self.data, t_start, t_end)


def startable(buf: AgentBuffer, *, robot: bool) -> bool:
    """Whether the buffer holds what the agent's tracker's start reads (rate, first poses)."""
    data = buf.data
    if buf.ended or data is None:
        return True
    a, b = data.time_span()
    return ready_to_start(accel_samples=0 if data.imu is None else len(data.imu.accel.t),
                          span_s=b - a,
                          robot_poses=(0 if data.fixes is None else len(data.fixes.t)) if robot
                          else None)


def window_complete(buffers: Mapping[str, AgentBuffer], t_end: float, *, clock_s: float,
                    silent_after_s: float, unready: Set[str]) -> bool:
    """Whether a window ending at ``t_end`` can be processed.

    Every agent that is neither ended nor silent (last part more than ``silent_after_s`` before
    ``clock_s``) has data at or after ``t_end`` and, if its tracker has not started, enough to
    start it (not in ``unready``); and at least one agent has data at or after ``t_end``.
    """
    if all(b.t_last < t_end for b in buffers.values()):
        return False
    for name, buf in buffers.items():
        if buf.ended or clock_s - buf.heard_s > silent_after_s:
            continue
        if buf.t_last < t_end or (name in unready and buf.t_first < t_end):
            return False
    return True
