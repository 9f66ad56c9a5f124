"""A robot driven toward way points: its true motion along the corridors and its sensors.

The controller plans on the robot's **estimated** position: :class:`CorridorRouter` finds the
shortest corridor route from the estimate to the way point (grid of the free space shrunk by
``margin_m``, straightened where the line of sight allows: :mod:`hrtls.sim.corridor_paths`).
The wheels execute that route, so the true path is the planned route shifted by the estimation
error ``p_true - p_est`` at the planning time (each shifted corner is pulled back into the free
space: the robot does not drive through walls). :class:`DrivenRobot` samples the true motion at
the odometry rate (:func:`hrtls.sim.motion_truth.simulate_motion`, a unicycle along the route),
integrates wheel odometry from it (the model of :func:`hrtls.sim.team.odometry_poses`, continued
from part to part) and draws ranges to the nodes with the mission's radio model. Each
:meth:`DrivenRobot.drive` returns the session part of one period, to be fed to the mission's
tracker.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import Point
from shapely.geometry.base import BaseGeometry
from shapely.ops import nearest_points

from hrtls.data import Session
from hrtls.data.observations import GroundTruth, PositionFixes
from hrtls.data.session import SessionMeta
from hrtls.errors import InputError
from hrtls.sim.corridor_paths import free_space_graph, pull_string
from hrtls.sim.infrastructure import RangeModel, TrackSample, range_measurements
from hrtls.sim.motion_truth import Waypoint, simulate_motion
from hrtls.sim.team import ROBOT_RATE_HZ

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class DriverParams:
    """Controller and odometry of a driven robot (lengths m, speeds m/s)."""

    speed_m_s: float = 0.5
    margin_m: float = 0.4
    grid_m: float = 0.75
    arrive_m: float = 0.3
    """A way point closer than this to the estimate is reached (the robot stands)."""
    odometry_scale_sigma: float = 0.01
    heading_step_sigma_rad: float = float(np.deg2rad(0.05))

    def __post_init__(self) -> None:
        if not (self.speed_m_s > 0 and self.grid_m > 0 and self.arrive_m > 0
                and self.margin_m >= 0):
            raise InputError("invalid driver parameters", where="DriverParams",
                             expected="speed, grid and arrival distance > 0, margin >= 0")


class CorridorRouter:
    """Shortest routes inside ``free_space`` (module doc)."""

    def __init__(self, free_space: BaseGeometry, *, grid_m: float, margin_m: float) -> None:
        self.inner = free_space.buffer(-margin_m)
        shapely.prepare(self.inner)
        nodes, graph = free_space_graph(inner=self.inner, spacing_m=grid_m)
        parts: list[set[int]] = [set(c) for c in nx.connected_components(graph)]
        part = sorted(parts[int(np.argmax([len(c) for c in parts]))])
        self.graph = graph.subgraph(part)
        self.nodes = nodes
        self.index = np.asarray(part, dtype=np.int64)
        self.points_m = nodes[self.index]
        """Reachable grid points (candidate way points of a planner)."""

    def inside(self, xy_m: FloatArray) -> FloatArray:
        """``xy_m`` pulled to the nearest point of the free space when it is outside."""
        p = Point(float(xy_m[0]), float(xy_m[1]))
        if self.inner.contains(p):
            return np.asarray(xy_m, dtype=np.float64)
        q = nearest_points(self.inner.buffer(-1e-6), p)[0]
        return np.array([q.x, q.y])

    def route(self, start_m: FloatArray, goal_m: FloatArray) -> FloatArray:
        """``(k, 2)`` corner points of the route from ``start_m`` to ``goal_m`` (both pulled in)."""
        a, b = self.inside(start_m), self.inside(goal_m)
        ia = int(self.index[np.argmin(np.hypot(*(self.points_m - a).T))])
        ib = int(self.index[np.argmin(np.hypot(*(self.points_m - b).T))])
        path = self.nodes[nx.shortest_path(self.graph, ia, ib, weight="weight")]
        pts = np.vstack([a[None], path, b[None]])
        keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-9])
        return np.asarray(pull_string(points_m=pts[keep], inner=self.inner))


class DrivenRobot:
    """True pose, odometry and radio of a robot driven period by period (module doc)."""

    def __init__(self, *, meta: SessionMeta, start_xy_m: FloatArray, start_t_s: float,
                 nodes: dict[str, tuple[float, float, float]], model: RangeModel,
                 router: CorridorRouter, rng: np.random.Generator,
                 params: DriverParams | None = None) -> None:
        self.params = params or DriverParams()
        self.meta = meta
        self.nodes = nodes
        self.model = model
        self.router = router
        self.rng = rng
        self.t_s = start_t_s
        self.xy_m = np.asarray(start_xy_m, dtype=np.float64)
        self.heading_rad = float(meta.start_pose.heading or 0.0) if meta.start_pose else 0.0
        self.odo_m = self.xy_m.copy()
        self.odo_heading_err_rad = 0.0
        self.odo_scale = 1.0 + rng.normal(0.0, self.params.odometry_scale_sigma)
        self.travelled_m = 0.0
        self.first = True

    def _true_motion(self, estimate_m: FloatArray, target_m: FloatArray,
                     n: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``n`` true samples after the current one: position, heading, speed."""
        prm = self.params
        dt = 1.0 / ROBOT_RATE_HZ
        route = self.router.route(estimate_m, target_m)
        shifted = [self.xy_m] + [self.router.inside(p + self.xy_m - route[0]) for p in route[1:]]
        pts = [shifted[0]] + [p for p in shifted[1:] if np.hypot(*(p - shifted[0])) > 1e-6]
        length = float(np.sum(np.hypot(*np.diff(np.asarray(pts), axis=0).T))) \
            if len(pts) > 1 else 0.0
        xy = np.broadcast_to(self.xy_m, (n, 2)).copy()
        heading = np.full(n, self.heading_rad)
        speed = np.zeros(n)
        if length < prm.arrive_m or np.hypot(*(estimate_m - target_m)) < prm.arrive_m:
            return xy, heading, speed
        wps = [Waypoint(x=float(p[0]), y=float(p[1]), speed_m_s=prm.speed_m_s,
                        corner_radius_m=0.3) for p in pts]
        m = simulate_motion(wps, rate_hz=ROBOT_RATE_HZ, start_pause_s=0.0, end_pause_s=dt)
        k = min(n, len(m.t) - 1)
        xy[:k] = m.xyz[1:k + 1, :2]
        heading[:k] = m.heading[1:k + 1]
        speed[:k] = m.speed[1:k + 1]
        xy[k:] = xy[k - 1] if k else self.xy_m
        heading[k:] = heading[k - 1] if k else self.heading_rad
        return xy, heading, speed

    def drive(self, *, estimate_m: FloatArray, target_m: FloatArray, until_s: float) -> Session:
        """Drive toward ``target_m`` planned from ``estimate_m`` until ``until_s``; the part."""
        dt = 1.0 / ROBOT_RATE_HZ
        n = int(np.floor((until_s - self.t_s) / dt + 1e-9))
        if n < 1:
            raise InputError(f"until {until_s} s", where="DrivenRobot.drive",
                             expected=f"at least one odometry period after {self.t_s} s")
        xy, heading, speed = self._true_motion(np.asarray(estimate_m), np.asarray(target_m), n)
        t = np.asarray(self.t_s + dt * np.arange(1, n + 1), dtype=np.float64)
        step = np.diff(np.vstack([self.xy_m[None], xy]), axis=0)
        odo = self._odometry(step)
        travelled = self.travelled_m + np.cumsum(np.hypot(*step.T))
        # the radio sees the track from the previous sample on (the part's first ranges)
        track = TrackSample(t=np.concatenate([[self.t_s], t]),
                            xyz=np.column_stack([np.vstack([self.xy_m[None], xy]),
                                                 np.zeros(n + 1)]),
                            heading=np.concatenate([[self.heading_rad], heading]),
                            speed=np.concatenate([[0.0], speed]))
        ranges = range_measurements(self.nodes, self.model, track, self.rng)
        if self.first:  # the part that starts the session holds the start pose
            t, xy, heading = track.t, track.xyz[:, :2], track.heading
            odo = np.vstack([self.odo_m[None], odo])
            travelled = np.concatenate([[self.travelled_m], travelled])
        self.first = False
        self.t_s, self.xy_m, self.heading_rad = float(t[-1]), xy[-1].copy(), float(heading[-1])
        self.odo_m, self.travelled_m = odo[-1].copy(), float(travelled[-1])
        z = np.zeros(len(t))
        xyz = np.column_stack([xy, z])
        return Session(meta=self.meta,
                       fixes=PositionFixes(t, np.column_stack([odo, z]), 0.05 + 0.01 * travelled),
                       ranges=ranges, truth=GroundTruth(t, xyz, heading))

    def _odometry(self, step: FloatArray) -> FloatArray:
        """Odometry positions after each true displacement (heading random walk, scale)."""
        err = self.odo_heading_err_rad + np.cumsum(
            self.rng.normal(0.0, self.params.heading_step_sigma_rad, len(step)))
        self.odo_heading_err_rad = float(err[-1])
        c, s = np.cos(err), np.sin(err)
        moved = self.odo_scale * np.column_stack([c * step[:, 0] - s * step[:, 1],
                                                  s * step[:, 0] + c * step[:, 1]])
        return np.asarray(self.odo_m + np.cumsum(moved, axis=0))
