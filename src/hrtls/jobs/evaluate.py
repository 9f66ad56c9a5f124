"""Score a result folder of ``hrtls track`` against the ground truth of any recording.

:func:`evaluate_result` reads the result's trajectory (and steps), reads the truth with
:func:`hrtls.recordings.read_any` (a session folder, a simulated session, an IPIN logfile with
landmarks, ...), refuses truth whose time span does not overlap the result's (naming both) or
whose IMU is not the one tracked (as ``report.json`` records it), and writes
``evaluation.json`` (and plots) beside the result. The track's own files (``report.json``,
tables, GeoJSON, ``track.png``) are never touched.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import Checkpoints, GroundTruth, StepEvents, Trajectory
from hrtls.errors import DegradedInputWarning, InputError

EVALUATION_FILE = "evaluation.json"
PLOT_FILES = ("evaluation_trajectory.png", "evaluation_error.png", "evaluation_cdf.png")
MIN_OVERLAP = 0.5
"""Share of the shorter of the two time spans that must be common to result and truth."""


@dataclass(frozen=True, slots=True)
class TruthData:
    """What a truth recording offers for scoring."""

    truth: GroundTruth | None
    checkpoints: Checkpoints | None
    true_steps: StepEvents | None
    true_activity: tuple[np.ndarray, np.ndarray] | None
    reference: dict[str, Any]
    floor_height_m: float
    label: str
    imu_t: np.ndarray | None
    rss_t: np.ndarray | None


def read_estimate(result_dir: Path) -> tuple[Trajectory, StepEvents | None]:
    """The trajectory and steps of a result folder (CSV or Parquet tables)."""
    from hrtls.io.tables import read_steps, read_trajectory

    if not result_dir.is_dir():
        raise InputError("not a folder", where=str(result_dir),
                         expected="a result folder written by `hrtls track`")
    tables = [result_dir / f"trajectory.{ext}" for ext in ("csv", "parquet")]
    found = [p for p in tables if p.exists()]
    if not found:
        raise InputError("no trajectory.csv or trajectory.parquet", where=str(result_dir),
                         expected="a result folder written by `hrtls track`")
    estimate = read_trajectory(found[0])
    steps_path = found[0].with_name("steps" + found[0].suffix)
    return estimate, read_steps(steps_path) if steps_path.exists() else None


def read_truth(path: Path, *, fmt: str | None = None, trial: str | None = None) -> TruthData:
    """Ground truth of any supported recording (plus simulated steps/activity when present)."""
    from hrtls.recordings import read_any, reader_options

    if not path.exists():
        raise InputError("no such file or folder", where=str(path),
                         expected="a recording with ground truth (--truth)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        session = read_any(path, fmt=fmt, check_units=False, **reader_options(fmt, trial=trial))
    if session.truth is None and session.checkpoints is None:
        raise InputError("no ground truth (truth trajectory or checkpoints)", where=str(path),
                         expected="a recording with ground truth (--truth)")
    checkpoints = session.checkpoints
    true_steps = None
    activity = None
    reference: dict[str, Any] = {}
    if path.is_dir():
        from hrtls.cli.sim import read_activity_intervals
        from hrtls.io.tables import read_steps

        if (path / "truth_steps.csv").exists():
            true_steps = read_steps(path / "truth_steps.csv")
        if (path / "activity.csv").exists():
            activity = read_activity_intervals(path / "activity.csv")
        if (path / "scenario.json").exists():
            reference = json.loads((path / "scenario.json").read_text()).get("reference", {})
    return TruthData(session.truth, checkpoints, true_steps, activity, reference,
                     session.meta.floor_height_m, str(path),
                     None if session.imu is None else session.imu.accel.t,
                     None if session.rss is None else session.rss.t)


def _span(t: np.ndarray) -> tuple[float, float]:
    return (float(t[0]), float(t[-1])) if len(t) else (0.0, 0.0)


def check_overlap(estimate: Trajectory, truth: TruthData, *, result_label: str) -> None:
    """Refuse truth whose time span shares less than :data:`MIN_OVERLAP` with the result's."""
    times = [x.t for x in (truth.truth, truth.checkpoints) if x is not None and len(x.t)]
    t_truth = np.sort(np.concatenate(times)) if times else np.zeros(0)
    e0, e1 = _span(estimate.t)
    r0, r1 = _span(t_truth)
    common = min(e1, r1) - max(e0, r0)
    shorter = min(e1 - e0, r1 - r0)
    inside = np.count_nonzero((t_truth >= e0) & (t_truth <= e1))
    if len(t_truth) == 0 or inside == 0 or (shorter > 0 and common < MIN_OVERLAP * shorter):
        raise InputError(
            f"the truth spans {r0:.3f} .. {r1:.3f} s but the result {e0:.3f} .. {e1:.3f} s",
            where=f"--truth {truth.label}",
            expected=f"the ground truth of the recording {result_label} was tracked from "
            f"(time spans sharing at least {MIN_OVERLAP:.0%} of the shorter one)")


def check_same_recording(result_dir: Path, truth: TruthData) -> None:
    """Refuse truth from another recording than the one tracked (by its stream fingerprint).

    ``report.json`` of ``hrtls track`` records the IMU's sample count and first/last time (the
    RSS readings' for a recording without IMU); a truth recording with that stream must match
    them (a converted copy does).
    """
    from hrtls.jobs.track import stream_fingerprint

    path = result_dir / "report.json"
    if not path.exists():
        return
    try:
        tracked_input = json.loads(path.read_text(encoding="utf-8")).get("input", {})
    except (json.JSONDecodeError, AttributeError):
        return
    for key, t in (("imu", truth.imu_t), ("rss", truth.rss_t)):
        tracked = tracked_input.get(key) if isinstance(tracked_input, dict) else None
        if t is None or len(t) == 0 or not isinstance(tracked, dict):
            continue
        mine = stream_fingerprint(t)
        same = (tracked.get("samples") == mine["samples"]
                and abs(float(tracked.get("t_first_s", np.nan)) - mine["t_first_s"]) < 1e-3
                and abs(float(tracked.get("t_last_s", np.nan)) - mine["t_last_s"]) < 1e-3)
        if not same:
            what = "IMU samples" if key == "imu" else "RSS readings"
            raise InputError(
                f"not the recording that was tracked: the result tracked {tracked.get('samples')}"
                f" {what} over {tracked.get('t_first_s', 0.0):.3f} .. "
                f"{tracked.get('t_last_s', 0.0):.3f} s, the truth recording has "
                f"{mine['samples']} over {mine['t_first_s']:.3f} .. {mine['t_last_s']:.3f} s",
                where=f"--truth {truth.label}",
                expected="the recording given to `hrtls track` (or a converted copy of it)")
        return


def evaluate_result(result_dir: Path, truth_path: Path, *, output: Path | None = None,
                    plots: bool = True, fmt: str | None = None, trial: str | None = None
                    ) -> dict[str, Any]:
    """Score ``result_dir`` against the truth of ``truth_path``; write ``evaluation.json``.

    Returns the evaluation. ``output`` (default: ``result_dir``) receives ``evaluation.json``
    and, with ``plots``, :data:`PLOT_FILES`.
    """
    from hrtls.evaluate.floors import floor_detection
    from hrtls.evaluate.report import EvaluationInputs, build_report

    estimate, steps = read_estimate(result_dir)
    truth = read_truth(truth_path, fmt=fmt, trial=trial)
    check_overlap(estimate, truth, result_label=str(result_dir))
    check_same_recording(result_dir, truth)
    report = build_report(EvaluationInputs(
        estimate=estimate, estimated_steps=steps, truth=truth.truth,
        checkpoints=truth.checkpoints, true_steps=truth.true_steps,
        true_activity=truth.true_activity, reference=truth.reference))
    floors = floor_detection(estimate, truth.truth, truth.checkpoints,
                             floor_height_m=truth.floor_height_m)
    if floors is not None:
        report["floors"] = floors
    report["truth"] = {"source": truth.label, "result": str(result_dir)}
    out = output or result_dir
    out.mkdir(parents=True, exist_ok=True)
    (out / EVALUATION_FILE).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    if plots:
        _plots(out, estimate, truth, title=result_dir.name)
    return report


def _plots(out: Path, estimate: Trajectory, truth: TruthData, *, title: str) -> None:
    from hrtls.evaluate.metrics import checkpoint_errors, position_errors
    from hrtls.evaluate.plots import plot_cdf, plot_error_over_time, plot_trajectory

    plot_trajectory(out / PLOT_FILES[0], estimate, truth.truth, checkpoints=truth.checkpoints,
                    title=title)
    t_e, e = (position_errors(estimate, truth.truth) if truth.truth is not None
              else (np.zeros(0), np.zeros(0)))
    t_c, e_c = (checkpoint_errors(estimate, truth.checkpoints)[:2]
                if truth.checkpoints is not None else (None, None))
    plot_error_over_time(out / PLOT_FILES[1], t_e, e, checkpoint_t=t_c, checkpoint_error_m=e_c)
    sets = {"continuous truth": e} if e.size else {}
    if e_c is not None and len(e_c):
        sets["checkpoints"] = e_c
    plot_cdf(out / PLOT_FILES[2], sets)
