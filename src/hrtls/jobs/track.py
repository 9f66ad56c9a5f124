"""Track a session into a result folder, and score it when the session has ground truth."""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import GroundTruth, ImuStream, Session
from hrtls.data.clocks import ClockStream, check_clocks
from hrtls.errors import InputError, RepairWarning
from hrtls.evaluate.report import EvaluationInputs, build_report
from hrtls.io.background import Background, read_ahead
from hrtls.io.geojson import write_geojson, write_local_geojson
from hrtls.io.session import TableFormat
from hrtls.io.stream import DEFAULT_CHUNK_ROWS, NotStreamable, SessionStream, open_stream
from hrtls.io.tables import write_steps, write_trajectory
from hrtls.pipeline.build import RATE_SAMPLES, leading_rate_hz
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.finish import finish_track
from hrtls.pipeline.gap_uncertainty import widen_over_gaps
from hrtls.pipeline.mounting import declared_handheld
from hrtls.pipeline.tracker import Tracker, TrackResult
from hrtls.pipeline.unobservable_heading import widen_unobservable_heading

LOCAL_GEOJSON = "trajectory.local.json"
"""The track of a recording without a georeference (local metres, not RFC 7946)."""
OUTPUT_FILES = ("trajectory.csv", "steps.csv", "trajectory.parquet", "steps.parquet",
                "trajectory.geojson", LOCAL_GEOJSON, "report.json")


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
    """True when a session folder or zip is tracked chunk by chunk with ``config``.

    :meth:`Tracker.start` looks at no samples (the hand-held mounting and the hard iron are
    estimated as the samples arrive); only ``[offline] two_pass`` fits them on the whole
    recording first, which :meth:`Tracker.run` does on the session read whole (as
    ``[offline] grid_smoother`` smooths the grid's rows).
    """
    return not config.offline.whole_recording


def check_output_dir(out_dir: Path, *, overwrite: bool = False) -> None:
    """Refuse, before any work, an output that is a file or a folder holding results."""
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError("is a file", where=str(out_dir),
                         expected="a folder for the results (a new or an empty one)")
    existing = [n for n in OUTPUT_FILES if (out_dir / n).exists()]
    if existing and not overwrite:
        raise InputError(f"already holds results ({', '.join(existing)})", where=str(out_dir),
                         expected="an empty or new folder (or --overwrite)")


Progress = Callable[[str, float, float | None], None]
"""``(what, done, total)``: called while reading (total None) and tracking (IMU rows or s)."""
PROGRESS_CHUNK_S = 60.0
"""Window fed to the tracker at a time when progress is reported (whole-session formats)."""


def track_recording(path: Path, config: TrackerConfig, *, repair: bool = False,
                    beacons: Path | None = None, chunk_rows: int = DEFAULT_CHUNK_ROWS,
                    fmt: str | None = None, trial: str | None = None,
                    progress: Progress | None = None) -> TrackRun:
    """Track a recording; a session folder or zip is streamed in chunks when it can be.

    Streaming (bounded memory) feeds ``chunk_rows`` IMU rows at a time to
    :meth:`Tracker.update`, which gives the result of :meth:`Tracker.run` on the whole session.
    Other formats and ``repair`` read the whole recording. ``fmt`` (detected when None) and
    ``trial`` are passed to :func:`hrtls.recordings.read_any`. ``result.report["input"]``
    lists the format, every repair warned while reading and the reader's notes (unit
    conversions, clock offsets).

    ``progress`` is told what is being done: reading (no total), then tracking (IMU rows of a
    stream, or seconds of a whole session, which is then fed in windows of
    :data:`PROGRESS_CHUNK_S` as the live service would; the result equals the one-call run to
    rounding).
    """
    from hrtls.recordings import detect_format, read_any, reader_options

    fmt = fmt or detect_format(path)
    options = reader_options(fmt, trial=trial)
    if progress:
        progress(f"reading {path.name} ({fmt})", 0.0, None)
    stream = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if not repair and beacons is None and fmt == "hrtls-session" and streams(config):
            stream = open_stream(path, chunk_rows=chunk_rows)
        session = None if stream is not None else read_any(path, fmt=fmt, repair=repair,
                                                           beacons=beacons, **options)
    run: TrackRun | None = None
    if stream is not None:
        try:
            run = _track_stream(stream, config, progress, caught)
        except NotStreamable:
            session = read_any(path, fmt=fmt, repair=repair, beacons=beacons, **options)
    if run is None:
        assert session is not None
        start = time.perf_counter()
        tracker = Tracker(config)
        if progress is None or config.offline.whole_recording:
            raw = tracker.run(session)
        else:
            raw = _run_in_windows(tracker, session, progress)
        result = finish_track(raw, session, config)
        n = 0 if session.imu is None else len(session.imu.accel)
        run = TrackRun(result, session, n, time.perf_counter() - start, streamed=False)
    meta = run.session.meta
    input_report = _input_report(fmt, caught, meta.notes)
    input_report["path"] = str(path)
    input_report["time_origin_unix_s"] = meta.time_origin_unix_s
    input_report["georeference"] = (None if meta.georeference is None
                                    else meta.georeference.model_dump())
    t_imu = stream.imu_t if stream is not None and run.streamed else (
        None if run.session.imu is None else run.session.imu.accel.t)
    if t_imu is not None and len(t_imu):
        input_report["imu"] = stream_fingerprint(t_imu)
    elif run.session.rss is not None and len(run.session.rss.t):  # infrastructure only
        input_report["rss"] = stream_fingerprint(run.session.rss.t)
    return _with_input(run, input_report, config)


def stream_fingerprint(t: np.ndarray) -> dict[str, float | int]:
    """What identifies a recording's IMU (or RSS) stream: samples and first/last time (s)."""
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


def _with_input(run: TrackRun, input_report: dict[str, Any], config: TrackerConfig
                ) -> TrackRun:
    report = run.result.report
    report["input"] = input_report
    placement = run.session.meta.placement   # the reader's (IPIN: "hand")
    if declared_handheld(placement) and config.attitude.mounting == "session":
        note = (f"this is a hand-held phone recording ({input_report['format']}) but the "
                f"configuration {config.name!r} expects a body-worn device: use --preset "
                "handheld-phone (or [attitude] mounting = \"handheld\")")
        report.setdefault("notes", []).append(note)
    return run


def _run_in_windows(tracker: Tracker, session: Session, progress: Progress) -> TrackResult:
    from hrtls.pipeline.chunks import split_session

    t0, t1 = session.time_span()
    tracker.start_session(session)
    for part in split_session(session, PROGRESS_CHUNK_S):
        tracker.update(part)
        done = min(t1, part.time_span()[1]) - t0
        progress("tracking", done, t1 - t0)
    progress("tracking", t1 - t0, t1 - t0)
    return tracker.finish()


def _track_stream(stream: SessionStream, config: TrackerConfig,
                  progress: Progress | None, caught: list[warnings.WarningMessage]
                  ) -> TrackRun:
    """Read and track the IMU chunk by chunk; the clocks are checked once all are read.

    Clock warnings are added to ``caught``.

    Raises
    ------
    NotStreamable
        When the whole-session reader must read it (see :mod:`hrtls.io.stream`), or the IMU
        has fewer than two rows.
    """
    tracker = Tracker(config, keep_attitude=False)
    truth: list[Background[GroundTruth | None]] = []

    def chunks_then_truth() -> Iterator[Session]:
        held: Session | None = None
        for chunk in stream.chunks():
            if held is not None:
                yield held
            held = chunk
        # the IMU is read: the ground truth, for the evaluation, is read on a thread of its own
        # while the last chunk is tracked and the tracker finishes
        truth.append(Background(stream.truth, name=f"read truth of {stream.path.name}"))
        if held is not None:
            yield held

    chunks = read_ahead(chunks_then_truth(), name=f"read {stream.path.name}")
    held: list[Session] = []
    # the nominal rate is the median spacing of the leading samples, as in Tracker.run
    for chunk in chunks:
        held.append(chunk)
        if sum(_rows(c) for c in held) >= RATE_SAMPLES:
            break
    t = np.concatenate([c.imu.accel.t for c in held if c.imu is not None] or
                       [np.zeros(0)])[:RATE_SAMPLES]
    if len(t) < 2:
        chunks.close()
        raise NotStreamable(str(stream.path))
    tracker.start(stream.meta, stream.landmarks, has_imu=True, has_gyro=stream.has_gyro,
                  has_mag=stream.has_mag, has_orientation=stream.parts["orientation"] is not None,
                  rate_hz=leading_rate_hz(t), t0=stream.t0(float(t[0])))
    first: ImuStream | None = None
    seconds = 0.0
    rows = 0
    for chunk in _resumed(held, chunks):
        first = first or chunk.imu
        start = time.perf_counter()
        tracker.update(chunk)
        seconds += time.perf_counter() - start
        rows += _rows(chunk)
        if progress:
            progress("reading and tracking", rows, max(rows, stream.rows_hint))
    if first is None or rows < 2:
        truth[0].join()
        raise NotStreamable(str(stream.path))
    if progress:
        progress("reading and tracking", rows, rows)
    with warnings.catch_warnings(record=True) as clocks:
        warnings.simplefilter("always")
        check_clocks([ClockStream(*s) for s in stream.sensor_times()])
    caught.extend(clocks)
    start = time.perf_counter()
    result = tracker.finish()
    seconds += time.perf_counter() - start
    del tracker
    session = stream.session(first).with_parts(truth=truth[0].result())
    result = widen_over_gaps(widen_unobservable_heading(result, session), session,
                             imu_t=stream.imu_t)
    return TrackRun(result, session, rows, seconds, streamed=True)


def _rows(chunk: Session) -> int:
    return 0 if chunk.imu is None else len(chunk.imu.accel)


def _resumed(held: list[Session], rest: Iterator[Session]) -> Iterator[Session]:
    """The held chunks (let go of as they are fed), then the rest."""
    while held:
        yield held.pop(0)
    yield from rest


def write_track_outputs(result: TrackResult, session: Session, out_dir: Path, *,
                        overwrite: bool = False, plot: bool = False,
                        evaluation: dict[str, Any] | None = None,
                        table_format: TableFormat = "csv") -> list[Path]:
    """Write trajectory, steps (``.csv`` or ``.parquet``), geojson, report (and track.png).

    The GeoJSON is ``trajectory.geojson`` (RFC 7946, WGS-84) when the recording has a
    georeference, else :data:`LOCAL_GEOJSON` (local metres, a type map tools refuse).
    """
    if table_format not in ("csv", "parquet"):
        raise InputError(f"{table_format!r}", where="--format-out", expected="csv or parquet")
    check_output_dir(out_dir, overwrite=overwrite)
    out_dir.mkdir(parents=True, exist_ok=True)
    geo = session.georeference
    # the tables are written on a thread (Arrow's writer lets go of the GIL) while the GeoJSON
    # text is made here
    tables = Background(lambda: [
        write_trajectory(result.trajectory, out_dir / f"trajectory.{table_format}",
                         georeference=geo),
        write_steps(result.steps, out_dir / f"steps.{table_format}")], name="write tables")
    try:
        geojson = (
            write_geojson(result.trajectory, out_dir / "trajectory.geojson", steps=result.steps,
                          landmarks=session.resolved_landmarks(), georeference=geo,
                          time_origin_unix_s=session.meta.time_origin_unix_s, overwrite=True)
            if geo is not None else
            write_local_geojson(result.trajectory, out_dir / LOCAL_GEOJSON, steps=result.steps,
                                landmarks=session.landmarks,
                                time_origin_unix_s=session.meta.time_origin_unix_s,
                                overwrite=True))
    except BaseException:
        tables.join()
        raise
    written = [*tables.result(), geojson]
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
            title=f"hrtls track ({result.report['config']['name']})"
            + ("" if result.report.get("heading", {}).get("observable", True)
               else ", " + result.report["heading"]["plot_note"]), ellipses=25))
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


def reference_steps(result: TrackResult, session: Session) -> dict[str, Any] | None:
    """Our step count beside the recording's reference (mobgap, Oxford), or None.

    With reference walking bouts (``intervals_s``) our steps ending inside them (with 0.5 s
    of margin) are counted too, since the reference counts only those.
    """
    ref = session.meta.source.get("reference_steps")
    if not isinstance(ref, dict) or "count" not in ref:
        return None
    ours = len(result.steps)
    if ref["count"] is None:  # the recording has a reference system but no step in it
        return {"reference": None, "source": str(ref.get("source", "")), "ours": ours,
                "error_fraction": None}
    out: dict[str, Any] = {"reference": int(ref["count"]), "source": str(ref.get("source", "")),
                           "ours": ours}
    intervals = ref.get("intervals_s")
    if intervals:
        ends = result.steps.t_end
        inside = np.zeros(len(ends), dtype=bool)
        for start, end in intervals:
            inside |= (ends >= float(start) - 0.5) & (ends <= float(end) + 0.5)
        out["ours_in_reference_bouts"] = int(np.count_nonzero(inside))
    counted = out.get("ours_in_reference_bouts", ours)
    out["error_fraction"] = (counted - out["reference"]) / out["reference"] \
        if out["reference"] else None
    return out
