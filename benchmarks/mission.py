"""Hybrid mission study: rescuers' errors with and without cooperation; dropped nodes localized.

Simulates ``inderst_hybrid_mission`` per seed, tracks it with ``MissionTracker`` with cooperation
off and on (the estimator never sees the simulator's truth; the truth is read here, for scoring
only) and prints, over the seeds, mean / p90 / worst of (of the fraction localized: mean /
10th percentile / lowest):

* the rescuers' horizontal position error (sampled at 1 Hz while walking, all rescuers),
* the rescuers' NEES (2 dof, expected 2 when their covariance is consistent),
* the fraction of nodes localized at the end, their RMSE and mean NEES (2 dof, with the
  chi-square 95 % bounds of that mean over the localized nodes);
* the node RMSE the same estimator reaches from the same ranges taken at the agents' *true*
  positions (scoring only: how much of the node error is the agents' own error);
* the mission loop's cost per window (``chunk_s`` of every agent), first vs last quarter of the
  mission: the whole window, the agents' part (their trackers' updates and the reading
  collection, ``_collect``: flat when the per-agent cost does not grow with the mission's length)
  and the node re-estimation (grows with the readings of the nodes in range).

``--mode off|nodes|feedback``: the smoother's named mode (:mod:`hrtls.mission.smoother_modes`,
as ``hrtls mission track --smoother``); ``--smoother``: both columns with the range-SLAM
smoother (``MissionParams.smoother``, its default parameters; the cost table then gives its time
per solve); ``--feedback``: its latest
poses given back to the trackers (``SmootherParams.feedback``, ``--every-s``,
``--feedback-cov-scale``, ``--feedback-gate``, ``--feedback-ranges``); ``--window-s``: poses
older than this leave its problem as a prior (``SmootherParams.window_s``); its model:
``--increment-noise``, ``--heading-updates``, ``--odo-fraction``, ``--min-spread-m``,
``--localize-spread-m``, ``--smoother-correlation-s`` (``SmootherParams.range_correlation_s``).

``--peer-ranges``: cooperation on, the mission simulated without and with inter-agent ranges
(``MissionOptions.peer_ranges``, the rest of the mission identical); ``--peer-extrapolate``:
the peers carried to a range's time with their velocity (``PeerRangeParams.extrapolate``);
``--peer-rule``: a robot's peer correction, widening or covariance intersection
(``PeerRangeParams.rule``); ``--peer-factors-only``: with the smoother's peer factors no
tracker takes a peer range itself (``PeerRangeParams.factors_only``);
``--peer-factors on|off``: the inter-agent ranges as factors of the smoother
(``SmootherParams.peer_factors``).

``--node-ranges``: the dropped nodes range each other (``MissionOptions.node_ranges``, the
ranges fed by ``MissionTracker.feed_network``).

``--nees-split``: the agents' NEES split by time since their latest node use, the worst class
of their uses (independent, second-order loop, direct), the NEES of the latest node used, their
loop closures and their kind, pooled over the seeds (``benchmarks/_mission_nees.py``).

``--floors 2``: the two-floor building (``MissionOptions.n_floors``); a second table gives per
floor the nodes localized (and localized on the right floor) and their RMSE, the rescuers' share
of time on the right floor and their error per floor (``benchmarks/_mission_floors.py``).

``--why``: every node's class at the end (localized, never in range, too few readings, one
straight pass or mirror, a gate, sigma too large; ``benchmarks/_mission_why.py``), summed over
the seeds; ``--reach``: each seed's nodes not localized, each with where it was lost (never in
range, silent, not kept, seen from one corridor, rejected; ``benchmarks/_mission_reach.py``);
``--only-on`` / ``--only-off``: cooperation on / off only.
``--no-magnetometer`` / ``--no-hard-iron-fit``:
the rescuers' ``[attitude] use_magnetometer = false`` / ``mag_hard_iron = "off"`` (diagnosis of
their heading errors; ``benchmarks/mission_heading.py``); ``--heading-source gyro+compass``:
gyro-only step headings and the magnetic heading as a measurement (``hrtls.pipeline.mag_heading``;
``--offset-floor``: its ``offset_floor``; ``--offset-model``: its ``offset_model``, by default
the preset's).

The rescuers' trackers run the preset ``rescue-mission`` (its step-and-heading prediction noise
``--q-along`` / ``--heading-increment-rad``, its tag lobe sigma ``--tag-sigma-per-accuracy``) with
``[attitude] heading_source = "gyro+compass"`` (chosen on dev seeds; ``--heading-source filter``:
the tracker's default). The simulated rescuers follow their planner's way points by the estimate
of a tracker with ``hrtls.sim.mission.RESCUER_PREDICTION`` alone, so the
recordings of a seed do not depend on these options.

Dev seeds 0-9 (tuning); publish held-out seeds, e.g. ``--seeds 100-129``.

    python benchmarks/mission.py --seeds 100-129 [--engine local|ray] [--workers N]

Seeds run through ``--engine`` (``benchmarks/_engine.py``); the figures do not depend on it.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.stats import chi2

from _engine import Batch, add_engine_options, parse_seeds
from _mission_floors import KEYS as FLOOR_KEYS
from _mission_floors import floor_scores, floor_table
from _mission_nees import nees_split, nees_split_table
from _mission_reach import NodeReach, node_reach, reach_lines
from _mission_why import true_readings, why_not_localized, why_table
from hrtls.mission.graph import SmootherParams
from hrtls.mission.nodes import NodeEstimator, NodeEstimatorParams
from hrtls.mission.peers import RULES, PeerRangeParams
from hrtls.mission.smoother_modes import MODES, smoother_mode, smoother_params
from hrtls.mission.tracker import MissionParams, MissionResult, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission

RESCUER = preset("rescue-mission")
"""The rescuers' configuration the options below default to."""


def agent_errors(mission: Mission, result: MissionResult, kind: str = "rescuer"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal errors and their NEES (2 dof) at 1 Hz over every rescuer's (robot's) track."""
    errs, nees = [np.zeros(0)], [np.zeros(0)]
    for name, res in result.agents.items():
        if mission.kinds.get(name, "rescuer") != kind:
            continue
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


def _stats(x: list[float], *, higher_is_better: bool = False) -> str:
    """Mean / 90th percentile / worst over seeds (10th percentile / lowest when higher is
    better)."""
    a = np.asarray(x, dtype=float)
    if higher_is_better:
        return f"{np.mean(a):.2f} / {np.percentile(a, 10):.2f} / {np.min(a):.2f}"
    return f"{np.mean(a):.2f} / {np.percentile(a, 90):.2f} / {np.max(a):.2f}"


@dataclass(frozen=True)
class SeedItem:
    """One seed of the study."""

    seed: int
    options: MissionOptions
    nodes: NodeEstimatorParams = field(default_factory=NodeEstimatorParams)
    peers: bool = False
    """Compare cooperation on without and with peer ranges instead of cooperation off / on."""
    prediction: dict[str, float] = field(default_factory=dict)
    peer_extrapolate: bool = False
    """``PeerRangeParams.extrapolate``: peers carried to a range's time with their velocity."""
    only_on: bool = False
    """Cooperation on only (the ``off`` column skipped)."""
    smoother: SmootherParams | None = None
    """``MissionParams.smoother`` (None: the per-node estimator alone)."""
    attitude: dict[str, Any] = field(default_factory=dict)
    """The rescuers' ``[attitude]`` table (empty: the defaults)."""
    loop_closure_ratio: float | None = None
    """``MissionParams.loop_closure_ratio`` (None: its default)."""
    pass_cap: bool = True
    """``MissionParams.pass_cap``."""
    only_off: bool = False
    """Cooperation off only (the ``on`` column skipped)."""
    use_variance_ratio: float | None = None
    """``MissionParams.use_variance_ratio`` (None: its default)."""
    tags: dict[str, float] = field(default_factory=dict)
    """The rescuers' ``[tags]`` table (empty: the defaults)."""
    smooth_readings_s: float | None = None
    """``MissionParams.smooth_readings_s`` (None: its default)."""
    peer_rule: str | None = None
    """``PeerRangeParams.rule``: a robot's peer correction (None: its default)."""
    peer_factors_only: bool = False
    """``PeerRangeParams.factors_only``: with the smoother's peer factors no tracker takes one."""
    only_peers: bool = False
    """With ``peers``: the column with the inter-agent ranges only."""


def modes(peers: bool, only_on: bool = False, only_off: bool = False,
          only_peers: bool = False) -> tuple[str, ...]:
    """The columns compared: cooperation off / on (``only_on``: on, ``only_off``: off), or peer
    ranges off / on (``only_peers``: on)."""
    if peers and only_peers:
        return ("peers",)
    if only_off and not peers:
        return ("off",)
    return ("no peers", "peers") if peers else ("on",) if only_on else ("off", "on")


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
    robot_p90: float
    rmse_true_agents: float
    window_ms: tuple[float, float]
    agent_ms: tuple[float, float]
    nodes_ms: tuple[float, float]
    why: dict[str, int]
    """Nodes per class of ``_mission_why`` (why not localized)."""
    solve_s: tuple[float, float] = (float("nan"), float("nan"))
    nees_split: dict[str, list[float]] = field(default_factory=dict)
    """Agents' NEES per bin of ``_mission_nees.nees_split``."""
    floors: dict[str, float] = field(default_factory=dict)
    """``_mission_floors.floor_scores`` (two floors only)."""
    robot_nees: float = float("nan")
    """The robots' NEES (2 dof) at 1 Hz, mean."""
    reach: list[NodeReach] = field(default_factory=list)
    """The nodes not localized, each with its class (``_mission_reach``)."""


def _quarters(x: list[float]) -> tuple[float, float]:
    q = max(len(x) // 4, 1)
    return float(np.mean(x[:q])) * 1e3, float(np.mean(x[-q:])) * 1e3


def _run_timed(tracker: MissionTracker
               ) -> tuple[MissionResult, list[float], list[float], list[float]]:
    """Run the tracker window by window: the result, each window's time, its agents' part
    (trackers' updates and reading collection) and its node re-estimation."""
    spent = {"agents": [0.0], "nodes": [0.0]}

    def timed(fn: Callable[..., Any], part: str) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            out = fn(*args, **kwargs)
            spent[part][-1] += time.perf_counter() - t
            return out
        return run

    tracker._collect = timed(tracker._collect, "agents")  # type: ignore[method-assign]
    for tr in tracker.trackers.values():
        tr.update = timed(tr.update, "agents")  # type: ignore[method-assign]
    tracker.estimator.estimate = timed(tracker.estimator.estimate,  # type: ignore[method-assign]
                                       "nodes")
    windows: list[float] = []
    for t_start, t_end in tracker.windows():
        t = time.perf_counter()
        tracker.step(t_start, t_end)
        windows.append(time.perf_counter() - t)
        spent["agents"].append(0.0)
        spent["nodes"].append(0.0)
    return tracker.result(), windows, spent["agents"][:-1], spent["nodes"][:-1]


def _solves(tracker: MissionTracker) -> tuple[float, float]:
    """The smoother's solves: mean and largest time per solve, s (NaN without it)."""
    sec = [] if tracker.smoother is None else tracker.smoother.seconds
    return (float(np.mean(sec)), float(np.max(sec))) if sec else (float("nan"), float("nan"))


def true_agent_rmse(mission: Mission, tracker: MissionTracker) -> float:
    """Node RMSE from the same readings placed at the agents' true positions (zero covariance)."""
    est = NodeEstimator(tracker.params.nodes)
    d2 = []
    for node in tracker.readings:
        e = est.estimate(true_readings(mission, tracker, node))
        if e.localized:
            d = e.position_m - mission.node_truth_m[node]
            d2.append(float(d @ d))
    return float(np.sqrt(np.mean(d2))) if d2 else float("nan")


def run_seed(item: SeedItem) -> dict[str, ModeScores]:
    """Scores of one seed with cooperation ``off`` and ``on``."""
    out: dict[str, ModeScores] = {}
    for mode in modes(item.peers, item.only_on, item.only_off, item.only_peers):
        peers = mode == "peers"
        mission = inderst_hybrid_mission(item.seed, replace(item.options, peer_ranges=peers))
        tracker = MissionTracker(mission.agents, params=MissionParams(
            cooperate=mode in ("on", "peers", "no peers"), nodes=item.nodes,
            peer_ranges=PeerRangeParams(
                extrapolate=item.peer_extrapolate, factors_only=item.peer_factors_only,
                **({} if item.peer_rule is None else {"rule": item.peer_rule})),
            smoother=item.smoother, pass_cap=item.pass_cap,
            **({} if item.loop_closure_ratio is None else
               {"loop_closure_ratio": item.loop_closure_ratio}),
            **({} if item.use_variance_ratio is None else
               {"use_variance_ratio": item.use_variance_ratio}),
            **({} if item.smooth_readings_s is None else
               {"smooth_readings_s": item.smooth_readings_s})),
            kinds=mission.kinds,
            config=TrackerConfig.model_validate({"prediction": item.prediction,
                                                 "attitude": item.attitude, "tags": item.tags}))
        tracker.feed_network(mission.network_ranges)
        res, windows, agents_s, nodes_s = _run_timed(tracker)
        e, e_nees = agent_errors(mission, res)
        frac, rmse, nees = node_scores(mission, res)
        robot, robot_nees = agent_errors(mission, res, "robot")
        out[mode] = ModeScores(float(np.mean(e)), float(np.percentile(e, 90)),
                               float(np.max(e)), frac, float(np.mean(e_nees)), rmse, nees,
                               float(np.percentile(robot, 90)) if len(robot) else float("nan"),
                               true_agent_rmse(mission, tracker), _quarters(windows),
                               _quarters(agents_s), _quarters(nodes_s),
                               why_not_localized(mission, tracker, res), _solves(tracker),
                               nees_split(mission, res),
                               floor_scores(mission, res) if item.options.n_floors > 1 else {},
                               float(np.mean(robot_nees)) if len(robot) else float("nan"),
                               node_reach(mission, tracker, res))
    return out


def smoother_of(args: argparse.Namespace) -> SmootherParams | None:
    """``--smoother`` with ``--feedback``, ``--every-s``, ``--feedback-cov-scale``,
    ``--feedback-gate``, ``--window-s`` and the smoother's model options; without it the
    smoother of ``--mode`` (default: the library's, ``MissionParams().smoother``);
    ``--peer-factors``, ``--robots-take``, ``--link-bias-sigma-m``, ``--link-cov-scale`` and
    ``--link-join-tol-m`` on either."""
    links = {k: getattr(args, k) for k in ("link_bias_sigma_m", "link_cov_scale",
                                           "link_join_tol_m")
             if getattr(args, k) is not None}
    if not args.smoother:
        sm = MissionParams().smoother if args.mode is None else smoother_params(args.mode)
        if sm is not None and args.peer_factors is not None:
            sm = replace(sm, peer_factors=args.peer_factors == "on")
        if sm is not None and args.robots_take is not None:
            sm = replace(sm, robots=args.robots_take)
        return sm if sm is None else replace(sm, **links)
    kw: dict[str, Any] = {}
    for key in ("feedback", "robots_take", "every_s", "feedback_cov_scale", "feedback_gate",
                "feedback_ranges",
                "window_s", "increment_noise", "heading_updates", "odo_fraction", "min_spread_m",
                "localize_spread_m", "smoother_correlation_s"):
        if getattr(args, key) is not None:
            kw[{"smoother_correlation_s": "range_correlation_s", "robots_take": "robots"}.get(
                key, key)] = getattr(args, key)
    if args.peer_factors is not None:
        kw["peer_factors"] = args.peer_factors == "on"
    return SmootherParams(**kw, **links)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9", help="e.g. 0-9 (dev) or 100-129 (held-out)")
    ap.add_argument("--nodes", type=int, default=40)
    ap.add_argument("--rescuers", type=int, default=3)
    ap.add_argument("--robots", type=int, default=MissionOptions().n_robots)
    ap.add_argument("--tags", choices=("entrance", "doors"), default=MissionOptions().tag_layout,
                    help="MissionOptions.tag_layout: tags at the entrance only or at the doors too")
    ap.add_argument("--door-spacing-m", type=float, default=MissionOptions().door_spacing_m,
                    help="MissionOptions.door_spacing_m (doors along each wall)")
    ap.add_argument("--floors", type=int, choices=(1, 2), default=MissionOptions().n_floors,
                    help="MissionOptions.n_floors (2: the two-floor building)")
    ap.add_argument("--range-sigma-m", type=float, default=0.1)
    ap.add_argument("--range-sigma-fraction", type=float, default=0.0,
                    help="range noise proportional to the distance (0.02: the issue's 2 %%)")
    ap.add_argument("--robot-driver", choices=("random", "planner"), default="random",
                    help="robots on random routes or driven in closed loop by the planner")
    ap.add_argument("--rescuer-driver", choices=("random", "planner"), default="random",
                    help="rescuers on pre-generated random routes or walking to the planner's "
                         "way points in closed loop")
    ap.add_argument("--node-failure", type=float, default=0.0)
    ap.add_argument("--walk-s", type=float, default=300.0, help="each rescuer's walk, s")
    ap.add_argument("--peer-ranges", action="store_true",
                    help="cooperation on, without vs with inter-agent ranges")
    ap.add_argument("--node-ranges", action="store_true",
                    help="the dropped nodes range each other (MissionOptions.node_ranges)")
    ap.add_argument("--peer-factors", choices=("on", "off"), default=None,
                    help="SmootherParams.peer_factors: the inter-agent ranges as factors of the "
                    "smoother (default: the smoother's)")
    ap.add_argument("--peer-extrapolate", action="store_true",
                    help="PeerRangeParams.extrapolate: a peer extrapolated with its velocity")
    ap.add_argument("--only-peers", action="store_true",
                    help="with --peer-ranges: the column with the ranges only (candidates)")
    ap.add_argument("--peer-rule", choices=RULES, default=None,
                    help="PeerRangeParams.rule: a robot's peer correction (default: its default)")
    ap.add_argument("--peer-factors-only", action="store_true",
                    help="PeerRangeParams.factors_only: with the smoother's peer factors no "
                    "tracker takes a peer range (the feedback mode's robot ignores them)")
    ap.add_argument("--max-sigma-m", type=float, default=None,
                    help="NodeEstimatorParams.max_sigma_m (default: its default)")
    ap.add_argument("--agent-cov-scale", type=float, default=None,
                    help="NodeEstimatorParams.agent_cov_scale (default: its default)")
    ap.add_argument("--agent-correlation", type=float, default=None,
                    help="NodeEstimatorParams.agent_correlation (default: its default)")
    ap.add_argument("--range-correlation-s", type=float, default=None,
                    help="NodeEstimatorParams.range_correlation_s (default: its default)")
    ap.add_argument("--max-mirror-passes", type=int, default=None,
                    help="NodeEstimatorParams.max_mirror_passes (default: its default)")
    ap.add_argument("--smooth-readings-s", type=float, default=None,
                    help="MissionParams.smooth_readings_s: rescuers' readings at their smoothed "
                         "positions, lag s (default: its default; 0: off)")
    ap.add_argument("--use-variance-ratio", type=float, default=None,
                    help="MissionParams.use_variance_ratio (default: its default; inf: no gate)")
    ap.add_argument("--loop-closure-ratio", type=float, default=None,
                    help="MissionParams.loop_closure_ratio (default: its default; inf: never)")
    ap.add_argument("--no-pass-cap", action="store_true",
                    help="MissionParams.pass_cap = False (the earlier widening rule)")
    ap.add_argument("--q-along", type=float, default=RESCUER.prediction.q_along,
                    help="rescuers' [prediction] q_along (default: the rescue-mission preset)")
    ap.add_argument("--heading-increment-rad", type=float,
                    default=RESCUER.prediction.sigma_heading_increment_rad,
                    help="rescuers' [prediction] sigma_heading_increment_rad "
                         "(default: the rescue-mission preset)")
    ap.add_argument("--tag-sigma-per-accuracy", type=float,
                    default=RESCUER.tags.sigma_per_accuracy,
                    help="rescuers' [tags] sigma_per_accuracy (default: the rescue-mission preset)")
    ap.add_argument("--why", action="store_true",
                    help="also print why the nodes were not localized (benchmarks/_mission_why)")
    ap.add_argument("--reach", action="store_true",
                    help="also print each seed's nodes not localized and where they were lost "
                         "(benchmarks/_mission_reach)")
    ap.add_argument("--nees-split", action="store_true",
                    help="also print the agents' NEES split by node use (benchmarks/_mission_nees)")
    ap.add_argument("--only-on", action="store_true",
                    help="cooperation on only (the off column skipped: half the time)")
    ap.add_argument("--only-off", action="store_true",
                    help="cooperation off only (the on column skipped)")
    ap.add_argument("--mode", choices=MODES, default=None,
                    help="the smoother's named mode (hrtls.mission.smoother_modes; default: "
                    "MissionParams' default)")
    ap.add_argument("--smoother", action="store_true",
                    help="MissionParams.smoother = SmootherParams() with the options below "
                    "(range-SLAM smoother; overrides --mode)")
    ap.add_argument("--feedback", choices=("off", "implied", "replace"), default=None,
                    help="with --smoother: SmootherParams.feedback (the smoother's latest poses "
                         "given back to the rescuers' trackers)")
    ap.add_argument("--robots-take", dest="robots_take", choices=("nodes", "feedback", "alone"),
                    default=None, help="SmootherParams.robots (what a robot takes from the "
                    "mission; with --smoother or --mode)")
    ap.add_argument("--every-s", type=float, default=None,
                    help="with --smoother: SmootherParams.every_s (default: its default)")
    ap.add_argument("--feedback-cov-scale", type=float, default=None,
                    help="with --feedback: SmootherParams.feedback_cov_scale")
    ap.add_argument("--feedback-gate", type=float, default=None,
                    help="with --feedback implied: SmootherParams.feedback_gate (NIS)")
    ap.add_argument("--feedback-ranges", choices=("both", "smoother"), default=None,
                    help="with --feedback: SmootherParams.feedback_ranges (who takes a fed-back "
                    "rescuer's ranges to the smoother's nodes)")
    ap.add_argument("--window-s", type=float, default=None,
                    help="with --smoother: SmootherParams.window_s (poses older than this are "
                    "marginalized; default: none)")
    ap.add_argument("--increment-noise", choices=("length", "tracker"), default=None,
                    help="with --smoother: SmootherParams.increment_noise")
    ap.add_argument("--heading-updates", choices=("factor", "drop", "chain"), default=None,
                    help="with --smoother: SmootherParams.heading_updates")
    ap.add_argument("--odo-fraction", type=float, default=None,
                    help="with --smoother: SmootherParams.odo_fraction")
    ap.add_argument("--min-spread-m", type=float, default=None,
                    help="with --smoother: SmootherParams.min_spread_m")
    ap.add_argument("--localize-spread-m", type=float, default=None,
                    help="with --smoother: SmootherParams.localize_spread_m")
    ap.add_argument("--link-bias-sigma-m", type=float, default=None,
                    help="SmootherParams.link_bias_sigma_m (a node pair's persistent excess "
                    "path, m)")
    ap.add_argument("--link-cov-scale", type=float, default=None,
                    help="SmootherParams.link_cov_scale (calibration of a linked node's "
                    "covariance)")
    ap.add_argument("--link-join-tol-m", type=float, default=None,
                    help="SmootherParams.link_join_tol_m (a node joining through its links: "
                    "its start's median residual per anchor kind; inf: no check)")
    ap.add_argument("--smoother-correlation-s", type=float, default=None,
                    help="with --smoother: SmootherParams.range_correlation_s")
    ap.add_argument("--no-magnetometer", action="store_true",
                    help="rescuers' [attitude] use_magnetometer = false (gyro-only heading)")
    ap.add_argument("--no-hard-iron-fit", action="store_true",
                    help="rescuers' [attitude] mag_hard_iron = off (the field used raw)")
    ap.add_argument("--heading-source", choices=("filter", "gyro+compass"),
                    default="gyro+compass",
                    help="rescuers' [attitude] heading_source (filter: the tracker's default)")
    ap.add_argument("--offset-floor", action="store_true",
                    help="rescuers' [attitude.mag_heading] offset_floor = true")
    ap.add_argument("--offset-model", choices=("independent", "consider"),
                    default=RESCUER.attitude.mag_heading["offset_model"],
                    help="rescuers' [attitude.mag_heading] offset_model (default: the preset's)")
    add_engine_options(ap)
    args = ap.parse_args()
    batch = Batch.of(args)
    opts = MissionOptions(n_rescuers=args.rescuers, n_robots=args.robots, n_nodes=args.nodes,
                          range_sigma_m=args.range_sigma_m,
                          range_sigma_fraction=args.range_sigma_fraction,
                          node_failure_fraction=args.node_failure, walk_s=args.walk_s,
                          robot_driver=args.robot_driver, rescuer_driver=args.rescuer_driver,
                          tag_layout=args.tags, door_spacing_m=args.door_spacing_m,
                          n_floors=args.floors, node_ranges=args.node_ranges)
    cols = modes(args.peer_ranges, args.only_on, args.only_off, args.only_peers)
    rows: dict[str, dict[str, list[float]]] = {
        m: {"mean": [], "p90": [], "max": [], "frac": [], "rmse": [], "anees": [],
            "rmse_true": [], "robot_p90": [], "robot_nees": [], "w0": [], "w1": [], "a0": [],
            "a1": [], "n0": [], "n1": [], "s0": [], "s1": []}
        for m in cols}
    nees_all: dict[str, list[float]] = {m: [] for m in cols}
    why: dict[str, list[dict[str, int]]] = {m: [] for m in cols}
    split: dict[str, list[dict[str, list[float]]]] = {m: [] for m in why}
    floor_rows = {m: {k: [] for k in FLOOR_KEYS} for m in why}
    t0 = time.perf_counter()
    nodes = NodeEstimatorParams()
    for key in ("agent_cov_scale", "agent_correlation", "max_sigma_m", "range_correlation_s",
                "max_mirror_passes"):
        if getattr(args, key) is not None:
            nodes = replace(nodes, **{key: getattr(args, key)})
    prediction = {"q_along": args.q_along,
                  "sigma_heading_increment_rad": args.heading_increment_rad}
    attitude: dict[str, Any] = {"use_magnetometer": False} if args.no_magnetometer else {}
    if args.no_hard_iron_fit:
        attitude["mag_hard_iron"] = "off"
    if not args.no_magnetometer:
        attitude["heading_source"] = args.heading_source
    attitude["mag_heading"] = {"offset_model": args.offset_model,
                               **({"offset_floor": True} if args.offset_floor else {})}
    items = [SeedItem(seed, opts, nodes, args.peer_ranges, prediction, args.peer_extrapolate,
                      args.only_on, smoother_of(args),
                      attitude, args.loop_closure_ratio, not args.no_pass_cap,
                      only_off=args.only_off, use_variance_ratio=args.use_variance_ratio,
                      tags={"sigma_per_accuracy": args.tag_sigma_per_accuracy},
                      smooth_readings_s=args.smooth_readings_s, peer_rule=args.peer_rule,
                      peer_factors_only=args.peer_factors_only, only_peers=args.only_peers)
             for seed in parse_seeds(args.seeds)]
    for item, scores in batch.map(run_seed, items, label=lambda it: f"seed {it.seed}"):
        for mode in cols:
            m = scores[mode]
            r = rows[mode]
            r["mean"].append(m.mean)
            r["p90"].append(m.p90)
            r["max"].append(m.max)
            r["frac"].append(m.frac)
            r["anees"].append(m.anees)
            r["rmse"].append(m.rmse)
            r["rmse_true"].append(m.rmse_true_agents)
            r["robot_p90"].append(m.robot_p90)
            r["robot_nees"].append(m.robot_nees)
            r["w0"].append(m.window_ms[0])
            r["w1"].append(m.window_ms[1])
            r["a0"].append(m.agent_ms[0])
            r["a1"].append(m.agent_ms[1])
            r["n0"].append(m.nodes_ms[0])
            r["n1"].append(m.nodes_ms[1])
            r["s0"].append(m.solve_s[0])
            r["s1"].append(m.solve_s[1])
            nees_all[mode].extend(m.node_nees)
            why[mode].append(m.why)
            if args.reach:
                print("\n".join(reach_lines(item.seed, args.nodes, m.reach)), flush=True)
            split[mode].append(m.nees_split)
            for k, v in m.floors.items():
                floor_rows[mode][k].append(v)
            print(f"seed {item.seed} {mode:>8}: err mean {m.mean:.2f} p90 {m.p90:.2f} max "
                  f"{m.max:.2f} m; nodes {m.frac:.2f} rmse {m.rmse:.2f} m; agent NEES "
                  f"{m.anees:.1f}; robot p90 {m.robot_p90:.2f} m, NEES "
                  f"{m.robot_nees:.2f}; node NEES "
                  f"{np.mean(m.node_nees) if m.node_nees else float('nan'):.2f}", flush=True)
    ratio = (MissionParams().use_variance_ratio if args.use_variance_ratio is None
             else args.use_variance_ratio)
    lag = (MissionParams().smooth_readings_s if args.smooth_readings_s is None
           else args.smooth_readings_s)
    print(f"\nseeds {args.seeds}, {args.rescuers} rescuers ({args.rescuer_driver} driver), "
          f"{args.robots} robots "
          f"({args.robot_driver} driver), tags {args.tags}"
          f"{f' (doors {args.door_spacing_m:g} m apart)' if args.tags == 'doors' else ''}, "
          f"{args.nodes} nodes{' ranging each other' if args.node_ranges else ''}, "
          f"{args.floors} floor(s), range sigma "
          f"{args.range_sigma_m} m + {100 * args.range_sigma_fraction:g} % of the distance, "
          f"node failure {args.node_failure}, agent covariance scale "
          f"{nodes.agent_cov_scale}, agent correlation {nodes.agent_correlation}, use variance "
          f"ratio {ratio:g}, smoothed readings lag {lag:g} s, rescuers' "
          f"q_along {args.q_along}, heading increment {args.heading_increment_rad} rad, "
          f"magnetic offset {args.offset_model}, tag sigma per accuracy "
          f"{args.tag_sigma_per_accuracy}, smoother {smoother_mode(items[0].smoother)}; values "
          "are mean / p90 / "
          f"worst over seeds ({time.perf_counter() - t0:.0f} s)\n")
    head = "peer ranges" if args.peer_ranges else "cooperation"
    print(f"| {head} | rescuer error mean, m | rescuer error p90, m | rescuer error max, m "
          "| agent NEES | nodes localized (mean / p10 / lowest) | node RMSE, m "
          "| node NEES (mean; 95 % bounds) | node RMSE from true agent positions, m "
          "| robot error p90, m | robot NEES |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for mode in cols:
        r = rows[mode]
        n = len(nees_all[mode])
        lo, hi = (chi2.ppf(0.025, 2 * n) / n, chi2.ppf(0.975, 2 * n) / n) if n else (0, 0)
        nees = f"{np.mean(nees_all[mode]):.2f} ({lo:.2f}-{hi:.2f}, n={n})" if n else "-"
        print(f"| {mode} | {_stats(r['mean'])} | {_stats(r['p90'])} | {_stats(r['max'])} "
              f"| {_stats(r['anees'])} | {_stats(r['frac'], higher_is_better=True)} "
              f"| {_stats(r['rmse'])} | {nees} "
              f"| {_stats(r['rmse_true'])} | {_stats(r['robot_p90'])} "
              f"| {_stats(r['robot_nees'])} |")
    print("\nms per window (all agents), mean over seeds, first / last quarter of the mission:\n")
    print("| cooperation | window | agents (trackers + collection) | node re-estimation "
          "| smoother solve, s (mean / largest) |")
    print("|---|---|---|---|---|")
    for mode in cols:
        r = rows[mode]
        print(f"| {mode} | {np.mean(r['w0']):.1f} / {np.mean(r['w1']):.1f} "
              f"| {np.mean(r['a0']):.1f} / {np.mean(r['a1']):.1f} "
              f"| {np.mean(r['n0']):.1f} / {np.mean(r['n1']):.1f} "
              f"| {np.mean(r['s0']):.1f} / {np.max(r['s1']):.1f} |")
    if args.floors > 1:
        print("\nfloors (benchmarks/_mission_floors.py), mean / p90 / worst over seeds (shares: "
              "mean / p10 / lowest):\n")
        print(floor_table(floor_rows))
    if args.nees_split:
        for mode, per_seed in split.items():
            print(f"\nagents' NEES by node use, cooperation {mode}, pooled over seeds "
                  "(benchmarks/_mission_nees.py):\n")
            print(nees_split_table(per_seed))
    if args.why:
        print(f"\nnodes by class at the end, summed over seeds ({args.rescuer_driver} driver; "
              "benchmarks/_mission_why.py):\n")
        print(why_table({f"cooperation {m}": why[m] for m in why}))
    batch.finish()


if __name__ == "__main__":
    main()
