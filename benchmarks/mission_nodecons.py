"""Node consistency diagnosis on the hybrid mission, cooperation off (issue 18; scoring only).

With cooperation off the agents never use nodes, so the node readings of a seed do not depend on
the node estimator: ``dump`` tracks each seed once and stores every node's readings with the
agents' true positions at the readings (truth read for scoring only, never given to the
estimator); ``report`` then runs :class:`~hrtls.mission.nodes.NodeEstimator` variants on them and
prints, per variant, the localized fraction, node RMSE and NEES (mean / p90 / worst over seeds and
pooled), split by chains and passes, and the error sources of the module doc of
:mod:`hrtls.mission.nodes`.

    python benchmarks/mission_nodecons.py dump --seeds 0-9 --out /tmp/nc
    python benchmarks/mission_nodecons.py report --seeds 0-9 --out /tmp/nc [--no-times]
        [--set max_mirror_passes=2 range_correlation_s=0 ...]
"""

from __future__ import annotations

import argparse
import pickle
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from _engine import parse_seeds
from hrtls.mission.nodes import NodeEstimator, NodeEstimatorParams, NodeRanges
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import RESCUER_PREDICTION, MissionOptions, inderst_hybrid_mission


def dump_seed(seed: int, opts: MissionOptions, out: Path) -> None:
    """Track ``seed`` with cooperation off; store each node's readings and the truth there."""
    mission = inderst_hybrid_mission(seed, opts)
    tracker = MissionTracker(mission.agents, params=MissionParams(cooperate=False),
                             kinds=mission.kinds, config=TrackerConfig.model_validate(
                                 {"prediction": dict(RESCUER_PREDICTION),
                                  "attitude": {"heading_source": "gyro+compass"}}))
    res = tracker.run()
    truth = {}
    for name in tracker.names:
        tr = mission.simulations[name].session.truth
        assert tr is not None
        truth[name] = (tr.t, tr.xyz[:, :2])
    nodes: dict[str, Any] = {}
    for node, rd in tracker.readings.items():
        obs = rd.ranges(tracker.params.pass_gap_s)
        ag, t = np.asarray(rd.agent), np.asarray(rd.t)
        xy = np.zeros((len(t), 2))
        for i, name in enumerate(tracker.names):
            m = ag == i
            xy[m, 0] = np.interp(t[m], truth[name][0], truth[name][1][:, 0])
            xy[m, 1] = np.interp(t[m], truth[name][0], truth[name][1][:, 1])
        nodes[node] = {"obs": obs, "t": t, "true_xy": xy,
                       "truth": np.asarray(mission.node_truth_m[node][:2], float),
                       "final": res.nodes.get(node)}
    agents = {}
    for name, ares in res.agents.items():
        tr = ares.trajectory
        agents[name] = (tr.t, tr.xyz[:, :2], tr.cov_xy, truth[name])
    with open(out / f"seed{seed}.pkl", "wb") as f:
        pickle.dump({"nodes": nodes, "agents": agents, "n_nodes": len(mission.node_truth_m)}, f)


def _nees(d: np.ndarray, cov: np.ndarray) -> np.ndarray:
    return np.einsum("ki,kij,kj->k", d, np.linalg.inv(cov), d)


def node_rows(data: dict[str, Any], prm: NodeEstimatorParams, *, times: bool = True
              ) -> list[dict[str, float]]:
    """One row per node with readings: localized, error, NEES, chains, passes and sources
    (``times``: the readings with their times, else without: no drift, no autocorrelation)."""
    est = NodeEstimator(prm)
    rows = []
    for nd in data["nodes"].values():
        obs: NodeRanges = replace(nd["obs"], t_s=nd["t"] if times else None)
        e = est.estimate(obs)
        row: dict[str, float] = {"localized": float(e.localized)}
        if e.localized:
            d = e.position_m - nd["truth"]
            row["err2"] = float(d @ d)
            row["nees"] = float(d @ np.linalg.solve(e.covariance_m2, d))
            row["sigma"] = float(np.sqrt(np.linalg.eigvalsh(e.covariance_m2)[-1]))
            u = e.used
            row["chains"] = float(np.unique(obs.chain[u]).size)
            row["passes"] = float(np.unique(obs.group[u]).size)
            ae = obs.agent_xy_m[u] - nd["true_xy"][u]
            row["agent_nees"] = float(np.mean(_nees(ae, obs.agent_cov_m2[u])))
            grp = obs.group[u]
            within, total, whit = [], [], []
            chain_mean = {}
            for g in np.unique(grp).tolist():
                m = grp == g
                mu = ae[m].mean(axis=0)
                within.append(float(np.mean(np.sum((ae[m] - mu) ** 2, axis=1))))
                total.append(float(np.mean(np.sum(ae[m] ** 2, axis=1))))
                pg = prm.agent_cov_scale * obs.agent_cov_m2[u][m].mean(axis=0)
                whit.append(float(mu @ np.linalg.solve(pg, mu)))
            for c in np.unique(obs.chain[u]).tolist():
                chain_mean[c] = ae[obs.chain[u] == c].mean(axis=0)
            row["within"] = float(np.mean(within))
            row["total"] = float(np.mean(total))
            row["pass_whit"] = float(np.mean(whit))
            cs = list(chain_mean.values())
            dots, sq = [], []
            for i in range(len(cs)):
                sq.append(float(cs[i] @ cs[i]))
                for j in range(i + 1, len(cs)):
                    dots.append(float(cs[i] @ cs[j]))
            row["cross_dot"] = float(np.mean(dots)) if dots else float("nan")
            row["chain_sq"] = float(np.mean(sq))
            true_r = np.linalg.norm(nd["true_xy"] - nd["truth"], axis=1)
            excess = obs.range_m - true_r
            row["nlos_used"] = float(np.mean(excess[u] > 3 * obs.range_sigma_m[u]))
            row["excess_used"] = float(np.mean(excess[u]))
            row["nlos_all"] = float(np.mean(excess > 3 * obs.range_sigma_m))
            tr = replace(obs, agent_xy_m=nd["true_xy"], agent_cov_m2=0 * obs.agent_cov_m2)
            et = est.estimate(tr)
            row["true_err2"] = (float(np.sum((et.position_m - nd["truth"]) ** 2))
                                if et.localized else float("nan"))
        rows.append(row)
    return rows


def agent_nees(data: dict[str, Any]) -> np.ndarray:
    """The agents' NEES at 1 Hz over their tracks (as ``benchmarks/mission.py``)."""
    out = []
    for t, xy, cov, (tt, txy) in data["agents"].values():
        tq = np.arange(float(t[0]), float(t[-1]), 1.0)
        d = np.column_stack([np.interp(tq, t, xy[:, 0]) - np.interp(tq, tt, txy[:, 0]),
                             np.interp(tq, t, xy[:, 1]) - np.interp(tq, tt, txy[:, 1])])
        j = np.clip(np.searchsorted(t, tq), 0, len(t) - 1)
        out.append(_nees(d, cov[j]))
    return np.concatenate(out)


def report(seeds: list[int], out: Path, prm: NodeEstimatorParams, *, times: bool = True
           ) -> None:
    """Per seed and pooled: localized, RMSE, NEES; split by chains; error sources."""
    allrows: list[dict[str, float]] = []
    per = {"frac": [], "rmse": [], "nees": []}
    anees = []
    for seed in seeds:
        with open(out / f"seed{seed}.pkl", "rb") as f:
            data = pickle.load(f)
        rows = node_rows(data, prm, times=times)
        anees.append(float(np.mean(agent_nees(data))))
        loc = [r for r in rows if r["localized"]]
        allrows += loc
        per["frac"].append(len(loc) / data["n_nodes"])
        per["rmse"].append(float(np.sqrt(np.mean([r["err2"] for r in loc]))) if loc else np.nan)
        per["nees"].append(float(np.mean([r["nees"] for r in loc])) if loc else np.nan)
        print(f"seed {seed}: localized {per['frac'][-1]:.2f} rmse {per['rmse'][-1]:.2f} "
              f"node NEES {per['nees'][-1]:.2f} agent NEES {anees[-1]:.2f}", flush=True)

    def st(x: list[float]) -> str:
        a = np.asarray(x, float)
        return f"{np.nanmean(a):.2f} / {np.nanpercentile(a, 90):.2f} / {np.nanmax(a):.2f}"

    print(f"\nlocalized {st(per['frac'])}; rmse {st(per['rmse'])}; node NEES per seed "
          f"{st(per['nees'])}; pooled {np.mean([r['nees'] for r in allrows]):.2f} "
          f"(n={len(allrows)}); agents' NEES (1 Hz, whole tracks) {st(anees)}")
    keys = ("nees", "agent_nees", "pass_whit", "within", "total", "chain_sq", "cross_dot",
            "nlos_used", "excess_used", "nlos_all", "sigma")
    print("\n| nodes | n | RMSE, m | from true agents, m | " + " | ".join(keys) + " |")
    print("|---" * (len(keys) + 4) + "|")
    splits = [("all", lambda r: True)]
    splits += [(f"{c} chain(s)", lambda r, c=c: r["chains"] == c) for c in (1, 2, 3)]
    splits += [("passes <= 3", lambda r: r["passes"] <= 3),
               ("passes 4-8", lambda r: 4 <= r["passes"] <= 8),
               ("passes > 8", lambda r: r["passes"] > 8),
               ("sigma < 1 m", lambda r: r["sigma"] < 1), ("sigma 1-3 m",
                                                         lambda r: 1 <= r["sigma"] < 3),
               ("sigma >= 3 m", lambda r: r["sigma"] >= 3)]
    for name, f in splits:
        sel = [r for r in allrows if f(r)]
        if not sel:
            continue
        vals = [np.nanmean([r[k] for r in sel]) for k in keys]
        rm = np.sqrt(np.mean([r["err2"] for r in sel]))
        rt = np.sqrt(np.nanmean([r["true_err2"] for r in sel]))
        print(f"| {name} | {len(sel)} | {rm:.2f} | {rt:.2f} | "
              + " | ".join(f"{v:.2f}" for v in vals) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("dump", "report"))
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--out", default="/tmp/nc")
    ap.add_argument("--range-sigma-fraction", type=float, default=0.0)
    ap.add_argument("--no-times", action="store_true",
                    help="readings without their times (the estimator before the drift and "
                         "autocorrelation terms; with --set max_mirror_passes=2: as before)")
    ap.add_argument("--set", nargs="*", default=[],
                    help="NodeEstimatorParams overrides, e.g. agent_cov_scale=4")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    opts = MissionOptions(range_sigma_fraction=args.range_sigma_fraction)
    for seed in parse_seeds(args.seeds):
        if args.what == "dump":
            dump_seed(seed, opts, out)
            print(f"seed {seed} dumped", flush=True)
    if args.what == "report":
        prm = NodeEstimatorParams()
        for kv in args.set:
            k, v = kv.split("=")
            prm = replace(prm, **{k: type(getattr(prm, k))(float(v))})
        report(parse_seeds(args.seeds), out, prm, times=not args.no_times)


if __name__ == "__main__":
    main()
