"""Track a session into a result folder, and score it when the session has ground truth."""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import ImuStream, Session
from hrtls.data.clocks import ClockStream, check_clocks
from hrtls.errors import InputError, RepairWarning
from hrtls.evaluate.report import EvaluationInputs, build_report
from hrtls.io.geojson import write_geojson
from hrtls.io.session import TableFormat
from hrtls.io.stream import DEFAULT_CHUNK_ROWS, NotStreamable, SessionStream, open_stream
from hrtls.io.tables import write_steps, write_trajectory
from hrtls.pipeline.barometric import apply_baro_floors, with_baro_floors
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import Tracker, TrackResult

OUTPUT_FILES = ("trajectory.csv", "steps.csv", "trajectory.parquet", "steps.parquet",
                "trajectory.geojson", "report.json")


@dataclass(frozen=True, slots=True)
class TrackRun:
    """A tracked recording.

    ``session`` holds, when streamed, only the first IMU chunk, and ``result.attitude`` is
    None (the per-sample attitude is not kept); ``tracker_s`` is the time spent in the tracker
    alone; ``streamed`` tells whether the IMU was read in chunks.
    """

    result: TrackResult
    session: Session
    samples: int
    tracker_s: float
    streamed: bool


def streams(config: TrackerConfig) -> bool:
    """True when ``config`` needs no samples at :meth:`Tracker.start`.

    The hand-held mounting and the hard-iron fit need the accelerometer and magnetometer over
    their windows.
    """
    return config.attitude.mounting != "handheld" and config.attitude.mag_hard_iron != "fit"


def check_output_dir(out_dir: Path, *, overwrite: bool = False) -> None:
    """Refuse, before any work, an output that is a file or a folder holding results."""
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError("is a file", where=str(out_dir),
                         expected="a folder for the results (a new or an empty one)")
    existing = [n for n in OUTPUT_FILES if (out_dir / n).exists()]
    if existing and not overwrite:
        raise InputError(f"already holds results ({', '.join(existing)})", where=str(out_dir),
                         expected="an empty or new folder (or --overwrite)")


def track_recording(path: Path, config: TrackerConfig, *, repair: bool = False,
                    beacons: Path | None = None, chunk_rows: int = DEFAULT_CHUNK_ROWS,
                    fmt: str | None = None, trial: str | None = None) -> TrackRun:
    """Track a recording; a session folder or zip is streamed in chunks when it can be.

    Streaming (bounded memory) feeds ``chunk_rows`` IMU rows at a time to
    :meth:`Tracker.update`, which gives the result of :meth:`Tracker.run` on the whole session.
    Other formats and ``repair`` read the whole recording. ``fmt`` (detected when None) and
    ``trial`` are passed to :func:`hrtls.recordings.read_any`. ``result.report["input"]``
    lists the format, every repair warned while reading and the reader's notes (unit
    conversions, clock offsets).
    """
    from hrtls.recordings import detect_format, read_any, reader_options

    fmt = fmt or detect_format(path)
    options = reader_options(fmt, trial=trial)
    stream = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if not repair and beacons is None and fmt == "hrtls-session":
            stream = open_stream(path, chunk_rows=chunk_rows)
            if stream is not None:
                check_clocks([ClockStream(*s) for s in stream.sensor_times()])
        session = None if stream is not None else read_any(path, fmt=fmt, repair=repair,
                                                           beacons=beacons, **options)
    meta = stream.meta if stream is not None else session.meta if session is not None else None
    input_report = _input_report(fmt, caught, [] if meta is None else meta.notes)
    input_report["path"] = str(path)
    t_imu = stream.imu_t if stream is not None else (
        None if session is None or session.imu is None else session.imu.accel.t)
    if t_imu is not None and len(t_imu):
        input_report["imu"] = imu_fingerprint(t_imu)
    if stream is not None:
        try:
            return _with_input(_track_stream(stream, config), input_report)
        except NotStreamable:
            session = read_any(path, fmt=fmt, repair=repair, beacons=beacons, **options)
    assert session is not None
    start = time.perf_counter()
    result = with_baro_floors(Tracker(config).run(session), session, config)
    n = 0 if session.imu is None else len(session.imu.accel)
    run = TrackRun(result, session, n, time.perf_counter() - start, streamed=False)
    return _with_input(run, input_report)


def imu_fingerprint(t: np.ndarray) -> dict[str, float | int]:
    """What identifies a recording's IMU stream: samples and first/last time (s)."""
    return {"samples": len(t), "t_first_s": float(t[0]), "t_last_s": float(t[-1])}


def _input_report(fmt: str, caught: list[warnings.WarningMessage], notes: list[str]
                  ) -> dict[str, Any]:
    """What reading did: format, repairs (warned again here) and the reader's notes."""
    repairs: list[str] = []
    for w in caught:
        text = str(w.message)
        if issubclass(w.category, RepairWarning) and text not in repairs:
            repairs.append(text)
        warnings.warn(w.message, w.category, stacklevel=3)
    return {"format": fmt, "repairs": repairs, "notes": list(notes)}


def _with_input(run: TrackRun, input_report: dict[str, Any]) -> TrackRun:
    run.result.report["input"] = input_report
    return run


def _track_stream(stream: SessionStream, config: TrackerConfig) -> TrackRun:
    tracker = Tracker(config, keep_attitude=False)
    if streams(config):
        tracker.start(stream.meta, stream.landmarks, has_imu=True, has_gyro=stream.has_gyro,
                      has_mag=stream.has_mag,
                      has_orientation=stream.parts["orientation"] is not None,
                      rate_hz=stream.rate_hz, t0=stream.t0)
    else:
        # the hand-held mounting and the hard-iron fit look at the whole accelerometer and
        # magnetometer: read those columns alone, once
        tracker.start_session(stream.session(stream.start_imu()))
    first: ImuStream | None = None
    seconds = 0.0
    for chunk in stream.chunks():
        first = first or chunk.imu
        start = time.perf_counter()
        tracker.update(chunk)
        seconds += time.perf_counter() - start
    start = time.perf_counter()
    result = tracker.finish()
    result = apply_baro_floors(result, stream.parts.get("pressure"),
                               floor_height_m=stream.meta.floor_height_m,
                               enabled=config.barometer)
    seconds += time.perf_counter() - start
    del tracker
    assert first is not None
    # the ground truth is read only now, for the evaluation: it is not held while tracking
    session = stream.session(first).with_parts(truth=stream.truth())
    return TrackRun(result, session, stream.n_rows, seconds, streamed=True)


def write_track_outputs(result: TrackResult, session: Session, out_dir: Path, *,
                        overwrite: bool = False, plot: bool = False,
                        evaluation: dict[str, Any] | None = None,
                        table_format: TableFormat = "csv") -> list[Path]:
    """Write trajectory, steps (``.csv`` or ``.parquet``), geojson, report (and track.png)."""
    if table_format not in ("csv", "parquet"):
        raise InputError(f"{table_format!r}", where="--format-out", expected="csv or parquet")
    check_output_dir(out_dir, overwrite=overwrite)
    out_dir.mkdir(parents=True, exist_ok=True)
    geo = session.georeference
    written = [
        write_trajectory(result.trajectory, out_dir / f"trajectory.{table_format}",
                         georeference=geo),
        write_steps(result.steps, out_dir / f"steps.{table_format}"),
        write_geojson(result.trajectory, out_dir / "trajectory.geojson", steps=result.steps,
                      landmarks=session.resolved_landmarks() if geo else session.landmarks,
                      georeference=geo, time_origin_unix_s=session.meta.time_origin_unix_s,
                      overwrite=True),
    ]
    report = dict(result.report)
    if evaluation is not None:
        report["evaluation"] = evaluation
    (out_dir / "report.json").write_text(json.dumps(report, indent=2, default=float) + "\n",
                                         encoding="utf-8")
    written.append(out_dir / "report.json")
    if plot:
        from hrtls.evaluate.floor_plots import plot_track_by_floor

        written.append(plot_track_by_floor(
            out_dir / "track.png", result.trajectory, session.truth,
            floor_height_m=session.meta.floor_height_m,
            checkpoints=session.checkpoints, landmarks=_positioned(session),
            fixes_xy=None if session.fixes is None else session.fixes.xyz[:, :2],
            title=f"hrtls track ({result.report['config']['name']})", ellipses=25))
    return written


def _positioned(session: Session) -> dict[str, Any]:
    geo = session.georeference
    return {k: lm.resolved(geo) for k, lm in session.landmarks.items()
            if lm.position is not None or geo is not None}


def evaluate_track(result: TrackResult, session: Session,
                   reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """Evaluation report against the session's truth/checkpoints (None without ground truth)."""
    if session.truth is None and session.checkpoints is None:
        return None
    return build_report(EvaluationInputs(estimate=result.trajectory, estimated_steps=result.steps,
                                         truth=session.truth, checkpoints=session.checkpoints,
                                         reference=reference or {}))
