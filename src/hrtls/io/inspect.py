"""A factual summary of a session: streams, rates, gaps, observations, suspected unit problems."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.data import SensorSeries, Session
from hrtls.units import (
    suspect_accelerometer_unit,
    suspect_gyroscope_unit,
    suspect_magnetometer_unit,
)


@dataclass(frozen=True, slots=True)
class StreamSummary:
    """One stream or observation file."""

    name: str
    samples: int
    start_s: float
    end_s: float
    rate_hz: float
    gaps: int
    longest_gap_s: float
    detail: str = ""


@dataclass(frozen=True, slots=True)
class SessionSummary:
    """What ``hrtls info`` prints."""

    start_s: float
    end_s: float
    streams: list[StreamSummary]
    sensors: list[str]
    landmarks: dict[str, int]
    unknown_ids: dict[str, list[str]]
    unit_problems: list[str]
    has_truth: bool
    checkpoints: int
    georeferenced: bool
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        """Span from the earliest to the latest time, s."""
        return self.end_s - self.start_s


def _series_summary(name: str, t: np.ndarray, detail: str = "", *, gap_factor: float = 3.0
                    ) -> StreamSummary:
    if len(t) == 0:
        return StreamSummary(name, 0, np.nan, np.nan, 0.0, 0, 0.0, detail)
    dt = np.diff(t)
    pos = dt[dt > 0]
    median = float(np.median(pos)) if len(pos) else 0.0
    if not np.isfinite(gap_factor):
        # observation files repeat times (one scan, many readings): report the mean rate
        span = float(t[-1] - t[0])
        rate = (len(t) - 1) / span if span > 0 else 0.0
        return StreamSummary(name, len(t), float(t[0]), float(t[-1]), rate, 0, 0.0, detail)
    gap_mask = dt > gap_factor * median if median > 0 else np.zeros(len(dt), dtype=bool)
    return StreamSummary(
        name=name, samples=len(t), start_s=float(t[0]), end_s=float(t[-1]),
        rate_hz=1.0 / median if median > 0 else 0.0, gaps=int(gap_mask.sum()),
        longest_gap_s=float(dt[gap_mask].max()) if gap_mask.any() else 0.0, detail=detail)


def summarize(session: Session) -> SessionSummary:
    """Summarize a session (read it with ``check_units=False`` to see unit problems here)."""
    streams: list[StreamSummary] = []
    problems: list[str] = []
    sensors: list[str] = []
    imu = session.imu
    if imu is not None:
        sensors = imu.sensors
        checks = (("accelerometer", imu.accel, suspect_accelerometer_unit),
                  ("gyroscope", imu.gyro, suspect_gyroscope_unit),
                  ("magnetometer", imu.mag, suspect_magnetometer_unit))
        for label, series, check in checks:
            if series is None:
                continue
            streams.append(_series_summary(label, series.t, _vector_detail(series)))
            message = check(series.values)
            if message:
                problems.append(f"{label}: {message}")
    for label, part in (("pressure", session.pressure), ("orientation", session.orientation)):
        if part is not None:
            streams.append(_series_summary(label, part.t))
    observations: tuple[tuple[str, Any], ...] = (
        ("fixes", session.fixes), ("rss", session.rss), ("tags", session.tags),
        ("ranges", session.ranges), ("truth", session.truth),
        ("checkpoints", session.checkpoints))
    for label, obs in observations:
        if obs is None:
            continue
        detail = ""
        if label == "rss" and session.rss is not None:
            detail = f"{len(np.unique(session.rss.anchor))} anchors"
        elif label == "tags" and session.tags is not None:
            detail = f"{len(np.unique(session.tags.tag))} tags"
        elif label == "ranges" and session.ranges is not None:
            detail = f"{len(np.unique(session.ranges.node))} nodes"
        streams.append(_series_summary(label, obs.t, detail, gap_factor=np.inf))
    kinds: dict[str, int] = {}
    for landmark in session.landmarks.values():
        kinds[landmark.kind] = kinds.get(landmark.kind, 0) + 1
    start, end = session.time_span()
    return SessionSummary(
        start_s=start, end_s=end, streams=streams, sensors=sensors, landmarks=kinds,
        unknown_ids=session.unknown_ids(), unit_problems=problems,
        has_truth=session.truth is not None,
        checkpoints=0 if session.checkpoints is None else len(session.checkpoints),
        georeferenced=session.meta.georeference is not None, notes=list(session.meta.notes))


def _vector_detail(series: SensorSeries) -> str:
    norm = np.linalg.norm(series.values, axis=1)
    return f"median |v| {np.median(norm):.3g}"
