"""Where each node not localized at the end of a simulated mission was lost (scoring only).

The ceiling of issue 18's "90 % of the nodes localized": every node the mission tracker did not
localize falls in one class, checked in this order (truth used for the diagnosis only):

* ``never in range``: no agent's true track on the node's floor came within the radio's
  ``max_range_m`` of it (the agents' routes never reached it);
* ``silent``: some agent passed within range, but no agent's session holds a range to it (a
  failed node, or dropouts and NLOS all the way);
* ``not kept``: ranges in the sessions, none kept as a reading by the tracker;
* ``one corridor``: the readings' true positions lie in one corridor only (fewer than
  ``min_readings`` in any other): one bearing, the mirror across the pass's line is as likely;
* ``rejected``: readings from at least two corridors, and the estimator still did not localize
  it (its reason class from ``_mission_why``; ``from true positions``: the same readings at the
  agents' true positions localize it, so the agents' error lost it).

A reading's corridor is the corridor box holding its true position alone (a point where two
corridors cross counts for neither).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from _mission_why import reason_class, true_readings
from hrtls.mission.nodes import NodeEstimator
from hrtls.mission.tracker import MissionResult, MissionTracker
from hrtls.sim.mission import CORRIDORS, Mission
from hrtls.sim.mission_floors import FLOOR_HEIGHT_M

FloatArray = NDArray[np.float64]
REACH_CLASSES = ("never in range", "silent", "not kept", "one corridor", "rejected")


@dataclass(frozen=True)
class NodeReach:
    """One node not localized: its class and the facts behind it (module doc)."""

    node: str
    kind: str
    closest_m: float
    """Closest approach of any agent's true track on the node's floor, m."""
    robot_closest_m: float
    """Closest approach of a robot's true track, m (inf without robots)."""
    n_ranges: int
    """Ranges to it in every agent's session."""
    n_readings: int
    """Readings the tracker kept."""
    agents: int
    corridors: int
    reason: str
    """The estimator's reason class (``_mission_why.reason_class``), '' before ``rejected``."""
    from_truth: bool


def corridors_seen(xy_m: FloatArray, corridors: tuple[BaseGeometry, ...], *,
                   min_readings: int = 3) -> int:
    """Corridors holding at least ``min_readings`` of the points ``(k, 2)``, each point counted
    only in a corridor it lies in alone (module doc)."""
    if len(xy_m) == 0:
        return 0
    inside = np.array([shapely.contains_xy(c, xy_m[:, 0], xy_m[:, 1]) for c in corridors])
    alone = inside & (inside.sum(axis=0) == 1)[None]
    return int(np.sum(alone.sum(axis=1) >= min_readings))


def reach_class(*, closest_m: float, max_range_m: float, n_ranges: int, n_readings: int,
                corridors: int) -> str:
    """The class of a node not localized (module doc, in its order)."""
    if closest_m > max_range_m:
        return "never in range"
    if n_ranges == 0:
        return "silent"
    if n_readings == 0:
        return "not kept"
    if corridors <= 1:
        return "one corridor"
    return "rejected"


def _closest(mission: Mission, xy: FloatArray, floor: int, kind: str | None) -> float:
    best = np.inf
    for name, sim in mission.simulations.items():
        truth = sim.session.truth
        if truth is None or (kind is not None and mission.kinds.get(name) != kind):
            continue
        on = np.floor(truth.xyz[:, 2] / FLOOR_HEIGHT_M + 0.5).astype(int) == floor
        if on.any():
            best = min(best, float(np.min(np.hypot(*(truth.xyz[on, :2] - xy).T))))
    return best


def node_reach(mission: Mission, tracker: MissionTracker, result: MissionResult, *,
               min_readings: int = 3) -> list[NodeReach]:
    """Every node not localized, with its class (module doc)."""
    est = NodeEstimator(tracker.params.nodes)
    out = []
    for node, truth in sorted(mission.node_truth_m.items()):
        e = result.nodes.get(node)
        if e is not None and e.localized:
            continue
        floor = mission.node_floor.get(node, 0)
        n_ranges = sum(int(np.sum(s.ranges.node == node)) for s in mission.agents.values()
                       if s.ranges is not None)
        rd = tracker.readings.get(node)
        kept = rd is not None and bool(rd.r)
        true_xy = true_readings(mission, tracker, node).agent_xy_m if kept else np.zeros((0, 2))
        seen = corridors_seen(true_xy, CORRIDORS, min_readings=min_readings)
        closest = _closest(mission, truth, floor, None)
        kind = reach_class(closest_m=closest, max_range_m=mission.options.max_range_m,
                           n_ranges=n_ranges, n_readings=len(true_xy), corridors=seen)
        reason = reason_class(e.reason) if kept and e is not None else ""
        from_truth = kept and est.estimate(true_readings(mission, tracker, node)).localized
        out.append(NodeReach(node, kind, closest, _closest(mission, truth, floor, "robot"),
                             n_ranges, len(true_xy),
                             len(set(rd.agent)) if rd is not None and kept else 0, seen,
                             reason, bool(from_truth)))
    return out


def reach_lines(seed: int, n_nodes: int, rows: list[NodeReach]) -> list[str]:
    """One line per node not localized, after a line with the seed's counts per class."""
    counts = ", ".join(f"{k} {sum(r.kind == k for r in rows)}" for k in REACH_CLASSES)
    lines = [f"seed {seed}: {n_nodes - len(rows)} of {n_nodes} localized; not: {counts}"]
    for r in rows:
        lines.append(f"  {r.node}: {r.kind}; closest agent {r.closest_m:.1f} m, robot "
                     f"{r.robot_closest_m:.1f} m; {r.n_ranges} ranges, {r.n_readings} readings "
                     f"from {r.agents} agents in {r.corridors} corridors"
                     + (f"; estimator: {r.reason}, from true positions "
                        f"{'localized' if r.from_truth else 'not localized'}"
                        if r.kind == "rejected" or r.kind == "one corridor" else ""))
    return lines
