"""The robot's inter-agent range corrections against the truth (diagnosis, issue 18).

Runs the hybrid mission (2 % ranges, inter-agent ranges on, cooperation on, the library's
default smoother mode unless ``--mode``) and reads back every peer range the robot's EKF took:
the peer's landmark (position and the variance the rule gave it), the range's sigma as used,
and the robot's position and covariance before and after the update. The truth (read here,
for scoring only) gives per update:

* the robot's 2-dof NEES before / after and its error before / after, m;
* the peer landmark's error against the peer's true position at the range's time, and its
  1-dof NEES along the line of sight against the variance the rule claimed;
* the range's normalized residual from the robot's TRUE position, ``(r - |x_true - b|) /
  sigma_used`` (a consistent rule gives a unit RMS; with ``--peer-rule intersect`` the sigma
  is the range's own, the peer's variance is taken in the robot's update, so the column does
  not apply).

Printed per peer over the seeds, and the robot's NEES at 1 Hz over the whole track::

    python benchmarks/mission_robot_peers.py --seeds 0-9 [--mode feedback] [--peer-rule widen]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import Any

import numpy as np

from _engine import parse_seeds
from hrtls.mission import peers as peers_mod
from hrtls.mission import tracker as tracker_mod
from hrtls.mission.peers import RULES, PeerRangeParams
from hrtls.mission.robot import RobotTracker
from hrtls.mission.smoother_modes import MODES, smoother_params
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission

RESCUER = preset("rescue-mission")


def rescuer_config() -> TrackerConfig:
    """The rescuers' configuration of ``benchmarks/mission.py``'s defaults."""
    return TrackerConfig.model_validate({
        "prediction": {"q_along": RESCUER.prediction.q_along,
                       "sigma_heading_increment_rad":
                           RESCUER.prediction.sigma_heading_increment_rad},
        "attitude": {"heading_source": "gyro+compass",
                     "mag_heading": {"offset_model":
                                     RESCUER.attitude.mag_heading["offset_model"]}},
        "tags": {"sigma_per_accuracy": RESCUER.tags.sigma_per_accuracy}})


def truth_xy(mission: Mission, name: str, t: np.ndarray) -> np.ndarray:
    truth = mission.simulations[name].session.truth
    assert truth is not None
    return np.column_stack([np.interp(t, truth.t, truth.xyz[:, 0]),
                            np.interp(t, truth.t, truth.xyz[:, 1])])


def run(seed: int, mode: str | None, rule: str | None = None) -> dict[str, Any]:
    """One seed: the robot's peer updates and its track's NEES (module doc)."""
    mission = inderst_hybrid_mission(seed, replace(MissionOptions(range_sigma_fraction=0.02),
                                                   peer_ranges=True))
    prm = MissionParams() if mode is None else MissionParams(smoother=smoother_params(mode))
    if rule is not None:
        prm = replace(prm, peer_ranges=PeerRangeParams(rule=rule))
    mt = MissionTracker(mission.agents, params=prm, kinds=mission.kinds, config=rescuer_config())
    mt.feed_network(mission.network_ranges)
    robot = next(n for n, k in mission.kinds.items() if k == "robot")
    given: list[tuple[float, str, float, float, float]] = []
    orig = peers_mod.split_peer_ranges

    def split(m: MissionTracker, i: int, ranges: Any) -> Any:
        rest, peer_r = orig(m, i, ranges)
        if m.names[i] == robot and peer_r is not None:
            tr = m.trackers[robot]
            assert isinstance(tr, RobotTracker)
            for k in range(len(peer_r.t)):
                peer = str(peer_r.node[k])
                pos = tr.peers[peer] if peer in tr.peers else tr.landmarks[peer]
                given.append((float(peer_r.t[k]), str(peer_r.node[k]), float(pos[0]),
                              float(pos[1]), float(peer_r.sigma_m[k])))
        return rest, peer_r

    tracker_mod.split_peer_ranges = split  # type: ignore[assignment]
    try:
        res = mt.run()
    finally:
        tracker_mod.split_peer_ranges = orig
    corr = mt.trackers[robot].corrections_since(0)
    rg = mission.agents[robot].ranges
    assert rg is not None
    lookup = {(g[0], g[1]): g for g in given}
    rows = []
    for k in range(len(corr)):
        g = lookup.get((float(corr.t[k]), str(corr.source[k])))
        if g is None:
            continue
        t = np.array([g[0]])
        x_true = truth_xy(mission, robot, t)[0]
        b_true = truth_xy(mission, g[1], t)[0]
        b = np.array([g[2], g[3]])
        e0, e1 = corr.mean0_m[k] - x_true, corr.mean1_m[k] - x_true
        m = (rg.t == g[0]) & (rg.node == g[1])
        r = float(rg.range_m[m][0]) if m.any() else float("nan")
        rows.append({"peer": g[1],
                     "nees0": float(e0 @ np.linalg.solve(corr.cov0_m2[k], e0)),
                     "nees1": float(e1 @ np.linalg.solve(corr.cov1_m2[k], e1)),
                     "err0": float(np.linalg.norm(e0)), "err1": float(np.linalg.norm(e1)),
                     "b_err": float(np.linalg.norm(b - b_true)), "sigma": g[4],
                     "resid": (r - float(np.linalg.norm(x_true - b))) / g[4]})
    tr = res.agents[robot].trajectory
    tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
    xy = np.column_stack([np.interp(tq, tr.t, tr.xyz[:, 0]), np.interp(tq, tr.t, tr.xyz[:, 1])])
    d = xy - truth_xy(mission, robot, tq)
    j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
    nees = np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d)
    return {"rows": rows, "nees": float(np.mean(nees)),
            "p90": float(np.percentile(np.hypot(d[:, 0], d[:, 1]), 90)),
            "n_given": len(given)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="development seeds only (0-9)")
    ap.add_argument("--mode", choices=MODES, default=None,
                    help="the smoother's named mode (default: the library's)")
    ap.add_argument("--peer-rule", choices=RULES, default=None,
                    help="PeerRangeParams.rule: the robot's peer correction (default: its default)")
    args = ap.parse_args()
    allrows: list[dict[str, Any]] = []
    print("| seed | robot p90, m | robot NEES | peer updates | NEES before / after "
          "| error before / after, m | RMS resid (true robot) |")
    print("|---|---|---|---|---|---|---|")
    for seed in parse_seeds(args.seeds):
        out = run(seed, args.mode, args.peer_rule)
        rows = out["rows"]
        allrows += rows
        if rows:
            a = {k: np.array([r[k] for r in rows]) for k in rows[0] if k != "peer"}
            print(f"| {seed} | {out['p90']:.2f} | {out['nees']:.2f} | {len(rows)} | "
                  f"{np.mean(a['nees0']):.2f} / {np.mean(a['nees1']):.2f} | "
                  f"{np.mean(a['err0']):.2f} / {np.mean(a['err1']):.2f} | "
                  f"{np.sqrt(np.mean(a['resid'] ** 2)):.2f} |", flush=True)
        else:
            print(f"| {seed} | {out['p90']:.2f} | {out['nees']:.2f} | 0 | | | |", flush=True)
    print("\n| peer | updates | NEES before / after | error before / after, m "
          "| peer error, m | RMS resid (true robot) | sigma used, m |")
    print("|---|---|---|---|---|---|---|")
    for peer in sorted({r["peer"] for r in allrows}):
        a = {k: np.array([r[k] for r in allrows if r["peer"] == peer])
             for k in allrows[0] if k != "peer"}
        print(f"| {peer} | {len(a['nees0'])} | {np.mean(a['nees0']):.2f} / "
              f"{np.mean(a['nees1']):.2f} | {np.mean(a['err0']):.2f} / {np.mean(a['err1']):.2f} "
              f"| {np.mean(a['b_err']):.2f} | {np.sqrt(np.mean(a['resid'] ** 2)):.2f} | "
              f"{np.median(a['sigma']):.2f} |")


if __name__ == "__main__":
    main()
