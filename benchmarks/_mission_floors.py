"""Floor scores of a two-floor hybrid mission (``benchmarks/mission.py --floors 2``; scoring only).

Per true floor of the nodes: the share localized, the share localized **on the right floor**
(the mission's node floor equals the node's true floor) and the RMSE of those; over the
rescuers (1 Hz samples of each track): the share of time on the right floor (the estimate's
floor ``round(z / floor height)`` against the truth's) and the horizontal error on each true
floor. The truth is read here only.
"""

from __future__ import annotations

import numpy as np

from hrtls.mission.tracker import MissionResult
from hrtls.sim.floorplan import floor_of
from hrtls.sim.mission import Mission
from hrtls.sim.mission_floors import FLOOR_HEIGHT_M

KEYS = ("frac0", "right0", "rmse0", "frac1", "right1", "rmse1", "on_floor", "err0", "err1")
"""Scores per seed: nodes of floor k localized / localized on floor k / their RMSE (m), the
rescuers' share of time on the right floor and their mean error on floor 0 / 1 (m)."""


def floor_scores(mission: Mission, result: MissionResult) -> dict[str, float]:
    """The :data:`KEYS` of one mission (NaN where a floor has no node or no sample)."""
    out: dict[str, float] = {}
    for f in (0, 1):
        nodes = [n for n in mission.node_truth_m if mission.node_floor.get(n, 0) == f]
        loc = [n for n in nodes if n in result.nodes and result.nodes[n].localized]
        right = [n for n in loc if result.node_floor.get(n, 0) == f]
        d2 = [float(np.sum((result.nodes[n].position_m - mission.node_truth_m[n]) ** 2))
              for n in right]
        out[f"frac{f}"] = len(loc) / len(nodes) if nodes else float("nan")
        out[f"right{f}"] = len(right) / len(nodes) if nodes else float("nan")
        out[f"rmse{f}"] = float(np.sqrt(np.mean(d2))) if d2 else float("nan")
    hits, errs, floors = [], [], []
    for name, res in result.agents.items():
        if mission.kinds.get(name, "rescuer") != "rescuer":
            continue
        truth = mission.simulations[name].session.truth
        assert truth is not None
        tr = res.trajectory
        tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
        true_floor = floor_of(np.interp(tq, truth.t, truth.xyz[:, 2]),
                              floor_height_m=FLOOR_HEIGHT_M)
        est_floor = floor_of(np.interp(tq, tr.t, tr.xyz[:, 2]), floor_height_m=FLOOR_HEIGHT_M)
        hits.append(est_floor == true_floor)
        floors.append(true_floor)
        errs.append(np.hypot(np.interp(tq, tr.t, tr.xyz[:, 0]) - np.interp(tq, truth.t,
                                                                           truth.xyz[:, 0]),
                             np.interp(tq, tr.t, tr.xyz[:, 1]) - np.interp(tq, truth.t,
                                                                           truth.xyz[:, 1])))
    hit, err, fl = np.concatenate(hits), np.concatenate(errs), np.concatenate(floors)
    out["on_floor"] = float(np.mean(hit))
    for f in (0, 1):
        out[f"err{f}"] = float(np.mean(err[fl == f])) if np.any(fl == f) else float("nan")
    return out


def floor_table(rows: dict[str, dict[str, list[float]]]) -> str:
    """Markdown table of the floor scores, mean / p90 / worst over seeds (p10 / lowest for
    shares), one row per cooperation mode."""
    def stats(x: list[float], share: bool) -> str:
        a = np.asarray(x, dtype=float)
        a = a[np.isfinite(a)]
        if not len(a):
            return "-"
        if share:
            return f"{np.mean(a):.2f} / {np.percentile(a, 10):.2f} / {np.min(a):.2f}"
        return f"{np.mean(a):.2f} / {np.percentile(a, 90):.2f} / {np.max(a):.2f}"

    lines = ["| cooperation | floor-0 nodes localized / on the right floor | floor-0 node RMSE, m "
             "| floor-1 nodes localized / on the right floor | floor-1 node RMSE, m "
             "| rescuers' time on the right floor | rescuer error on floor 0 / 1, m |",
             "|---|---|---|---|---|---|---|"]
    for mode, r in rows.items():
        lines.append(
            f"| {mode} | {stats(r['frac0'], True)} ; {stats(r['right0'], True)} "
            f"| {stats(r['rmse0'], False)} | {stats(r['frac1'], True)} ; "
            f"{stats(r['right1'], True)} | {stats(r['rmse1'], False)} "
            f"| {stats(r['on_floor'], True)} | {stats(r['err0'], False)} ; "
            f"{stats(r['err1'], False)} |")
    return "\n".join(lines)
