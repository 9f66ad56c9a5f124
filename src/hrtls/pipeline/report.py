"""The tracker's report: notes, correction counts, rejected observations, learned values.

A report is JSON-able (``report.json`` of ``hrtls track``). Counts and the first rejected
observations carry over a snapshot (``base``: what the tracker had before its restore).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hrtls.calibration.hard_iron_running import RunningHardIron
from hrtls.data import StepEvents, Trajectory
from hrtls.pipeline.build import Notes
from hrtls.pipeline.compass import CompassYaw
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.diagnostics import DiagnosticsLog
from hrtls.pipeline.engine import FusionEngine
from hrtls.pipeline.schedule import PoseGate

MAX_REJECTED = 200
"""Rejected observations listed in the report (the first ones)."""


def empty_base() -> dict[str, Any]:
    """Report counters of a tracker started afresh."""
    return {"counts": {}, "rejected": [], "accepted_t": [], "yaw_pseudo": 0}


def note_hard_iron(hard_iron: RunningHardIron | None, notes: Notes) -> None:
    """Report line of the running hard-iron fit (at the end of the recording)."""
    if hard_iron is None:
        return
    st = hard_iron.state
    if not hard_iron.accepted:
        notes.degrade("magnetometer hard iron not fitted (no fit accepted: the walk turned too "
                      "little or the field was disturbed); field used raw")
        return
    notes.add(
        "magnetometer hard iron fitted on the turns so far (running fit, first accepted at "
        f"t = {st.t_accepted:.1f} s, {st.n_fits} fits): c = ["
        f"{', '.join(f'{v:.2f}' for v in st.c_ut)}] uT, horizontal field "
        f"{st.field_ut:.1f} uT, residual {st.residual_ut:.2f} uT, {st.arc_deg:.0f} deg "
        f"of turning, {st.n_used} block means; the field was used raw before")


def counts(diagnostics: DiagnosticsLog, base: dict[str, Any]) -> dict[str, dict[str, int]]:
    """Corrections by kind and outcome, with those before a restore."""
    out = diagnostics.counts()
    for kind, by_status in base["counts"].items():
        d = out.setdefault(kind, {})
        for status, n in by_status.items():
            d[status] = d.get(status, 0) + n
    return out


def rejected(diagnostics: DiagnosticsLog, base: dict[str, Any]) -> list[dict[str, Any]]:
    """The first ``MAX_REJECTED`` rejected observations, with those before a restore."""
    out = list(base["rejected"])
    out += diagnostics.first_rejected_dicts(MAX_REJECTED - len(out))
    return out[:MAX_REJECTED]


def carried(eng: FusionEngine, base: dict[str, Any]) -> dict[str, Any]:
    """The counters a snapshot carries (to ``base`` of the restored tracker)."""
    acc_t = eng.diagnostics.accepted_times()
    return {"counts": counts(eng.diagnostics, base), "rejected": rejected(eng.diagnostics, base),
            "accepted_t": ([float(acc_t[-1])] if len(acc_t)
                           else list(base["accepted_t"])[-1:]),
            "yaw_pseudo": base["yaw_pseudo"] + len(eng.yaw_pseudo)}


def final_notes(notes: Notes, pose: PoseGate, *, t0: float, has_imu: bool,
                seen_obs: bool) -> None:
    """Notes known only at the end (what the start pose held back, pure dead reckoning)."""
    if pose.t_pose > t0:
        ignored = ", ".join(f"{n} {k}" for k, n in pose.ignored.items())
        notes.add(f"start pose holds at t = {pose.t_pose:.3f} s: attitude and gait ran from "
                  f"t = {t0:.3f} s, position starts at the pose"
                  + (f"; ignored before it: {ignored}" if ignored else ""))
    if has_imu and not seen_obs:
        notes.add("no infrastructure observations: pure dead reckoning (the error grows with "
                  "the distance walked)")


def build_report(config: TrackerConfig, eng: FusionEngine, base: dict[str, Any], *,
                 trajectory: Trajectory, steps: StepEvents, notes: Notes,
                 attitude_method: str, two_pass: bool,
                 compass: CompassYaw | None) -> dict[str, Any]:
    """The JSON-able report of a finished track."""
    final = eng.state
    report: dict[str, Any] = {
        "config": config.model_dump(),
        "attitude_method": attitude_method,
        "notes": notes.items,
        "corrections": counts(eng.diagnostics, base),
        "rejected": rejected(eng.diagnostics, base),
        "step_length_scale": eng.scale.step_scale,
        "running_step_length_scale": eng.scale.run_scale,
        "running_step_factor": eng.running_factor,
        "yaw_pseudo_measurements": base["yaw_pseudo"] + len(eng.yaw_pseudo),
        "offline": {"two_pass": two_pass, "grid_smoother": eng.grid.smoothed},
        "summary": {
            "duration_s": float(trajectory.t[-1] - trajectory.t[0]) if len(trajectory) else 0,
            "steps": len(steps),
            "distance_walked_m": steps.distance_m,
            "path_length_m": trajectory.path_length_m,
            "final_position_m": final.x[:3].tolist(),
            "final_sigma_xy_m": float(math.sqrt(max(np.trace(final.P[:2, :2]), 0.0) / 2)),
        },
    }
    if compass is not None:
        report["compass"] = {"hard_iron_ut": compass.c.tolist(),
                             "field_ut": compass.radius if math.isfinite(compass.radius)
                             else None,
                             "last_yaw_correction_deg": math.degrees(-compass.last_error)}
    if eng.channel_state is not None and config.rss.mode != "off":
        report["channel"] = {"a_dbm": float(eng.channel_state.theta[0]),
                             "eta": float(eng.channel_state.theta[1]),
                             "sigma_db": math.sqrt(eng.channel_state.residual_var_db2)}
    return report
