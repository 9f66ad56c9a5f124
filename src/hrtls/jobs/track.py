"""Track a session into a result folder, and score it when the session has ground truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hrtls.data import Session
from hrtls.errors import InputError
from hrtls.evaluate.report import EvaluationInputs, build_report
from hrtls.io.geojson import write_geojson
from hrtls.io.tables import write_steps, write_trajectory
from hrtls.pipeline.tracker import TrackResult

OUTPUT_FILES = ("trajectory.csv", "steps.csv", "trajectory.geojson", "report.json")


def write_track_outputs(result: TrackResult, session: Session, out_dir: Path, *,
                        overwrite: bool = False, plot: bool = False,
                        evaluation: dict[str, Any] | None = None) -> list[Path]:
    """Write trajectory.csv, steps.csv, trajectory.geojson, report.json (and track.png)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    existing = [n for n in OUTPUT_FILES if (out_dir / n).exists()]
    if existing and not overwrite:
        raise InputError(f"already holds results ({', '.join(existing)})", where=str(out_dir),
                         expected="an empty or new folder (or --overwrite)")
    geo = session.georeference
    written = [
        write_trajectory(result.trajectory, out_dir / "trajectory.csv", georeference=geo),
        write_steps(result.steps, out_dir / "steps.csv"),
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
        from hrtls.evaluate.plots import plot_trajectory

        written.append(plot_trajectory(
            out_dir / "track.png", result.trajectory, session.truth,
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
