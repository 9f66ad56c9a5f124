"""Hybrid mission study: rescuers' errors with and without cooperation; dropped nodes localized.

Simulates ``inderst_hybrid_mission`` per seed, tracks it with ``MissionTracker`` with cooperation
off and on (the estimator never sees the simulator's truth; the truth is read here, for scoring
only) and prints, over the seeds, mean / p90 / worst of:

* the rescuers' horizontal position error (sampled at 1 Hz while walking, all rescuers),
* the rescuers' NEES (2 dof, expected 2 when their covariance is consistent),
* the fraction of nodes localized at the end, their RMSE and mean NEES (2 dof, with the
  chi-square 95 % bounds of that mean over the localized nodes).

Dev seeds 0-9 (tuning); publish held-out seeds, e.g. ``--seeds 100-129``.

    python benchmarks/mission.py --seeds 100-129 [--engine local|ray] [--workers N]

Seeds run through ``--engine`` (``benchmarks/_engine.py``); the figures do not depend on it.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from _engine import Batch, add_engine_options
from hrtls.mission.tracker import MissionParams, MissionResult, MissionTracker
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def agent_errors(mission: Mission, result: MissionResult) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal errors and their NEES (2 dof) at 1 Hz over every rescuer's walk."""
    errs, nees = [], []
    for name, res in result.agents.items():
        truth = mission.simulations[name].session.truth
        assert truth is not None
        tr = res.trajectory
        tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
        ex = np.interp(tq, tr.t, tr.xyz[:, 0]) - np.interp(tq, truth.t, truth.xyz[:, 0])
        ey = np.interp(tq, tr.t, tr.xyz[:, 1]) - np.interp(tq, truth.t, truth.xyz[:, 1])
        errs.append(np.hypot(ex, ey))
        j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
        d = np.column_stack([ex, ey])
        nees.append(np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d))
    return np.concatenate(errs), np.concatenate(nees)


def node_scores(mission: Mission, result: MissionResult) -> tuple[float, float, list[float]]:
    """Fraction localized, RMSE (m) and the NEES of each localized node."""
    n = len(mission.node_truth_m)
    d2, nees = [], []
    for node, est in result.nodes.items():
        if not est.localized:
            continue
        d = est.position_m - mission.node_truth_m[node]
        d2.append(float(d @ d))
        nees.append(float(d @ np.linalg.solve(est.covariance_m2, d)))
    rmse = float(np.sqrt(np.mean(d2))) if d2 else float("nan")
    return len(d2) / n, rmse, nees


def _stats(x: list[float]) -> str:
    a = np.asarray(x, dtype=float)
    return f"{np.mean(a):.2f} / {np.percentile(a, 90):.2f} / {np.max(a):.2f}"


@dataclass(frozen=True)
class SeedItem:
    """One seed of the study."""

    seed: int
    options: MissionOptions


@dataclass(frozen=True)
class ModeScores:
    """One seed tracked with cooperation off or on."""

    mean: float
    p90: float
    max: float
    frac: float
    anees: float
    rmse: float
    node_nees: list[float]


def run_seed(item: SeedItem) -> dict[str, ModeScores]:
    """Scores of one seed with cooperation ``off`` and ``on``."""
    mission = inderst_hybrid_mission(item.seed, item.options)
    out: dict[str, ModeScores] = {}
    for mode in ("off", "on"):
        res = MissionTracker(mission.agents, params=MissionParams(cooperate=mode == "on")).run()
        e, e_nees = agent_errors(mission, res)
        frac, rmse, nees = node_scores(mission, res)
        out[mode] = ModeScores(float(np.mean(e)), float(np.percentile(e, 90)),
                               float(np.max(e)), frac, float(np.mean(e_nees)), rmse, nees)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="e.g. 0-9 (dev) or 100-129 (held-out)")
    ap.add_argument("--nodes", type=int, default=40)
    ap.add_argument("--rescuers", type=int, default=3)
    ap.add_argument("--range-sigma-m", type=float, default=0.1)
    ap.add_argument("--node-failure", type=float, default=0.0)
    add_engine_options(ap)
    args = ap.parse_args()
    batch = Batch.of(args)
    opts = MissionOptions(n_rescuers=args.rescuers, n_nodes=args.nodes,
                          range_sigma_m=args.range_sigma_m,
                          node_failure_fraction=args.node_failure)
    rows: dict[str, dict[str, list[float]]] = {
        m: {"mean": [], "p90": [], "max": [], "frac": [], "rmse": [], "anees": []}
        for m in ("off", "on")}
    nees_all: dict[str, list[float]] = {"off": [], "on": []}
    t0 = time.perf_counter()
    items = [SeedItem(seed, opts) for seed in _seeds(args.seeds)]
    for item, scores in batch.map(run_seed, items, label=lambda it: f"seed {it.seed}"):
        for mode in ("off", "on"):
            m = scores[mode]
            r = rows[mode]
            r["mean"].append(m.mean)
            r["p90"].append(m.p90)
            r["max"].append(m.max)
            r["frac"].append(m.frac)
            r["anees"].append(m.anees)
            r["rmse"].append(m.rmse)
            nees_all[mode].extend(m.node_nees)
            print(f"seed {item.seed} {mode:>3}: err mean {m.mean:.2f} p90 {m.p90:.2f} max "
                  f"{m.max:.2f} m; nodes {m.frac:.2f} rmse {m.rmse:.2f} m; agent NEES "
                  f"{m.anees:.1f}; node NEES "
                  f"{np.mean(m.node_nees) if m.node_nees else float('nan'):.2f}", flush=True)
    print(f"\nseeds {args.seeds}, {args.rescuers} rescuers, {args.nodes} nodes, range sigma "
          f"{args.range_sigma_m} m, node failure {args.node_failure}; values are mean / p90 / "
          f"worst over seeds ({time.perf_counter() - t0:.0f} s)\n")
    print("| cooperation | rescuer error mean, m | rescuer error p90, m | rescuer error max, m "
          "| agent NEES | nodes localized | node RMSE, m | node NEES (mean; 95 % bounds) |")
    print("|---|---|---|---|---|---|---|---|")
    for mode in ("off", "on"):
        r = rows[mode]
        n = len(nees_all[mode])
        lo, hi = (chi2.ppf(0.025, 2 * n) / n, chi2.ppf(0.975, 2 * n) / n) if n else (0, 0)
        nees = f"{np.mean(nees_all[mode]):.2f} ({lo:.2f}-{hi:.2f}, n={n})" if n else "-"
        print(f"| {mode} | {_stats(r['mean'])} | {_stats(r['p90'])} | {_stats(r['max'])} "
              f"| {_stats(r['anees'])} | {_stats(r['frac'])} | {_stats(r['rmse'])} | {nees} |")
    batch.finish()


if __name__ == "__main__":
    main()
