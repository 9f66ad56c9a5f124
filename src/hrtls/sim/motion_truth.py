"""Ground-truth motion of a walking person: paths from waypoints, speed profiles, stops and turns.

A path is a list of :class:`Waypoint` s. Consecutive waypoints are joined by straight legs; at an
interior waypoint the corner is rounded by a circular arc (``corner_radius_m``) or, with radius 0,
the person stops and turns on the spot. A leg whose end point has a different height is a
staircase (activity upstairs / downstairs). The person stops for ``stop_s`` at a waypoint.

Speed along each stop-free *run* follows the leg speeds, limited by an acceleration and a
braking bound, and by the lateral acceleration in arcs (``v <= sqrt(a_lat r)``). The profile is
integrated by a compiled kernel on the simulation grid; positions and headings of lines and
arcs are evaluated in closed form, vectorized.

Conventions: ENU navigation frame, heading CCW from +x (east), SI units (:mod:`hrtls.frames`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d
from shapely.geometry.base import BaseGeometry

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.sim._speed_profile import run_profile_kernel, run_speed_limits, still_headings
from hrtls.sim.corridor_paths import free_space_graph, pull_string

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

GAIT_WALK = 0
GAIT_RUN = 1
GAIT_STAIRS = 2


@dataclass(frozen=True, slots=True, kw_only=True)
class Waypoint:
    """A point of the path and the properties of the leg that *arrives* at it.

    Attributes
    ----------
    x, y, z:
        Position, m (ENU). ``z`` differs from the previous waypoint's on a staircase leg.
    speed_m_s:
        Horizontal cruise speed on the arriving leg, m/s.
    run:
        True when the arriving leg is run (activity running), else walked.
    stop_s:
        Time standing still at this waypoint, s (0: pass through).
    corner_radius_m:
        Radius of the arc that rounds the corner at this waypoint, m; clamped so that the arc
        fits in half of each adjacent leg. 0 means stop and turn on the spot.
    turn_rate_rad_s:
        Peak yaw rate of a turn on the spot at this waypoint, rad/s.
    """

    x: float
    y: float
    z: float = 0.0
    speed_m_s: float = 1.2
    run: bool = False
    stop_s: float = 0.0
    corner_radius_m: float = 0.5
    turn_rate_rad_s: float = 2.0


@dataclass(frozen=True, slots=True, kw_only=True)
class MotionParams:
    """Limits of the speed profile.

    Attributes
    ----------
    accel_m_s2: largest forward acceleration when speeding up, m/s^2.
    decel_m_s2: largest braking deceleration, m/s^2.
    lateral_accel_m_s2: largest centripetal acceleration in arcs, m/s^2.
    stair_tread_m: horizontal depth of one stair, m (one step per stair).
    stair_riser_m: height of one stair, m.
    min_turn_s: shortest duration of a turn on the spot, s.
    heading_smoothing_s: standard deviation of the Gaussian that smooths the body heading, s.
    vertical_smoothing_s: standard deviation of the Gaussian that smooths the height, s: the
        vertical velocity changes over about a step where a flight starts or ends.
    """

    accel_m_s2: float = 1.0
    decel_m_s2: float = 1.2
    lateral_accel_m_s2: float = 2.5
    stair_tread_m: float = 0.30
    stair_riser_m: float = 0.17
    min_turn_s: float = 0.4
    heading_smoothing_s: float = 0.15
    vertical_smoothing_s: float = 0.15


@dataclass(frozen=True, slots=True)
class PathGeometry:
    """Lines and arcs parameterized by horizontal arc length ``s`` (m).

    Primitive ``i`` starts at ``s0[i]`` at point ``p0[i]`` with heading ``h0[i]`` and has
    curvature ``k[i]`` (1/m, 0 for a line, positive turning left) and length ``length[i]``;
    ``leg[i]`` is the index of the leg it belongs to (arcs belong to the arriving leg). Height is
    linear in ``s`` between ``z_knots_s`` / ``z_knots``. ``corner_s`` are the path positions of
    the interior waypoints, ``corner_turn`` the on-the-spot turn there (rad, 0 for arcs).
    """

    s0: FloatArray
    length: FloatArray
    p0: FloatArray
    h0: FloatArray
    k: FloatArray
    leg: IntArray
    z_knots_s: FloatArray
    z_knots: FloatArray
    corner_s: FloatArray
    corner_turn: FloatArray

    @property
    def total_length_m(self) -> float:
        """Horizontal length of the whole path, m."""
        return float(self.s0[-1] + self.length[-1]) if len(self.s0) else 0.0

    def evaluate(self, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Positions (N, 3) in m, tangent headings (N,) in rad and curvature (N,) at ``s``."""
        s = np.clip(np.asarray(s, dtype=np.float64), 0.0, self.total_length_m)
        idx = np.clip(np.searchsorted(self.s0, s, side="right") - 1, 0, len(self.s0) - 1)
        ds = s - self.s0[idx]
        k = self.k[idx]
        h0 = self.h0[idx]
        h = h0 + k * ds
        straight = np.abs(k) < 1e-12
        safe_k = np.where(straight, 1.0, k)
        dx = np.where(straight, ds * np.cos(h0), (np.sin(h) - np.sin(h0)) / safe_k)
        dy = np.where(straight, ds * np.sin(h0), -(np.cos(h) - np.cos(h0)) / safe_k)
        z = np.interp(s, self.z_knots_s, self.z_knots)
        xyz = np.column_stack([self.p0[idx, 0] + dx, self.p0[idx, 1] + dy, z])
        return xyz, wrap_angle(h), k

    def leg_at(self, s: FloatArray) -> IntArray:
        """Index of the leg at path positions ``s``."""
        idx = np.clip(np.searchsorted(self.s0, s, side="right") - 1, 0, len(self.s0) - 1)
        return self.leg[idx]


def build_geometry(waypoints: Sequence[Waypoint]) -> PathGeometry:
    """Join waypoints by lines, rounding corners by arcs (or sharp corners for radius 0)."""
    if len(waypoints) < 2:
        raise InputError(f"{len(waypoints)} waypoint(s)", where="waypoints",
                         expected="at least 2 waypoints")
    pts = np.array([[w.x, w.y] for w in waypoints], dtype=np.float64)
    if not np.all(np.isfinite(pts)):
        raise InputError("non-finite waypoint", where="waypoints", expected="finite x, y in m")
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    if np.any(seg_len < 1e-6):
        i = int(np.flatnonzero(seg_len < 1e-6)[0])
        raise InputError("zero-length leg", where=f"waypoints index {i + 1}",
                         expected="distinct consecutive waypoints")
    hd = np.arctan2(seg[:, 1], seg[:, 0])
    n_legs = len(seg)
    # tangent lengths of the fillet at each interior waypoint: r tan(|turn| / 2), scaled down
    # where the two fillets of one leg would not fit on it
    want = np.zeros(n_legs + 1)
    turn = np.zeros(n_legs + 1)
    for i in range(1, n_legs):
        delta = float(wrap_angle(hd[i] - hd[i - 1]))
        turn[i] = delta
        r = waypoints[i].corner_radius_m
        half = 0.5 * abs(delta)
        if abs(delta) < 1e-9 or r <= 0.0 or half > np.deg2rad(67.5):
            continue  # straight on, or a sharp corner / turn above 135 deg: turn on the spot
        want[i] = r * np.tan(half)
    fit = np.minimum(1.0, seg_len / np.maximum(want[:-1] + want[1:], 1e-12))
    trim = want * np.minimum(np.concatenate([[1.0], fit]), np.concatenate([fit, [1.0]]))
    radius = np.zeros(n_legs + 1)
    for i in range(1, n_legs):
        if trim[i] > 1e-6:
            radius[i] = trim[i] / np.tan(0.5 * abs(turn[i]))
        else:
            trim[i] = 0.0
    s0: list[float] = []
    length: list[float] = []
    p0: list[FloatArray] = []
    h0: list[float] = []
    k: list[float] = []
    leg: list[int] = []
    corner_s = np.zeros(n_legs - 1)
    corner_turn = np.zeros(n_legs - 1)
    knot_s = [0.0]
    s = 0.0
    for j in range(n_legs):
        d = seg[j] / seg_len[j]
        start = pts[j] + trim[j] * d
        line_len = seg_len[j] - trim[j] - trim[j + 1]
        s0.append(s)
        length.append(line_len)
        p0.append(start)
        h0.append(float(hd[j]))
        k.append(0.0)
        leg.append(j)
        s += line_len
        if j + 1 < n_legs:
            i = j + 1
            if radius[i] > 0.0:
                arc_len = radius[i] * abs(turn[i])
                s0.append(s)
                length.append(arc_len)
                p0.append(pts[i] - trim[i] * d)
                h0.append(float(hd[j]))
                k.append(float(np.sign(turn[i]) / radius[i]))
                leg.append(j)
                corner_s[j] = s + 0.5 * arc_len
                s += arc_len
            else:
                corner_s[j] = s
                corner_turn[j] = turn[i]
            knot_s.append(corner_s[j])
    knot_s.append(s)
    z = np.array([w.z for w in waypoints], dtype=np.float64)
    return PathGeometry(
        s0=np.asarray(s0), length=np.asarray(length), p0=np.asarray(p0), h0=np.asarray(h0),
        k=np.asarray(k), leg=np.asarray(leg, dtype=np.int64), z_knots_s=np.asarray(knot_s),
        z_knots=z, corner_s=corner_s, corner_turn=corner_turn,
    )


@dataclass(frozen=True, slots=True)
class MotionTruth:
    """Sampled ground truth of the nominal (non-oscillating) motion.

    Attributes
    ----------
    t: sample times, s (uniform, ``dt`` apart).
    s: horizontal arc length travelled along the path, m.
    xyz: position of the body's centre (waist) without gait oscillation, m (N, 3).
    heading: walking direction / body heading without pelvis oscillation, rad.
    speed: horizontal speed along the path, m/s.
    gait: GAIT_WALK / GAIT_RUN / GAIT_STAIRS per sample.
    moving: True while walking (False while standing or turning on the spot).
    run_id: index of the stop-free run a sample belongs to (-1 while standing).
    activity: :class:`~hrtls.data.Activity` code per sample.
    step_length_override: fixed step length (stairs tread), m; NaN where the gait model decides.
    """

    t: FloatArray
    s: FloatArray
    xyz: FloatArray
    heading: FloatArray
    speed: FloatArray
    gait: IntArray
    moving: NDArray[np.bool_]
    run_id: IntArray
    activity: IntArray
    step_length_override: FloatArray

    @property
    def dt(self) -> float:
        """Sample period, s."""
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def distance_m(self) -> float:
        """Horizontal distance walked, m."""
        return float(self.s[-1] - self.s[0])

    def velocity(self) -> FloatArray:
        """Velocity of the nominal motion, m/s (N, 3), by central differences."""
        if len(self.t) < 2:
            return np.zeros((len(self.t), 3))
        return np.asarray(np.gradient(self.xyz, self.t, axis=0), dtype=np.float64)

    def floor(self, floor_height_m: float) -> IntArray:
        """Floor index per sample (0 at z = 0) for storeys ``floor_height_m`` apart."""
        if not floor_height_m > 0:
            raise InputError(f"floor height {floor_height_m}", where="floor_height_m",
                             expected="a positive height in m")
        return np.asarray(np.floor(self.xyz[:, 2] / floor_height_m + 0.5), dtype=np.int64)


def _check_waypoints(waypoints: Sequence[Waypoint], *, rate_hz: float) -> None:
    """Reject a non-positive rate, speed or a negative stop, naming the waypoint."""
    if not rate_hz > 0:
        raise InputError(f"rate {rate_hz}", where="rate_hz", expected="a positive rate in Hz")
    for i, w in enumerate(waypoints[1:], start=1):
        if not w.speed_m_s > 0:
            raise InputError(f"speed {w.speed_m_s}", where=f"waypoints index {i} speed_m_s",
                             expected="a positive speed in m/s")
        if w.stop_s < 0:
            raise InputError(f"stop {w.stop_s}", where=f"waypoints index {i} stop_s",
                             expected="a non-negative duration in s")


def _leg_labels(waypoints: Sequence[Waypoint]) -> tuple[IntArray, IntArray, FloatArray]:
    """Per leg: gait (GAIT_*), :class:`~hrtls.data.Activity` code and cruise speed, m/s."""
    n_legs = len(waypoints) - 1
    dz = np.diff([w.z for w in waypoints])
    leg_gait = np.array([GAIT_STAIRS if abs(dz[j]) > 1e-6 else
                         (GAIT_RUN if waypoints[j + 1].run else GAIT_WALK)
                         for j in range(n_legs)], dtype=np.int64)
    leg_activity = np.array([
        int(Activity.UPSTAIRS) if dz[j] > 1e-6 else int(Activity.DOWNSTAIRS) if dz[j] < -1e-6
        else int(Activity.RUNNING) if waypoints[j + 1].run else int(Activity.WALKING)
        for j in range(n_legs)], dtype=np.int64)
    leg_speed = np.array([waypoints[j + 1].speed_m_s for j in range(n_legs)])
    return leg_gait, leg_activity, leg_speed


def _run_boundaries(waypoints: Sequence[Waypoint], geo: PathGeometry
                    ) -> tuple[list[float], list[tuple[float, float, float]]]:
    """Path positions (m) bounding the stop-free runs and what follows each run.

    After each run: ``(turn rad, turn rate rad/s, stop s)``; a run ends at a waypoint with a
    stop or a turn on the spot.
    """
    boundaries = [0.0]
    pauses: list[tuple[float, float, float]] = []
    for i in range(1, len(waypoints) - 1):
        w = waypoints[i]
        turn = float(geo.corner_turn[i - 1])
        if w.stop_s > 0 or abs(turn) > 1e-9:
            boundaries.append(float(geo.corner_s[i - 1]))
            pauses.append((turn, w.turn_rate_rad_s, w.stop_s))
    boundaries.append(geo.total_length_m)
    pauses.append((0.0, 1.0, waypoints[-1].stop_s))
    return boundaries, pauses


@dataclass(slots=True)
class _Timeline:
    """The samples of the walk in order: arc length, speed, run index, headings of stills."""

    s: list[FloatArray]
    v: list[FloatArray]
    heading: list[FloatArray | None]
    run: list[FloatArray]

    def add_still(self, heading_rad: FloatArray, *, s_m: float) -> None:
        n = len(heading_rad)
        if n == 0:
            return
        self.s.append(np.full(n, s_m))
        self.v.append(np.zeros(n))
        self.heading.append(heading_rad)
        self.run.append(np.full(n, -1.0))

    def add_run(self, s_m: FloatArray, v_m_s: FloatArray, *, run: int) -> None:
        self.s.append(s_m)
        self.v.append(v_m_s)
        self.heading.append(None)
        self.run.append(np.full(len(s_m), float(run)))


def _body_pose(geo: PathGeometry, line: _Timeline, *, s_all: FloatArray, run_id: IntArray,
               boundaries: Sequence[float], smoothing_samples: float
               ) -> tuple[FloatArray, FloatArray]:
    """Position (m) and smoothed heading (rad) per sample: the path's, stills' headings kept."""
    # evaluate each run strictly inside its span so corner headings belong to the right leg
    s_eval = s_all.copy()
    for r in range(len(boundaries) - 1):
        sel = run_id == r
        s_eval[sel] = np.clip(s_all[sel], boundaries[r] + 1e-9, boundaries[r + 1] - 1e-9)
    xyz, h_path, _ = geo.evaluate(s_eval)
    heading = h_path.copy()
    pos = 0
    for part_s, part_h in zip(line.s, line.heading, strict=True):
        if part_h is not None:
            heading[pos:pos + len(part_s)] = part_h
        pos += len(part_s)
    # the body does not turn with infinite angular acceleration at line/arc joints
    heading = wrap_angle(gaussian_filter1d(np.unwrap(heading), smoothing_samples,
                                           mode="nearest"))
    return xyz, heading


def simulate_motion(waypoints: Sequence[Waypoint], *, rate_hz: float,
                    params: MotionParams | None = None, start_pause_s: float = 2.0,
                    end_pause_s: float = 2.0, t0_s: float = 0.0) -> MotionTruth:
    """Sample the motion along ``waypoints`` at ``rate_hz``.

    The person stands still for ``start_pause_s`` before walking and ``end_pause_s`` after.
    """
    p = params or MotionParams()
    _check_waypoints(waypoints, rate_hz=rate_hz)
    geo = build_geometry(waypoints)
    dt = 1.0 / rate_hz
    leg_gait, leg_activity, leg_speed = _leg_labels(waypoints)
    boundaries, pauses = _run_boundaries(waypoints, geo)
    line = _Timeline([], [], [], [])
    line.add_still(still_headings(duration_s=start_pause_s, heading_rad=float(geo.h0[0]),
                                   turn_rad=0.0, turn_rate_rad_s=1.0, dt_s=dt,
                                   min_turn_s=p.min_turn_s), s_m=0.0)
    for r in range(len(boundaries) - 1):
        a, b = boundaries[r], boundaries[r + 1]
        seg_s0, limits = run_speed_limits(geo, start_m=a, end_m=b, leg_speed_m_s=leg_speed,
                                           lateral_accel_m_s2=p.lateral_accel_m_s2)
        est_time = (b - a) / max(float(np.min(limits)), 0.05) + 20.0
        s_run, v_run = run_profile_kernel(seg_s0, limits, b - a, dt, p.accel_m_s2,
                                           p.decel_m_s2, int(est_time / dt) + 10)
        line.add_run(a + s_run, v_run, run=r)
        _, h_end, _ = geo.evaluate(np.array([b - 1e-9]))
        turn, rate, stop = pauses[r]
        still = stop + (max(abs(turn) * 1.875 / rate, p.min_turn_s) if abs(turn) > 0 else 0.0)
        if r == len(boundaries) - 2:
            still += end_pause_s
        line.add_still(still_headings(duration_s=still, heading_rad=float(h_end[0]),
                                       turn_rad=turn, turn_rate_rad_s=rate, dt_s=dt,
                                       min_turn_s=p.min_turn_s), s_m=b)
    s_all = np.concatenate(line.s)
    v_all = np.concatenate(line.v)
    run_id = np.concatenate(line.run).astype(np.int64)
    t = np.asarray(t0_s + np.arange(len(s_all)) * dt, dtype=np.float64)
    xyz, heading = _body_pose(geo, line, s_all=s_all, run_id=run_id, boundaries=boundaries,
                              smoothing_samples=p.heading_smoothing_s / dt)
    if np.ptp(xyz[:, 2]) > 0:
        # an instant change of vertical velocity would be an acceleration impulse
        xyz[:, 2] = gaussian_filter1d(xyz[:, 2], p.vertical_smoothing_s / dt, mode="nearest")
    moving = run_id >= 0
    leg_idx = geo.leg_at(s_all)
    gait = np.where(moving, leg_gait[leg_idx], GAIT_WALK)
    activity = np.where(moving & (v_all > 0.05), leg_activity[leg_idx], int(Activity.STANDING))
    override = np.where(gait == GAIT_STAIRS, p.stair_tread_m, np.nan)
    return MotionTruth(t=t, s=s_all, xyz=xyz, heading=heading, speed=v_all, gait=gait,
                       moving=moving, run_id=run_id, activity=activity.astype(np.int64),
                       step_length_override=override)


# --------------------------------------------------------------------------------------------
# Path builders
# --------------------------------------------------------------------------------------------
def circle_waypoints(*, center: tuple[float, float], radius_m: float, laps: float,
                     start_angle_rad: float = -np.pi / 2, ccw: bool = True, sides: int = 36,
                     speed_m_s: float = 1.2, z: float = 0.0) -> list[Waypoint]:
    """Waypoints whose maximally rounded polygon is exactly a circle of ``radius_m``.

    A regular polygon with inradius ``radius_m`` is walked from the middle of a side; rounding
    each corner with the inradius makes the arcs join into the circle.
    """
    if radius_m <= 0 or laps <= 0 or sides < 4:
        raise InputError(f"radius {radius_m}, laps {laps}, sides {sides}", where="circle",
                         expected="radius > 0, laps > 0, sides >= 4")
    big = radius_m / np.cos(np.pi / sides)
    sign = 1.0 if ccw else -1.0
    step = sign * 2 * np.pi / sides
    n_corners = int(np.floor(laps * sides + 1e-9))
    out = [Waypoint(x=center[0] + radius_m * np.cos(start_angle_rad),
                    y=center[1] + radius_m * np.sin(start_angle_rad), z=z, speed_m_s=speed_m_s)]
    for i in range(n_corners):
        ang = start_angle_rad + step * (i + 0.5)
        out.append(Waypoint(x=center[0] + big * np.cos(ang), y=center[1] + big * np.sin(ang),
                            z=z, speed_m_s=speed_m_s, corner_radius_m=radius_m * 1.0001))
    end_ang = start_angle_rad + step * n_corners
    out.append(Waypoint(x=center[0] + radius_m * np.cos(end_ang),
                        y=center[1] + radius_m * np.sin(end_ang), z=z, speed_m_s=speed_m_s))
    return out


def staircase_waypoints(*, start: tuple[float, float, float], heading_rad: float, n_stairs: int,
                        up: bool, params: MotionParams | None = None,
                        speed_m_s: float = 0.55) -> Waypoint:
    """End waypoint of a straight flight of ``n_stairs`` from ``start`` (tread x riser)."""
    p = params or MotionParams()
    run_len = n_stairs * p.stair_tread_m
    dz = n_stairs * p.stair_riser_m * (1.0 if up else -1.0)
    return Waypoint(x=start[0] + run_len * np.cos(heading_rad),
                    y=start[1] + run_len * np.sin(heading_rad), z=start[2] + dz,
                    speed_m_s=speed_m_s, corner_radius_m=0.3)


def random_floorplan_walk(free_space: BaseGeometry, rng: np.random.Generator, *,
                          distance_m: float, start: tuple[float, float] | None = None,
                          speed_range_m_s: tuple[float, float] = (0.9, 1.5),
                          stop_probability: float = 0.3,
                          stop_range_s: tuple[float, float] = (1.0, 20.0),
                          corner_radius_range_m: tuple[float, float] = (0.0, 1.0),
                          min_leg_m: float = 1.0, margin_m: float = 0.4,
                          grid_m: float | None = None) -> list[Waypoint]:
    """A natural random walk inside ``free_space`` (shapely polygon, m) of about ``distance_m``.

    The person picks random destinations in the floor plan shrunk by ``margin_m`` and goes
    there along the shortest route on a grid of free space (doors and corridors are found),
    straightened where the line of sight allows; at a destination they stop with probability
    ``stop_probability`` for a time drawn from ``stop_range_s``. Each leg has its own speed and
    corner radius drawn from the given ranges.
    """
    inner = free_space.buffer(-margin_m)
    if inner.is_empty or inner.area <= 0:
        raise InputError("free space vanishes after the margin", where="free_space",
                         expected=f"a polygon wider than 2 x {margin_m} m")
    minx, miny, maxx, maxy = inner.bounds
    shapely.prepare(inner)
    spacing = grid_m or max(0.25, min(1.0, min(maxx - minx, maxy - miny) / 8.0))
    nodes, graph = free_space_graph(inner=inner, spacing_m=spacing)
    if len(nodes) < 2:
        raise InputError("floor plan too small for its grid", where="free_space",
                         expected="a larger area")
    # keep the largest connected part
    part = max(nx.connected_components(graph), key=len)
    usable = np.array(sorted(part))
    cur = np.asarray(start, dtype=np.float64) if start is not None else \
        nodes[usable[rng.integers(len(usable))]]
    pts = [Waypoint(x=float(cur[0]), y=float(cur[1]))]
    walked = 0.0
    tries = 0
    while walked < distance_m:
        tries += 1
        if tries > 100000:
            raise InputError("cannot build the walk", where="free_space",
                             expected="a connected floor plan")
        goal = usable[rng.integers(len(usable))]
        here = usable[np.argmin(np.hypot(*(nodes[usable] - cur).T))]
        if np.hypot(*(nodes[goal] - cur)) < max(min_leg_m, 1e-6):
            continue
        route = nx.shortest_path(graph, int(here), int(goal), weight="weight")
        route_pts = np.vstack([cur[None, :], nodes[route]])
        keep = np.concatenate([[True], np.hypot(*np.diff(route_pts, axis=0).T) > 1e-9])
        straight = pull_string(points_m=route_pts[keep], inner=inner)
        speed = float(rng.uniform(*speed_range_m_s))
        for k, p in enumerate(straight[1:], start=1):
            last = k == len(straight) - 1
            stop = (float(rng.uniform(*stop_range_s))
                    if last and rng.random() < stop_probability else 0.0)
            pts.append(Waypoint(x=float(p[0]), y=float(p[1]), speed_m_s=speed, stop_s=stop,
                                corner_radius_m=float(rng.uniform(*corner_radius_range_m))))
            walked += float(np.hypot(*(p - cur)))
            cur = np.asarray(p, dtype=np.float64)
    return pts
