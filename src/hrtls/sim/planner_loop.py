"""Closed loop of a planner-driven robot: mission tracker <-> planner <-> simulator (issue 18).

Every ``control_period_s``: the :class:`~hrtls.mission.tracker.MissionTracker` processes every
complete window of ``chunk_s`` up to now; the robot's estimated position is its tracker's last row
moved on by the robot's own odometry since that row (``p = p_row + R(psi) (o_now - o_row)``,
the odometry-frame rotation ``psi`` of :mod:`hrtls.mission.robot`); every ``plan_period_s``, or
when the estimate reaches the way point, :func:`hrtls.mission.waypoints.next_waypoint` picks the
next way point from :func:`~hrtls.mission.waypoints.planner_input` (tracker state only); the
:class:`~hrtls.sim.robot_driver.DrivenRobot` drives toward it, steering on the estimate, and its
odometry and ranges of the period are fed to the tracker. The rescuers' sessions are fed whole
(the tracker is causal: their later data is not used before its window).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session
from hrtls.data.observations import GroundTruth, PositionFixes, RangeMeasurements
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionTracker
from hrtls.mission.waypoints import Choice, WaypointParams, next_waypoint, planner_input
from hrtls.sim.robot_driver import DrivenRobot

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class LoopParams:
    """Closed-loop settings: planning period, s, and the planner's parameters."""

    plan_period_s: float = 15.0
    control_period_s: float = 1.0
    """The robot's position estimate is checked against its way point this often."""
    waypoints: WaypointParams = field(
        default_factory=lambda: WaypointParams(cross_m=3.0, side_m=1.0))
    """The robot's planner: a node heard from one straight pass gets a way point 3 m off the
    pass's line, else 1 m beside it (the corridor's other side)."""
    mission: MissionParams = field(default_factory=MissionParams)


@dataclass(frozen=True, eq=False)
class LoopResult:
    """The robot's whole session (parts joined) and the way points it was given, in order."""

    session: Session
    choices: list[tuple[float, Choice]]


def _estimate(tracker: MissionTracker, name: str, robot: DrivenRobot,
              odometry: list[PositionFixes]) -> FloatArray:
    """The robot's estimated position now (module doc); its start pose before its first row."""
    rows = tracker.trackers[name].estimates_since() if name in tracker.started else None
    if rows is None or len(rows.t) == 0:
        sp = robot.meta.start_pose
        assert sp is not None
        o = odometry[-1].xyz[-1, :2] - odometry[0].xyz[0, :2] if odometry else np.zeros(2)
        return np.array([sp.x, sp.y]) + o
    t_row = float(rows.t[-1])
    t = np.concatenate([f.t for f in odometry])
    o = np.vstack([f.xyz[:, :2] for f in odometry])
    o_row = np.array([np.interp(t_row, t, o[:, 0]), np.interp(t_row, t, o[:, 1])])
    psi = float(rows.heading_rad[-1])
    c, s = math.cos(psi), math.sin(psi)
    d = o[-1] - o_row
    return np.asarray(rows.xyz[-1, :2] + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]))


def drive_robot(name: str, robot: DrivenRobot, rescuers: dict[str, Session], *,
                end_s: float, params: LoopParams | None = None,
                cooperate: bool = True) -> LoopResult:
    """Run the closed loop until ``end_s``; the robot ``name``'s session (module doc)."""
    prm = params or LoopParams()
    mp = dataclasses.replace(prm.mission, cooperate=cooperate)
    agents: dict[str, Session | AgentHeader] = {**rescuers, name: AgentHeader(robot.meta)}
    tracker = MissionTracker(agents, params=mp,
                             kinds={**dict.fromkeys(rescuers, "rescuer"), name: "robot"})
    parts: list[Session] = []
    odometry: list[PositionFixes] = []
    choices: list[tuple[float, Choice]] = []
    visits: dict[str, int] = {}
    target: FloatArray | None = None
    planned_s = -math.inf
    while robot.t_s < end_s - 1e-9:
        est = _estimate(tracker, name, robot, odometry)
        reached = target is not None and np.hypot(*(est - target)) < robot.params.arrive_m
        if target is None or reached or robot.t_s - planned_s >= prm.plan_period_s:
            c = next_waypoint(planner_input(tracker, agent_m=est),
                              candidates_m=robot.router.points_m, visits=visits,
                              params=prm.waypoints)
            if c.node:
                visits[c.node] = visits.get(c.node, 0) + 1
            target, planned_s = c.position_m, robot.t_s
            choices.append((robot.t_s, c))
        until = min(end_s, robot.t_s + prm.control_period_s)
        part = robot.drive(estimate_m=est, target_m=target, until_s=until)
        parts.append(part)
        assert part.fixes is not None
        odometry.append(part.fixes)
        tracker.feed(name, part)
        tracker.advance(robot.t_s)
    return LoopResult(_join(parts, robot), choices)


def _join(parts: list[Session], robot: DrivenRobot) -> Session:
    """The parts as one session."""
    fixes = [p.fixes for p in parts if p.fixes is not None]
    truth = [p.truth for p in parts if p.truth is not None]
    ranges = [p.ranges for p in parts if p.ranges is not None]
    rg = None
    if ranges:
        rg = RangeMeasurements(np.concatenate([r.t for r in ranges]),
                               np.concatenate([r.node for r in ranges]),
                               np.concatenate([r.range_m for r in ranges]),
                               np.concatenate([r.sigma_m for r in ranges]))
    return Session(meta=robot.meta,
                   fixes=PositionFixes(np.concatenate([f.t for f in fixes]),
                                       np.vstack([f.xyz for f in fixes]),
                                       np.concatenate([f.sigma_m for f in fixes])),
                   ranges=rg,
                   truth=GroundTruth(np.concatenate([g.t for g in truth]),
                                     np.vstack([g.xyz for g in truth]),
                                     np.concatenate([np.asarray(g.heading_rad) for g in truth])))
