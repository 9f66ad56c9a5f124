"""Where the range-SLAM smoother's pose and node errors come from (diagnosis; reads the truth).

Runs the hybrid mission of each seed once with the smoother (the study's feedback preset:
``--feedback implied --every-s 10 --feedback-cov-scale 2 --feedback-gate 13.8``, cooperation
on, 2 % range noise) and keeps what the loop gave the smoother (cached in ``--cache``). Then,
for each smoother variant, it re-solves the kept data cut at every ``--step-s`` of mission time
(each solve warm-started from the previous, as the loop does) and scores against the truth:

* the latest pose of every agent at each cut (what the feedback gives back): RMS error and
  NEES (2 dof) with the smoother's covariance;
* the nodes the smoother localizes at the last cut: RMSE and NEES;
* every pose at the last cut: RMS error.

The estimator never sees the truth: only the scoring here reads it.

```bash
python benchmarks/smoother_diag.py --seeds 0-9 --variants base,drop,frac20,tracker,corr10
```
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mission as bench
from hrtls.mission import smoothing
from hrtls.mission.graph import SmootherParams, SmootherResult, smooth
from hrtls.pipeline.tracker import Tracker
from hrtls.sim.mission import MissionOptions

PRESET = SmootherParams(feedback="implied", every_s=10.0, feedback_cov_scale=2.0,
                        feedback_gate=13.8)
MERGED: dict[str, Any] = {"range_correlation_s": 0.0, "min_spread_m": 2.0,
                          "localize_spread_m": 2.0}
"""The model before the options of ``range_correlation_s`` and ``localize_spread_m``."""
VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "base": MERGED,
    "drop": {**MERGED, "heading_updates": "drop"},
    "chain": {**MERGED, "heading_updates": "chain"},
    "tracker": {**MERGED, "increment_noise": "tracker"},
    "frac05": {**MERGED, "odo_fraction": 0.05},
    "frac20": {**MERGED, "odo_fraction": 0.20},
    "chain-frac20": {**MERGED, "heading_updates": "chain", "odo_fraction": 0.20},
    "drop-frac20": {**MERGED, "heading_updates": "drop", "odo_fraction": 0.20},
    "spread1": {**MERGED, "min_spread_m": 1.0, "localize_spread_m": 1.0},
    "spread05": {**MERGED, "min_spread_m": 0.5, "localize_spread_m": 0.5},
    "spread1-own2": {**MERGED, "min_spread_m": 1.0},
    "corr10": {**MERGED, "range_correlation_s": 10.0},
    "corr10-spread1": {**MERGED, "range_correlation_s": 10.0, "min_spread_m": 1.0,
                       "localize_spread_m": 1.0},
}
"""Variant name -> ``SmootherParams`` fields changed."""


def capture(seed: int, cache: Path) -> dict[str, Any]:
    """The loop's smoother data and the truth of one seed (cached)."""
    path = cache / f"seed{seed}.pkl"
    if path.exists():
        with path.open("rb") as f:
            return dict(pickle.load(f))
    kept: dict[str, Any] = {}
    run = bench._run_timed

    def spy(tracker: Any) -> Any:
        kept["mt"] = tracker
        return run(tracker)

    bench._run_timed = spy
    item = bench.SeedItem(seed, MissionOptions(range_sigma_fraction=0.02), only_on=True,
                          smoother=PRESET, prediction={
                              "q_along": bench.RESCUER.prediction.q_along,
                              "sigma_heading_increment_rad":
                                  bench.RESCUER.prediction.sigma_heading_increment_rad},
                          attitude={"heading_source": "gyro+compass", "mag_heading": {
                              "offset_model": bench.RESCUER.attitude.mag_heading["offset_model"]}},
                          tags={"sigma_per_accuracy": bench.RESCUER.tags.sigma_per_accuracy})
    bench.run_seed(item)
    bench._run_timed = run
    mt = kept["mt"]
    mission = bench.inderst_hybrid_mission(seed, item.options)
    truth = {n: (s.session.truth.t, s.session.truth.xyz[:, :2])
             for n, s in mission.simulations.items()}
    out = {"state": smoothing.state_of(mt.smoother), "names": list(mt.names),
           "known": [list(k) for k in mt.known], "truth": truth,
           "nodes": {k: np.asarray(v[:2]) for k, v in mission.node_truth_m.items()}}
    cache.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as f:
        pickle.dump(out, f)
    return out


def cut(data: dict[str, Any], t_s: float, prm: SmootherParams) -> Any:
    """A stand-in for the mission tracker with the kept data up to ``t_s``."""
    st = smoothing.state_from(data["state"])
    assert st is not None
    st.rows = {k: [r for r in v if r[0] <= t_s] for k, v in st.rows.items()}
    st.tail = {}
    st.ranges = [[p[0], *(np.asarray(a)[np.asarray(p[1]) <= t_s] for a in p[1:])]
                 for p in st.ranges]
    st.corr = {k: [[np.asarray(a)[np.asarray(b[0]) <= t_s] for a in b] for b in v]
               for k, v in st.corr.items()}
    stub = object.__new__(Tracker)
    return SimpleNamespace(smoother=st, params=SimpleNamespace(smoother=prm),
                           names=data["names"], known=[np.asarray(k) for k in data["known"]],
                           trackers=dict.fromkeys(data["names"], stub))


def score(data: dict[str, Any], prm: SmootherParams, step_s: float) -> dict[str, list[float]]:
    """Latest-pose errors / NEES over the cuts; node and pose errors at the last cut."""
    end = max(r[-1][0] for r in data["state"]["rows"].values() if r)
    warm: SmootherResult | None = None
    out: dict[str, list[float]] = {"pose_e2": [], "pose_nees": [], "node_e2": [],
                                   "node_nees": [], "path_e2": [], "rms": []}
    for t in [*np.arange(step_s, end, step_s), end]:
        got = smoothing.problem(cut(data, float(t), prm))
        if got is None:
            continue
        warm = smooth(*got, params=prm, warm=warm)
        out["rms"].append(warm.rms)
        for name, (ta, m, p) in warm.last_pose.items():
            tt, xy = data["truth"][name]
            e = m - np.array([np.interp(ta, tt, xy[:, 0]), np.interp(ta, tt, xy[:, 1])])
            if np.all(np.isfinite(p)):
                out["pose_e2"].append(float(e @ e))
                out["pose_nees"].append(float(e @ np.linalg.solve(p, e)))
    assert warm is not None
    for node, (p, c, ok) in warm.nodes.items():
        if ok:
            e = p - data["nodes"][node]
            out["node_e2"].append(float(e @ e))
            out["node_nees"].append(float(e @ np.linalg.solve(c, e)))
    for name, (tp, xp) in warm.paths.items():
        tt, xy = data["truth"][name]
        e = xp - np.column_stack([np.interp(tp, tt, xy[:, 0]), np.interp(tp, tt, xy[:, 1])])
        out["path_e2"].extend(np.sum(e * e, axis=1).tolist())
    return out


def _row(name: str, per_seed: list[dict[str, list[float]]]) -> str:
    def rms(k: str) -> list[float]:
        return [math.sqrt(np.mean(s[k])) if s[k] else math.nan for s in per_seed]

    def mean(k: str) -> list[float]:
        return [float(np.mean(s[k])) if s[k] else math.nan for s in per_seed]

    pooled = {k: [v for s in per_seed for v in s[k]] for k in ("pose_nees", "node_nees")}
    cells = [bench._stats(rms("node_e2")), f"{np.mean(pooled['node_nees']):.2f}",
             bench._stats(mean("node_nees")), bench._stats(rms("pose_e2")),
             f"{np.mean(pooled['pose_nees']):.2f}", bench._stats(rms("path_e2")),
             f"{np.nanmean([x for s in per_seed for x in s['rms']]):.2f}"]
    return f"| {name} | " + " | ".join(cells) + " |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="dev seeds only (0-9)")
    ap.add_argument("--variants", default="default,base", help=", ".join(VARIANTS))
    ap.add_argument("--step-s", type=float, default=30.0)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/hrtls_smoother_diag"))
    args = ap.parse_args()
    seeds = bench.parse_seeds(args.seeds)
    data = {s: capture(s, args.cache) for s in seeds}
    print("| variant | own node RMSE, m | node NEES pooled | node NEES per seed | latest pose "
          "RMS, m | latest pose NEES pooled | all poses RMS, m | range RMS |")
    print("|---|---|---|---|---|---|---|---|")
    for v in args.variants.split(","):
        prm = replace(PRESET, **VARIANTS[v])
        print(_row(v, [score(data[s], prm, args.step_s) for s in seeds]), flush=True)


if __name__ == "__main__":
    main()
