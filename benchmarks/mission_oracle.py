"""Upper bound of cooperation on the hybrid mission: the agents given the nodes' positions.

Runs ``inderst_hybrid_mission`` (door tags, one robot, ``--range-sigma-fraction``) with
cooperation off, once as the mission is (the nodes unknown) and once per ``--sigmas`` value with
every node handed to every agent as a range anchor at its TRUE position plus a Gaussian error of
that 1-sigma (m, per node, the same for all agents; drawn from the seed). The anchors are read
from the simulator's truth: this is a bound on what better node estimates could give the
rescuers, not an estimator. The anchor's sigma is added to the variance of each range to it
(as if its error were independent between ranges: the trackers are then over-confident, so the
agent NEES of the bound rows is not meaningful; their accuracy is the bound).

Prints, over the seeds, mean / p90 / worst of the rescuers' error p90 (1 Hz over every walk)
and its reduction against the unknown-node run, on the mean over seeds and at the seeds' p90
(issue 18's cooperation target: 30 % at the p90 over held-out seeds).

    python benchmarks/mission_oracle.py --seeds 100-129 --sigmas 0,0.25,0.5
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from _engine import parse_seeds
from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission
from mission import RESCUER, agent_errors


def with_anchors(mission: Mission, sigma_m: float, rng: np.random.Generator) -> dict:
    """The agents' sessions with every node as an anchor at truth + N(0, sigma_m^2 I)."""
    anchors = {}
    for node, p in sorted(mission.node_truth_m.items()):
        e = rng.normal(0.0, sigma_m, 2)
        anchors[node] = Landmark(id=node, kind="node", accuracy_m=max(sigma_m, 1e-3),
                                 position=(float(p[0] + e[0]), float(p[1] + e[1]), 0.5))
    out = {}
    for k, s in mission.agents.items():
        r = s.ranges
        if r is not None:
            r = RangeMeasurements(r.t, r.node, r.range_m, np.hypot(r.sigma_m, sigma_m))
        out[k] = dataclasses.replace(s, landmarks={**s.landmarks, **anchors}, ranges=r)
    return out


def rescuer_p90(mission: Mission, agents: dict) -> tuple[float, float]:
    """Rescuers' error p90 (m) and robot's error p90 (m), cooperation off."""
    tracker = MissionTracker(agents, params=MissionParams(cooperate=False), kinds=mission.kinds,
                             config=RESCUER)
    res = tracker.run()
    robot = agent_errors(mission, res, "robot")[0]
    return (float(np.percentile(agent_errors(mission, res)[0], 90)),
            float(np.percentile(robot, 90)) if len(robot) else float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="e.g. 0-9 (dev) or 100-129 (held-out)")
    ap.add_argument("--sigmas", default="0,0.5", help="node position errors, m (comma list)")
    ap.add_argument("--range-sigma-fraction", type=float, default=0.02)
    args = ap.parse_args()
    sigmas = [float(s) for s in args.sigmas.split(",")]
    opts = MissionOptions(range_sigma_fraction=args.range_sigma_fraction)
    rows: dict[str, list[tuple[float, float]]] = {"unknown": []}
    for seed in parse_seeds(args.seeds):
        mission = inderst_hybrid_mission(seed, opts)
        rows["unknown"].append(rescuer_p90(mission, dict(mission.agents)))
        for s in sigmas:
            rng = np.random.default_rng([seed, round(1000 * s)])
            agents = with_anchors(mission, s, rng)
            rows.setdefault(f"{s:g}", []).append(rescuer_p90(mission, agents))
        print(f"seed {seed}: " + ", ".join(f"{k} {v[-1][0]:.2f}" for k, v in rows.items()),
              flush=True)
    base = np.array(rows["unknown"])[:, 0]
    print(f"\nseeds {args.seeds}, range sigma 0.1 m + {100 * args.range_sigma_fraction:g} %, "
          "cooperation off; mean / p90 / worst over seeds\n")
    print("| nodes | rescuer error p90, m | reduction on the mean | reduction at the seeds' p90 "
          "| robot error p90, m |")
    print("|---|---|---|---|---|")
    for k, v in rows.items():
        a = np.array(v)
        p = a[:, 0]
        label = "unknown (mission as is)" if k == "unknown" else f"known, sigma {k} m"
        print(f"| {label} | {p.mean():.2f} / {np.percentile(p, 90):.2f} / {p.max():.2f} | "
              f"{100 * (1 - p.mean() / base.mean()):.0f} % | "
              f"{100 * (1 - np.percentile(p, 90) / np.percentile(base, 90)):.0f} % | "
              f"{np.nanmean(a[:, 1]):.2f} |")


if __name__ == "__main__":
    main()
