"""Way points for a mission agent from the mission tracker's current state (issue 18).

:func:`planner_input` reads only a :class:`~hrtls.mission.tracker.MissionTracker` (its node
estimates, the node readings it keeps, every agent's estimated track) and the agent's estimated
position: the planner never sees the simulator's truth. :func:`next_waypoint` then picks, among
``candidates_m`` (reachable points of the floor plan, map knowledge), in this order:

1. for a node heard but not localized (the thesis' candidate visit, Sec. 5.3, Fig. 5.3): the
   node lies in every disc ``|q - a_i| <= r_i + 3 s_i`` of its readings (an NLOS range is only
   longer); the agent goes to the feasible point nearest to it that is at least ``new_view_m``
   from every reading position, so the next ranges come from a new direction (or rule the point
   out); the nearest such node first, none farther than ``heard_reach_m`` from the agent
   (heard from one straight pass: a point off the pass's line, :func:`heard_point`);
2. for a localized node whose largest position sigma exceeds ``target_sigma_m``: its estimate
   (ranges from close and from a new side), or with ``refine_reach_m`` the candidate nearest to
   it, none farther (the caller may leave out the candidates near way points already reached);
3. otherwise, or first while a gap wider than ``explore_gap_m`` is left, exploration: the
   candidate farthest from every agent's estimated track (where unheard nodes may be), less
   ``explore_distance_weight`` times its distance from the agent.

A node is targeted at most ``max_visits_per_node`` times (the caller keeps ``visits``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from hrtls.errors import InputError
from hrtls.mission.tracker import MissionTracker

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class WaypointParams:
    """Parameters of :func:`next_waypoint` (lengths m)."""

    target_sigma_m: float = 0.25
    new_view_m: float = 3.0
    max_visits_per_node: int = 3
    explore_distance_weight: float = 0.2
    heard_reach_m: float = float("inf")
    explore_gap_m: float = 6.0
    """Explore first while some candidate is farther than this from every agent's track."""
    max_readings: int = 60
    """Readings of a node used for its feasible set (the latest ones)."""
    straight_m: float = 1.0
    """Readings closer than this (RMS) to their best-fit line come from one straight pass."""
    cross_m: float = 0.0
    """The way point of a node heard from one straight pass is this far from the pass's line
    (0: off)."""
    side_m: float = 0.0
    """A node heard from one straight pass with no point ``cross_m`` off its line: the way point
    is at least this far off the line, beside its reading of the shortest range, however near
    the readings (a second line against the mirror ambiguity; 0: off)."""
    heard_again_m: float = 0.0
    """Extra cost of a heard node to an agent that heard it already (:func:`next_waypoint`)."""
    refine_reach_m: float | None = None
    """A localized node's way point is the candidate nearest its estimate, if within this
    (``None``: the estimate itself, whatever the candidates)."""

    def __post_init__(self) -> None:
        if not (self.target_sigma_m > 0 and self.new_view_m >= 0 and self.max_visits_per_node >= 1
                and self.max_readings >= 1 and self.straight_m >= 0 and self.cross_m >= 0
                and self.heard_again_m >= 0 and self.side_m >= 0):
            raise InputError("invalid way-point parameters", where="WaypointParams",
                             expected="sigma > 0, distance >= 0, visits and readings >= 1")


@dataclass(frozen=True, eq=False)
class PlannerInput:
    """What the planner knows: estimates only (module doc).

    ``localized``: node -> (position, covariance); ``heard``: unlocalized node -> (reading
    positions ``(k, 2)``, ranges, range sigmas including the reading agent's position sigma);
    ``tracks_m``: every agent's estimated positions so far (every 10th row) ``(m, 2)``;
    ``heard_by``: unlocalized node -> names of the agents whose readings it has.
    """

    agent_m: FloatArray
    localized: dict[str, tuple[FloatArray, FloatArray]]
    heard: dict[str, tuple[FloatArray, FloatArray, FloatArray]]
    tracks_m: FloatArray
    heard_by: dict[str, frozenset[str]] = field(default_factory=dict)


@dataclass(frozen=True)
class Choice:
    """A way point and why: ``kind`` is ``heard``, ``refine`` or ``explore``; ``node`` or ''."""

    position_m: FloatArray
    kind: str
    node: str


def planner_input(tracker: MissionTracker, *, agent_m: FloatArray) -> PlannerInput:
    """The planner's input from the tracker's state and the agent's estimated position."""
    localized = {k: (e.position_m, e.covariance_m2) for k, e in tracker.estimates.items()
                 if e.localized}
    heard: dict[str, tuple[FloatArray, FloatArray, FloatArray]] = {}
    heard_by: dict[str, frozenset[str]] = {}
    for k, rd in tracker.readings.items():
        if k in localized or not rd.r:
            continue
        xy, cov = np.asarray(rd.xy), np.asarray(rd.cov)
        s = np.sqrt(np.asarray(rd.s) ** 2 + np.trace(cov, axis1=1, axis2=2))
        heard[k] = (xy, np.asarray(rd.r), s)
        heard_by[k] = frozenset(tracker.names[i] for i in set(rd.agent))
    rows = [tr.estimates_since().xyz[::10, :2] for name, tr in tracker.trackers.items()
            if name in tracker.started]
    tracks = np.vstack(rows) if rows else np.zeros((0, 2))
    return PlannerInput(np.asarray(agent_m, dtype=np.float64), localized, heard, tracks,
                        heard_by)


def _fit_line(a: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """Best-fit line of ``a`` ``(k, 2)``: centre, unit direction, unit normal, RMS distance."""
    c = a.mean(axis=0)
    w, v = np.linalg.eigh(np.cov((a - c).T, bias=True).reshape(2, 2))
    return c, v[:, 1], v[:, 0], float(np.sqrt(max(w[0], 0.0)))


def _line_distance(points_m: FloatArray, a: FloatArray) -> tuple[float, FloatArray]:
    """RMS distance of ``a`` ``(k, 2)`` from its best-fit line, and each point's distance to it."""
    c, _, n, spread = _fit_line(a)
    return spread, np.abs((points_m - c) @ n)


def heard_point(inp: PlannerInput, node: str, candidates_m: FloatArray,
                prm: WaypointParams) -> FloatArray | None:
    """A heard node's way point (module doc, item 1), ``None`` when no candidate is feasible.

    Readings from one straight pass (RMS distance from their line below ``straight_m``): the
    feasible points at least ``cross_m`` from that line first, so that the leg leaves the
    pass's line at a clear angle (a second bearing against the mirror ambiguity); with none
    and ``side_m`` set, the point ``side_m`` off the line beside the reading of the shortest
    range, on the side of the nearer candidate (a parallel line, e.g. the corridor's other side;
    not a candidate itself: the driver pulls it into the free space).
    """
    a, r, s = (x[-prm.max_readings:] for x in inp.heard[node])
    d = np.linalg.norm(candidates_m[:, None, :] - a[None], axis=2)
    feasible = np.all(d <= r + 3.0 * s, axis=1) & np.all(d >= prm.new_view_m, axis=1)
    if len(a) >= 2:
        spread, off = _line_distance(candidates_m, a)
        crossing = feasible & (off >= prm.cross_m)
        if spread < prm.straight_m and prm.side_m > 0 and not (prm.cross_m > 0
                                                                and crossing.any()):
            return _side_point(a, r, candidates_m, prm.side_m)
        if spread < prm.straight_m and crossing.any():
            feasible = crossing
    if not feasible.any():
        return None
    pts = candidates_m[feasible]
    return np.asarray(pts[int(np.argmin(np.hypot(*(pts - inp.agent_m).T)))], dtype=np.float64)


def _side_point(a: FloatArray, r: FloatArray, candidates_m: FloatArray,
                side_m: float) -> FloatArray:
    """The point ``side_m`` off the best-fit line of ``a`` beside its shortest range.

    On the side whose point is nearer a candidate (:func:`heard_point`).
    """
    c, u, n, _ = _fit_line(a)
    foot = c + float((a[int(np.argmin(r))] - c) @ u) * u
    pts = foot[None] + side_m * np.array([n, -n])
    gap = np.min(np.linalg.norm(pts[:, None, :] - candidates_m[None], axis=2), axis=1)
    return np.asarray(pts[int(np.argmin(gap))], dtype=np.float64)


def node_targets(inp: PlannerInput, candidates_m: FloatArray, visits: dict[str, int],
                 prm: WaypointParams, *, taken: frozenset[str] = frozenset()) -> list[Choice]:
    """Every node worth a visit (module doc, items 1 and 2), ``taken`` ones left out."""
    out: list[Choice] = []
    for node in sorted(inp.heard):
        if visits.get(node, 0) >= prm.max_visits_per_node or node in taken:
            continue
        p = heard_point(inp, node, candidates_m, prm)
        if p is not None and np.hypot(*(p - inp.agent_m)) <= prm.heard_reach_m:
            out.append(Choice(p, "heard", node))
    for node, (p, c) in sorted(inp.localized.items()):
        if (np.sqrt(max(np.linalg.eigvalsh(c)[-1], 0.0)) > prm.target_sigma_m
                and visits.get(node, 0) < prm.max_visits_per_node and node not in taken):
            q = _refine_point(np.asarray(p, dtype=np.float64), candidates_m, prm)
            if q is not None:
                out.append(Choice(q, "refine", node))
    return out


def _refine_point(p: FloatArray, candidates_m: FloatArray, prm: WaypointParams
                  ) -> FloatArray | None:
    """A localized node's way point (module doc, item 2), ``None`` when there is none."""
    if prm.refine_reach_m is None:
        return p
    d = np.hypot(*(candidates_m - p).T)
    i = int(np.argmin(d))
    return candidates_m[i].copy() if d[i] <= prm.refine_reach_m else None


def assign(cost: FloatArray) -> NDArray[np.int64]:
    """Column of each row in a minimum total cost assignment, ``-1`` for none.

    Every row gets at most one column and no column is given twice; an infinite cost forbids
    the pair. As many rows as possible are assigned, then the total cost is least.
    """
    n_rows, n_cols = cost.shape
    out = np.full(n_rows, -1, dtype=np.int64)
    if n_rows == 0 or n_cols == 0:
        return out
    ok = np.isfinite(cost)
    big = 1.0 + 2.0 * n_rows * float(np.max(np.abs(cost[ok]), initial=0.0))
    rows, cols = linear_sum_assignment(np.where(ok, cost, big * (n_rows + 1)))
    keep = ok[rows, cols]
    out[rows[keep]] = cols[keep]
    return out


def next_waypoint(inp: PlannerInput, *, candidates_m: FloatArray, visits: dict[str, int],
                  params: WaypointParams | None = None, team_m: FloatArray | None = None,
                  taken: frozenset[str] = frozenset(),
                  names: Sequence[str] = ()) -> Choice:
    """The agent's next way point (module doc); ``visits`` counts the nodes already targeted.

    Team-aware (``team_m``, the teammates' next asking positions ``(k, 2)``, e.g. their current
    way points; ``taken``, the nodes they walk to now, not offered): the nodes worth a visit are
    assigned to the agent and its teammates at once (:func:`assign`, heard nodes before refine
    ones, then the least total straight-line distance), and the agent gets its own;
    the agent explores when it gets none. ``names``: the agent's and its teammates' names (rows
    in that order); a heard node costs ``heard_again_m`` more to an agent whose readings it has
    already (a new agent's readings carry an error independent of the first one's).
    """
    prm = params or WaypointParams()
    if len(candidates_m) == 0:
        raise InputError("no candidate way points", where="next_waypoint",
                         expected="reachable points of the floor plan")
    explore = _explore_choice(inp, candidates_m, prm)
    if explore[1] > prm.explore_gap_m:
        return explore[0]
    targets = node_targets(inp, candidates_m, visits, prm, taken=taken)
    if not targets:
        return explore[0]
    pos = np.vstack([inp.agent_m[None], np.zeros((0, 2)) if team_m is None else team_m])
    pts = np.array([c.position_m for c in targets])
    dist = np.linalg.norm(pos[:, None, :] - pts[None], axis=2)
    again = np.array([[prm.heard_again_m * (c.kind == "heard"
                                            and name in inp.heard_by.get(c.node, ()))
                       for c in targets] for name in names]).reshape(len(names), len(targets))
    if len(names) == len(pos):
        dist = dist + again
    # heard nodes first: a refine target costs more than any heard one
    penalty = np.array([0.0 if c.kind == "heard" else 1.0 + 2.0 * float(dist.max()) * len(pos)
                        for c in targets])
    j = int(assign(dist + penalty[None])[0])
    return targets[j] if j >= 0 else explore[0]


def _explore_choice(inp: PlannerInput, candidates_m: FloatArray,
                    prm: WaypointParams) -> tuple[Choice, float]:
    """The exploration way point and its distance from every agent's track, m."""
    if len(inp.tracks_m):
        gap = np.min(np.linalg.norm(candidates_m[:, None, :] - inp.tracks_m[None], axis=2),
                     axis=1)
    else:
        gap = np.zeros(len(candidates_m))
    score = gap - prm.explore_distance_weight * np.hypot(*(candidates_m - inp.agent_m).T)
    i = int(np.argmax(score))
    return Choice(candidates_m[i].copy(), "explore", ""), float(gap[i])
