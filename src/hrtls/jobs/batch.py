"""Track many recordings: one result folder each and a summary table.

A batch is a list of :class:`TrackTask` (recording, result folder, configuration source) mapped
by an engine of :mod:`hrtls.runner`; each task reads, tracks and writes on its own, so a failing
recording is reported in the summary and the others go on.
"""

from __future__ import annotations

import csv
import glob
import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hrtls.errors import InputError

if TYPE_CHECKING:  # the engines (process pools) are imported by their users: not by `track`
    from hrtls.parallel import Engine, Outcome, ProgressCallback

SUMMARY_COLUMNS = ("recording", "status", "result", "steps", "distance_walked_m", "imu_samples",
                   "seconds", "checkpoint_mean_m", "checkpoint_max_m", "error_p90_m", "error")

_GLOB_CHARS = set("*?[")
_WHOLE_FOLDER_FORMATS = ("hrtls-session", "mobgap", "oxford-step", "broad", "ble-rssi")


@dataclass(frozen=True, kw_only=True)
class TrackTask:
    """One recording of a batch; the configuration is a preset name or a TOML file."""

    recording: str
    output: str
    preset: str | None = None
    config_path: str | None = None
    repair: bool = False
    overwrite: bool = False
    plot: bool = False


@dataclass(frozen=True, kw_only=True)
class TrackSummary:
    """What a successful task reports for the summary table."""

    steps: int
    distance_walked_m: float
    imu_samples: int
    seconds: float
    checkpoint_mean_m: float | None = None
    checkpoint_max_m: float | None = None
    error_p90_m: float | None = None


def is_batch(spec: str) -> bool:
    """A glob pattern, or a folder of recordings rather than one recording.

    A folder is one recording when it is an hrtls session or one of the datasets read as a
    whole (mobgap, Oxford, BROAD, BLE RSSI); otherwise it is a batch when at least one of its
    sub-folders or zips is a recording.
    """
    if _GLOB_CHARS & set(spec):
        return True
    path = Path(spec)
    if not path.is_dir():
        return False
    from hrtls.recordings import detect_format

    try:
        if detect_format(path) in _WHOLE_FOLDER_FORMATS:
            return False
    except InputError:
        pass
    return any(_is_recording(p) for p in _entries(path)
               if p.is_dir() or p.suffix.lower() == ".zip")


def _entries(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if not p.name.startswith("."))


def _is_recording(path: Path) -> bool:
    from hrtls.recordings import detect_format

    try:
        detect_format(path)
    except InputError:
        return False
    return True


def find_recordings(spec: str) -> list[Path]:
    """The recordings a batch argument names: glob matches, or a folder's entries.

    Entries are taken in name order; hidden ones are skipped. A glob keeps only recordings;
    in a folder, sub-folders and zips are taken even when they are not recognized, so that a
    broken recording shows up as a failure in the summary rather than vanishing.
    """
    if _GLOB_CHARS & set(spec):
        out = [p for p in (Path(q) for q in sorted(glob.glob(spec))) if _is_recording(p)]
    else:
        out = [p for p in _entries(Path(spec)) if p.is_dir() or p.suffix.lower() == ".zip"
               or _is_recording(p)]
    if not out:
        raise InputError("no recordings found", where=spec,
                         expected="a glob or folder with session folders, zips or recordings")
    return out


def plan_batch(recordings: Sequence[Path], output: Path, *, preset: str | None,
               config_path: Path | None, repair: bool = False, overwrite: bool = False,
               plot: bool = False) -> list[TrackTask]:
    """One task per recording; result folders named after the recordings (made unique)."""
    names: dict[str, int] = {}
    tasks = []
    for rec in recordings:
        stem = rec.name[:-4] if rec.name.lower().endswith(".zip") else rec.stem or rec.name
        k = names.get(stem, 0)
        names[stem] = k + 1
        folder = output / (stem if k == 0 else f"{stem}-{k + 1}")
        tasks.append(TrackTask(recording=str(rec), output=str(folder), preset=preset,
                               config_path=None if config_path is None else str(config_path),
                               repair=repair, overwrite=overwrite, plot=plot))
    return tasks


def track_one(task: TrackTask) -> TrackSummary:
    """Read, track and write one recording (runs on any worker)."""
    from hrtls.jobs.track import evaluate_track, write_track_outputs
    from hrtls.pipeline import Tracker, load_config, preset
    from hrtls.pipeline.finish import finish_track
    from hrtls.recordings import read_any

    cfg = (load_config(Path(task.config_path)) if task.config_path is not None
           else preset(task.preset or "default"))
    data = read_any(task.recording, repair=task.repair)
    start = time.perf_counter()
    result = finish_track(Tracker(cfg).run(data), data, cfg)
    seconds = time.perf_counter() - start
    evaluation = evaluate_track(result, data)
    write_track_outputs(result, data, Path(task.output), overwrite=task.overwrite,
                        plot=task.plot, evaluation=evaluation)
    summary = result.report["summary"]
    cp = (evaluation or {}).get("checkpoints") or {}
    pos = (evaluation or {}).get("position") or {}
    return TrackSummary(
        steps=int(summary["steps"]), distance_walked_m=float(summary["distance_walked_m"]),
        imu_samples=0 if data.imu is None else len(data.imu.accel), seconds=seconds,
        checkpoint_mean_m=_maybe(cp.get("mean")), checkpoint_max_m=_maybe(cp.get("max")),
        error_p90_m=_maybe(pos.get("p90")))


def _maybe(v: Any) -> float | None:
    return None if v is None else float(v)


@dataclass(frozen=True)
class BatchResult:
    """Outcomes of a batch, the summary rows and where the summary was written."""

    rows: tuple[dict[str, Any], ...]
    summary_csv: Path
    summary_json: Path

    @property
    def failed(self) -> int:
        """Recordings that did not finish."""
        return sum(r["status"] != "ok" for r in self.rows)


def summary_rows(tasks: Sequence[TrackTask],
                 outcomes: Sequence[Outcome[TrackSummary]]) -> list[dict[str, Any]]:
    """One row per task, in task order (failed tasks keep their error message)."""
    rows = []
    for task, o in zip(tasks, outcomes, strict=True):
        row: dict[str, Any] = dict.fromkeys(SUMMARY_COLUMNS)
        row.update(recording=task.recording, result=task.output)
        if o.ok and o.value is not None:
            row.update(status="ok", **asdict(o.value))
        else:
            row.update(status="failed", error=o.error)
        rows.append(row)
    return rows


def run_batch(tasks: Sequence[TrackTask], output: Path, *, engine: Engine,
              progress: ProgressCallback | None = None) -> BatchResult:
    """Track every task on ``engine``; write ``summary.csv`` and ``summary.json`` in ``output``."""
    output.mkdir(parents=True, exist_ok=True)
    outcomes = engine.map(track_one, list(tasks), progress=progress)
    rows = summary_rows(tasks, outcomes)
    csv_path = output / "summary.csv"
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=SUMMARY_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    json_path = output / "summary.json"
    json_path.write_text(json.dumps({"engine": engine.name, "workers": engine.workers,
                                     "recordings": rows}, indent=2) + "\n", encoding="utf-8")
    return BatchResult(rows=tuple(rows), summary_csv=csv_path, summary_json=json_path)
