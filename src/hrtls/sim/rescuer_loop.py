"""Closed loop of planner-driven rescuers: mission tracker <-> planner <-> walking persons.

The rescuer counterpart of :mod:`hrtls.sim.planner_loop` (issue 18 item 3). Each rescuer is a
:class:`~hrtls.sim.person_legs.WalkingPerson`; every rescuer first stands at its start until its
entry time, then walks leg after leg. Events are handled in time order: the rescuer whose data
ends first (the end of its last leg: it stopped at its way point, or on its route after
``leg_walk_s`` of walking, :class:`TeamParams`) is next; the
:class:`~hrtls.mission.tracker.MissionTracker` processes every complete window up to that time
(every agent has data until then); the rescuer's position for the planner is its tracker's
latest row (at most ``chunk_s`` old; its start pose before the first row);
:func:`hrtls.mission.waypoints.next_waypoint` picks the way point from
:func:`~hrtls.mission.waypoints.planner_input` (tracker state only, never the truth); the person
walks there from its true position (it sees the building) and the leg's part is fed to the
tracker. A node is targeted at most ``max_visits_per_node`` times by the whole team. A rescuer
that reached its way point says so (it sees the building, as it sees the route): the candidates
within ``explore_gap_m`` of a reached way point are no longer offered to the team (without this
the planner, seeing the estimated track away from the point, sends the rescuer to where it
already stands, again and again); when none is left, every candidate but those near the
rescuer's last reached way point is offered (a new round).
Team-aware targets (:class:`TeamParams` ``assign``): the nodes the teammates walk to now are not
offered, and the other nodes worth a visit are assigned to the asking rescuer and its teammates
at once, each teammate at its current way point (where it asks next):
:func:`hrtls.mission.waypoints.next_waypoint` with ``team_m``. A node heard from one straight
pass gets a way point off the pass's line (``cross_m``), a localized node one of the offered
candidates near its estimate (``refine_reach_m``).
Team spreading (:class:`TeamParams`): while a teammate walks to its way point, the candidates
within ``team_gap_m`` of that way point or of its remaining route (the corridor route from the
teammate's estimated position, map knowledge) are not offered to the rescuer that asks, so two
rescuers asking at once get way points at least ``team_gap_m`` apart (greedy, in asking order);
if that leaves no candidate, the open candidates are offered. Legs are cut after
``leg_walk_s`` of walking (``None``: the loop's ``plan_period_s``).
Other agents (robots on fixed routes) are fed whole (the tracker is causal).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session
from hrtls.errors import InputError
from hrtls.mission.tracker import AgentHeader, MissionTracker
from hrtls.mission.waypoints import Choice, next_waypoint, planner_input
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.person_legs import WalkingPerson
from hrtls.sim.planner_loop import LoopParams

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class TeamParams:
    """Team-aware targets, spreading of the way points and leg length (module doc); m, s.

    ``team_gap_m = 0`` offers every open candidate (spreading off, the default: README,
    planner-driven rescuers).
    """

    team_gap_m: float = 0.0
    leg_walk_s: float | None = 40.0
    assign: bool = True
    """Team-aware targets (module doc): the teammates' nodes not offered, the rest assigned."""
    cross_m: float = 3.0
    """``WaypointParams.cross_m`` of the rescuers: a node heard from one straight pass gets a
    way point off the pass's line."""
    heard_again_m: float = 10.0
    """``WaypointParams.heard_again_m`` of the rescuers: a heard node goes preferably to a
    rescuer that has not heard it (with ``assign``)."""
    refine_reach_m: float | None = 3.0
    """``WaypointParams.refine_reach_m`` of the rescuers: a localized node's way point is an
    offered candidate (not near a way point reached), so no rescuer stands at a node twice."""

    def __post_init__(self) -> None:
        if not (self.team_gap_m >= 0 and (self.leg_walk_s is None or self.leg_walk_s > 0)
                and self.cross_m >= 0 and self.heard_again_m >= 0
                and (self.refine_reach_m is None or self.refine_reach_m >= 0)):
            raise InputError("invalid team parameters", where="TeamParams",
                             expected="team_gap_m >= 0, leg_walk_s > 0 or None, cross_m >= 0")


@dataclass(frozen=True, eq=False)
class RescuerLoopResult:
    """The tracker after the last leg and each rescuer's way points, in order."""

    tracker: MissionTracker
    choices: dict[str, list[tuple[float, Choice]]]


def rescuer_estimate(tracker: MissionTracker, person: WalkingPerson) -> FloatArray:
    """The rescuer's position for the planner: its tracker's latest row, else its start pose."""
    name = person.name
    rows = tracker.trackers[name].estimates_since() if name in tracker.started else None
    if rows is None or len(rows.t) == 0:
        sp = person.meta.start_pose
        assert sp is not None
        return np.array([sp.x, sp.y])
    return np.asarray(rows.xyz[-1, :2], dtype=np.float64)


def polyline_distance(points_m: FloatArray, line_m: FloatArray) -> FloatArray:
    """Distance of each point ``(n, 2)`` to the polyline ``(k, 2)`` (one vertex: to it), m."""
    a, b = line_m[:-1], line_m[1:]
    if len(line_m) < 2:
        return np.asarray(np.hypot(*(points_m - line_m[0]).T), dtype=np.float64)
    ab = b - a
    den = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    # projection parameter u = clip((p - a).(b - a) / |b - a|^2, 0, 1) per point and segment
    u = np.clip(np.einsum("nij,ij->ni", points_m[:, None, :] - a[None], ab) / den, 0.0, 1.0)
    foot = a[None] + u[..., None] * ab[None]
    return np.asarray(np.min(np.linalg.norm(points_m[:, None, :] - foot, axis=2), axis=1),
                      dtype=np.float64)


def team_free(points_m: FloatArray, routes_m: list[FloatArray], *, gap_m: float) -> FloatArray:
    """Candidates at least ``gap_m`` from every teammate's remaining route (bool mask)."""
    free = np.ones(len(points_m), dtype=bool)
    for line in routes_m:
        free &= polyline_distance(points_m, line) >= gap_m
    return free


def drive_rescuers(persons: Mapping[str, WalkingPerson], others: Mapping[str, Session], *,
                   kinds: Mapping[str, str], enter_s: Mapping[str, float],
                   end_s: Mapping[str, float], params: LoopParams | None = None,
                   config: TrackerConfig | None = None,
                   cooperate: bool = True, team: TeamParams | None = None) -> RescuerLoopResult:
    """Run the loop (module doc): rescuer ``k`` stands until ``enter_s[k]``, walks to ``end_s[k]``.

    ``others``: whole sessions of the other agents (their ``kinds``).
    """
    prm = params or LoopParams()
    tp = team or TeamParams()
    leg_s = prm.plan_period_s if tp.leg_walk_s is None else tp.leg_walk_s
    mp = dataclasses.replace(prm.mission, cooperate=cooperate)
    headers: dict[str, Session | AgentHeader] = {
        k: AgentHeader(p.meta, dict(p.landmarks)) for k, p in persons.items()}
    tracker = MissionTracker({**headers, **others}, params=mp, config=config,
                             kinds={**dict.fromkeys(persons, "rescuer"), **kinds})
    for k, p in persons.items():
        tracker.feed(k, p.stand_until(start_s=0.0, until_s=enter_s[k]))
    for k in others:  # whole sessions: they hold no window back after their end
        tracker.end(k)
    choices: dict[str, list[tuple[float, Choice]]] = {k: [] for k in persons}
    visits: dict[str, int] = {}
    points = next(iter(persons.values())).router.points_m
    open_ = np.ones(len(points), dtype=bool)
    targets: dict[str, Choice] = {}  # each rescuer's way point until it asks again
    reached: dict[str, FloatArray] = {}  # each rescuer's last way point reached
    wp = dataclasses.replace(prm.waypoints, cross_m=tp.cross_m, heard_again_m=tp.heard_again_m,
                             refine_reach_m=tp.refine_reach_m, side_m=0.0)  # the robot's only
    while True:
        busy = [k for k, p in persons.items() if p.t_s < end_s[k] - p.dt_s]
        for k in sorted(set(persons) - set(busy)):
            tracker.end(k)
            targets.pop(k, None)
        if not busy:
            break
        name = min(busy, key=lambda k: (persons[k].t_s, k))
        person = persons[name]
        tracker.advance(person.t_s)
        targets.pop(name, None)
        routes = [person.router.route(rescuer_estimate(tracker, persons[k]), w.position_m)
                  for k, w in sorted(targets.items())] if tp.team_gap_m > 0 else []
        offer = open_ & team_free(points, routes, gap_m=tp.team_gap_m) if routes else open_
        offer = offer if offer.any() else open_
        if not offer.any() and name in reached:  # a new round (module doc)
            offer = np.hypot(*(points - reached[name]).T) > prm.waypoints.explore_gap_m
        mates = sorted(targets) if tp.assign else []
        c = next_waypoint(planner_input(tracker, agent_m=rescuer_estimate(tracker, person)),
                          candidates_m=points[offer] if offer.any() else points,
                          visits=visits, params=wp,
                          team_m=np.array([targets[k].position_m for k in mates]).reshape(-1, 2),
                          taken=frozenset(targets[k].node for k in mates if targets[k].node),
                          names=[name, *mates])
        targets[name] = c
        if c.node:
            visits[c.node] = visits.get(c.node, 0) + 1
        choices[name].append((person.t_s, c))
        tracker.feed(name, person.walk_to(c.position_m, max_walk_s=leg_s,
                                          until_s=end_s[name]))
        if person.arrived:
            reached[name] = c.position_m
            open_ &= np.hypot(*(points - c.position_m).T) > prm.waypoints.explore_gap_m
    return RescuerLoopResult(tracker, choices)
