"""Where the agents' NEES tail is: agent, seed, time since the feedback or a tag (issue 18).

Runs the hybrid mission (2 % ranges, cooperation on, the library's default smoother mode,
``--peer-ranges``: with the inter-agent ranges) and scores every agent's track at 1 Hz against
the truth (read here, for scoring only): the 2-dof NEES per agent and seed, pooled per bin of
the time since the agent's latest smoother feedback (``SMOOTHED`` correction) and since its
latest tag read, per 100 s of its walk, and at each feedback the NEES of the state just before
and just after it::

    python benchmarks/mission_nees_tail.py --seeds 0-9
"""

from __future__ import annotations

import argparse
import math
from collections import defaultdict
from dataclasses import replace
from typing import Any

import numpy as np

from _engine import parse_seeds
from _mission_nees import time_bin
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline.corrections import SMOOTHED
from hrtls.pipeline.schedule import TAGS
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission
from mission_robot_peers import rescuer_config, truth_xy

SINCE_BINS_S = (2.0, 5.0, 10.0, 30.0, 60.0)


def _since(t: np.ndarray, events: np.ndarray) -> np.ndarray:
    """Time since the latest event at or before each ``t`` (inf before the first)."""
    if len(events) == 0:
        return np.full(len(t), math.inf)
    e = np.sort(events)
    k = np.searchsorted(e, t, side="right") - 1
    return np.where(k >= 0, t - e[np.maximum(k, 0)], math.inf)


def _label(dt: float) -> str:
    lo, hi = time_bin(dt, SINCE_BINS_S)
    return f"{lo:g}-{hi:g} s" if math.isfinite(hi) else f">= {lo:g} s"


def run(seed: int, peers: bool) -> dict[str, Any]:
    """One seed: per agent its NEES samples with their bins, and its feedbacks' NEES."""
    mission = inderst_hybrid_mission(seed, replace(MissionOptions(range_sigma_fraction=0.02),
                                                   peer_ranges=peers))
    mt = MissionTracker(mission.agents, params=MissionParams(), kinds=mission.kinds,
                        config=rescuer_config())
    mt.feed_network(mission.network_ranges)
    res = mt.run()
    out: dict[str, Any] = {}
    for name, ar in res.agents.items():
        tr = ar.trajectory
        tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
        xy = np.column_stack([np.interp(tq, tr.t, tr.xyz[:, k]) for k in (0, 1)])
        d = xy - truth_xy(mission, name, tq)
        j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
        nees = np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d)
        corr = mt.trackers[name].corrections_since(0)
        fed = corr.kind == SMOOTHED
        tags = corr.t[corr.kind == TAGS]
        x_true = truth_xy(mission, name, corr.t[fed])
        e0, e1 = corr.mean0_m[fed] - x_true, corr.mean1_m[fed] - x_true
        out[name] = {
            "kind": mission.kinds.get(name, "rescuer"), "nees": nees,
            "since_fb": _since(tq, corr.t[fed]), "since_tag": _since(tq, tags),
            "walked": tq - tq[0],
            "fb0": np.einsum("ki,kij,kj->k", e0, np.linalg.inv(corr.cov0_m2[fed]), e0),
            "fb1": np.einsum("ki,kij,kj->k", e1, np.linalg.inv(corr.cov1_m2[fed]), e1),
            "err": np.hypot(d[:, 0], d[:, 1])}
    return out


def _pool(table: dict[str, list[float]], title: str) -> None:
    n = sum(len(v) for v in table.values())
    print(f"\n| {title} | NEES mean | median | p90 | share of samples |\n|---|---|---|---|---|")
    for key in sorted(table, key=lambda k: (len(k), k)):
        a = np.asarray(table[key])
        print(f"| {key} | {np.mean(a):.2f} | {np.median(a):.2f} | {np.percentile(a, 90):.2f} "
              f"| {len(a) / n:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="development seeds only (0-9)")
    ap.add_argument("--peer-ranges", action="store_true", help="with inter-agent ranges")
    args = ap.parse_args()
    by_fb: dict[str, list[float]] = defaultdict(list)
    by_tag: dict[str, list[float]] = defaultdict(list)
    by_walk: dict[str, list[float]] = defaultdict(list)
    fb0: list[float] = []
    fb1: list[float] = []
    print("| seed | " + " | ".join(["agent: NEES mean / p90, error p90 m"] * 4) + " |")
    for seed in parse_seeds(args.seeds):
        out = run(seed, args.peer_ranges)
        cells = []
        for name, a in sorted(out.items()):
            cells.append(f"{name}: {np.mean(a['nees']):.2f} / "
                         f"{np.percentile(a['nees'], 90):.1f}, {np.percentile(a['err'], 90):.2f}")
            if a["kind"] != "rescuer":
                continue
            for k, v in enumerate(a["nees"]):
                by_fb[_label(float(a["since_fb"][k]))].append(float(v))
                by_tag[_label(float(a["since_tag"][k]))].append(float(v))
                by_walk[f"{int(a['walked'][k] // 100) * 100:03d} s"].append(float(v))
            fb0 += a["fb0"].tolist()
            fb1 += a["fb1"].tolist()
        print(f"| {seed} | " + " | ".join(cells) + " |", flush=True)
    _pool(by_fb, "rescuers, since feedback")
    _pool(by_tag, "rescuers, since tag")
    _pool(by_walk, "rescuers, walked")
    if fb0:
        print(f"\nAt the feedbacks (n = {len(fb0)}): NEES before mean {np.mean(fb0):.2f} "
              f"(p90 {np.percentile(fb0, 90):.2f}), after mean {np.mean(fb1):.2f} "
              f"(p90 {np.percentile(fb1, 90):.2f})")


if __name__ == "__main__":
    main()
