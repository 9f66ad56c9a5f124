"""Track a mission folder offline with :class:`~hrtls.mission.tracker.MissionTracker`.

:func:`track_mission` reads the folder (:mod:`hrtls.io.mission`), gives the tracker the agents'
sessions without their ground truth and the ranges between nodes (``network_ranges.csv``),
finishes each agent's track as ``hrtls track`` does and scores it against its truth;
:func:`write_mission_outputs` writes

* ``agents/<name>/``: the outputs of ``hrtls track`` (``trajectory.csv``, ``steps.csv``, GeoJSON,
  ``report.json`` with the evaluation when the agent has ground truth);
* ``nodes.csv``: one row per node (listed in ``network.json`` or heard): ``id, x, y, z, var_x,
  cov_xy, var_y, localized, readings, contributors, status`` (position and covariance of
  localized nodes only; ``z`` is empty, the estimate is planar; ``contributors``: the agents
  whose ranges fed the node, space-separated, ``none``; ``status``: ``localized`` or why not);
* ``report.json``: the mission summary (:func:`mission_summary`), with the loop closures
  (contributors that started to use a node they fed, ``hrtls.mission.tracker``).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import Session
from hrtls.errors import InputError
from hrtls.io.mission import MISSION_FILE, MissionFolder, read_mission
from hrtls.io.tables import encode_table
from hrtls.jobs.track import check_output_dir, evaluate_track, write_track_outputs
from hrtls.mission.smoother_modes import smoother_mode
from hrtls.mission.tracker import MissionParams, MissionResult, MissionTracker
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.finish import finish_track
from hrtls.pipeline.tracker import TrackResult

MISSION_OUTPUTS = ("report.json", "nodes.csv")


@dataclass(frozen=True, eq=False)
class MissionRun:
    """A tracked mission folder.

    ``agents``: each agent's finished track (as ``hrtls track`` writes it); ``evaluations``:
    its evaluation (None without ground truth); ``tracker_s``: time in the mission tracker.
    """

    folder: MissionFolder
    result: MissionResult
    agents: dict[str, TrackResult]
    evaluations: dict[str, dict[str, Any] | None]
    config: TrackerConfig
    params: MissionParams
    tracker_s: float


def estimator_sessions(folder: MissionFolder) -> dict[str, Session]:
    """The sessions the mission tracker gets (without ground truth); robots need odometry."""
    sessions = folder.sessions()
    for i, agent in enumerate(folder.agents.values()):
        if agent.kind == "robot" and (sessions[agent.name].fixes is None
                                      or sessions[agent.name].meta.start_pose is None):
            raise InputError(f"robot {agent.name!r} has no odometry poses or start pose",
                             where=f"{folder.path / MISSION_FILE} agents[{i}]",
                             expected="a robot session with fixes.csv (wheel odometry poses) "
                                      "and meta.start_pose")
    return sessions


def track_mission(folder: MissionFolder | Path | str, *, config: TrackerConfig,
                  params: MissionParams | None = None) -> MissionRun:
    """Track a mission folder (read first when given its path; see the module doc)."""
    params = params or MissionParams()
    if not isinstance(folder, MissionFolder):
        folder = read_mission(folder)
    sessions = estimator_sessions(folder)
    start = time.perf_counter()
    kinds = {name: a.kind for name, a in folder.agents.items()}
    tracker = MissionTracker(sessions, config=config, params=params, kinds=kinds,
                             landmark_updates=folder.landmark_updates)
    tracker.feed_network(folder.network_ranges)
    result = tracker.run()
    seconds = time.perf_counter() - start
    agents: dict[str, TrackResult] = {}
    evaluations: dict[str, dict[str, Any] | None] = {}
    for name, raw in result.agents.items():
        agent = folder.agents[name]
        finished = finish_track(raw, sessions[name], config) if agent.kind == "rescuer" else raw
        finished.report["input"] = {"format": "mission", "path": str(agent.path),
                                    "mission": str(folder.path)}
        finished.report["mission"] = {
            "agent": name, "kind": agent.kind, "cooperate": params.cooperate,
            "contributed_to": sorted(n for n, who in result.contributors.items()
                                     if name in who)}
        agents[name] = finished
        evaluations[name] = evaluate_track(finished, agent.session)
    return MissionRun(folder, result, agents, evaluations, config, params, seconds)


def node_ids(run: MissionRun) -> list[str]:
    """Listed nodes first (``network.json`` order), then nodes heard but not listed."""
    heard = sorted(set(run.result.readings) - set(run.folder.nodes))
    return list(run.folder.nodes) + heard


def nodes_columns(run: MissionRun) -> dict[str, np.ndarray]:
    """Columns of ``nodes.csv`` (see the module doc)."""
    ids = node_ids(run)
    n = len(ids)
    xy = np.full((n, 2), np.nan)
    cov = np.full((n, 2, 2), np.nan)
    localized, reason, contributors = [], [], []
    for i, node in enumerate(ids):
        est = run.result.nodes.get(node)
        ok = est is not None and est.localized
        if ok and est is not None:
            xy[i] = est.position_m
            cov[i] = est.covariance_m2
        localized.append("true" if ok else "false")
        reason.append("localized" if ok else est.reason if est is not None
                      else "never heard" if node not in run.result.readings
                      else "too few readings to estimate")
        contributors.append(" ".join(run.result.contributors.get(node, [])) or "none")
    return {"id": np.asarray(ids, dtype=np.str_), "x": xy[:, 0], "y": xy[:, 1],
            "z": np.full(n, np.nan), "var_x": cov[:, 0, 0], "cov_xy": cov[:, 0, 1],
            "var_y": cov[:, 1, 1], "localized": np.asarray(localized, dtype=np.str_),
            "readings": np.asarray([run.result.readings.get(k, 0) for k in ids], dtype=float),
            "contributors": np.asarray(contributors, dtype=np.str_),
            "status": np.asarray(reason, dtype=np.str_)}


def node_scores(run: MissionRun) -> dict[str, Any] | None:
    """Localized fraction of the true nodes, horizontal RMSE (m) and mean NEES (2 dof).

    None when the folder has no ``network_truth.json``.
    """
    truth = run.folder.node_truth_m
    if truth is None:
        return None
    errors: dict[str, float] = {}
    nees: list[float] = []
    for node, est in run.result.nodes.items():
        if not est.localized or node not in truth:
            continue
        d = est.position_m - truth[node][:2]
        errors[node] = float(np.hypot(*d))
        nees.append(float(d @ np.linalg.solve(est.covariance_m2, d)))
    e = np.asarray(list(errors.values()))
    return {"nodes": len(truth), "localized": len(errors),
            "localized_fraction": len(errors) / len(truth) if truth else None,
            "rmse_m": float(np.sqrt(np.mean(e ** 2))) if len(e) else None,
            "max_m": float(np.max(e)) if len(e) else None,
            "nees_mean": float(np.mean(nees)) if nees else None, "errors_m": errors}


def _headline(evaluation: dict[str, Any] | None) -> dict[str, Any] | None:
    if evaluation is None:
        return None
    keep: dict[str, Any] = {}
    for part, keys in (("position", ("mean", "rmse", "p90", "max", "final_m")),
                       ("checkpoints", ("mean", "max"))):
        if evaluation.get(part):
            keep[part] = {k: evaluation[part].get(k) for k in keys}
    return keep


def mission_summary(run: MissionRun) -> dict[str, Any]:
    """The mission's ``report.json``: inputs, parameters, per-agent and node figures."""
    folder, res = run.folder, run.result
    ratio, gate = run.params.loop_closure_ratio, run.params.use_variance_ratio
    localized = [n for n, e in res.nodes.items() if e.localized]
    agents = {}
    for name, tr in run.agents.items():
        s = tr.report["summary"]
        agents[name] = {
            "kind": folder.agents[name].kind, "outputs": f"agents/{name}",
            "steps": s["steps"], "distance_walked_m": s["distance_walked_m"],
            "range_corrections": tr.report["corrections"].get("range", {}),
            "contributed_to": tr.report["mission"]["contributed_to"],
            "evaluation": _headline(run.evaluations[name])}
    return {
        "mission": {"path": str(folder.path), "name": folder.name, "agents": len(folder.agents),
                    "nodes_listed": len(folder.nodes), "landmarks": sorted(folder.landmarks)},
        "params": {"cooperate": run.params.cooperate, "chunk_s": run.params.chunk_s,
                   "loop_closure_ratio": ratio if math.isfinite(ratio) else None,
                   "pass_cap": run.params.pass_cap,
                   "use_variance_ratio": gate if math.isfinite(gate) else None,
                   "agent_cov_scale": run.params.nodes.agent_cov_scale,
                   "agent_correlation": run.params.nodes.agent_correlation,
                   "smoother": smoother_mode(run.params.smoother),
                   "config": run.config.name},
        "tracker_s": run.tracker_s,
        "agents": agents,
        "nodes": {"heard": len(res.readings), "localized": len(localized),
                  "localized_ids": sorted(localized), "score": node_scores(run)},
        "loop_closures": [{"t": c.t, "agent": c.agent, "node": c.node,
                           "trace_now_m2": c.trace_now_m2,
                           "trace_readings_m2": c.trace_readings_m2} for c in res.closures],
    }


def check_mission_output(run_agents: list[str], out_dir: Path, *, overwrite: bool) -> None:
    """Refuse, before any work, an output folder that already holds mission results."""
    check_output_dir(out_dir, overwrite=overwrite)
    existing = [n for n in MISSION_OUTPUTS if (out_dir / n).exists()]
    if existing and not overwrite:
        raise InputError(f"already holds results ({', '.join(existing)})", where=str(out_dir),
                         expected="an empty or new folder (or --overwrite)")
    for name in run_agents:
        check_output_dir(out_dir / "agents" / name, overwrite=overwrite)


def write_mission_outputs(run: MissionRun, out_dir: Path, *, overwrite: bool = False,
                          plot: bool = False) -> list[Path]:
    """Write the outputs listed in the module doc; returns the files and folders written."""
    check_mission_output(list(run.agents), out_dir, overwrite=overwrite)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for name, tr in run.agents.items():
        folder = out_dir / "agents" / name
        write_track_outputs(tr, run.folder.agents[name].session, folder, overwrite=overwrite,
                            plot=plot, evaluation=run.evaluations[name])
        written.append(folder)
    (out_dir / "nodes.csv").write_bytes(encode_table(nodes_columns(run), table="nodes",
                                                     suffix=".csv"))
    (out_dir / "report.json").write_text(
        json.dumps(mission_summary(run), indent=2, default=float) + "\n", encoding="utf-8")
    written += [out_dir / "nodes.csv", out_dir / "report.json"]
    return written
