"""The two-floor building of the hybrid mission (:mod:`hrtls.sim.mission`, ``n_floors = 2``).

Floor 1 repeats the corridor layout of floor 0 at :data:`FLOOR_HEIGHT_M`. A stairwell outside
the north-east corridor corner joins them: from :data:`STAIR_FOOT_XY` a flight of 10 stairs
(0.30 m treads, 0.165 m risers) east to a landing, a second flight back west to
:data:`STAIR_TOP_XY` on floor 1 (the stairs of ``inderst_multifloor``). A rescuer's route walks
floor 0 from the entrance, the shortest corridor route to the stairwell, up, a random walk on
floor 1 and, for about half of the rescuers, down again and a last walk on floor 0.

The floor slab blocks the radio: an agent ranges only to the nodes of the floor it is on
(the nearest floor level to its true height at the reading; :func:`slab_ranges`). Tags and
nodes of floor ``k`` are ``k * FLOOR_HEIGHT_M`` higher than their floor-0 counterparts.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from hrtls.data.observations import RangeMeasurements
from hrtls.sim.floorplan import floor_of
from hrtls.sim.infrastructure import RangeModel, RfidTag, TrackSample, range_measurements
from hrtls.sim.motion_truth import MotionParams, MotionTruth, Waypoint, random_floorplan_walk
from hrtls.sim.robot_driver import CorridorRouter

FloatArray = NDArray[np.float64]

FLOOR_HEIGHT_M = 3.3
"""Height between two floors of the building, m."""
STAIR_FOOT_XY = (59.0, 28.0)
"""Foot of the stairs on floor 0 (north-east corridor corner)."""
STAIR_TOP_XY = (59.0, 29.2)
"""Top of the stairs on floor 1 (above the floor-0 corridor corner)."""
STAIR_MOTION = MotionParams(stair_tread_m=0.30, stair_riser_m=0.165)
"""Stairs of the stairwell: 10 stairs a flight, two flights a floor."""
NODE_HEIGHT_M = 0.5
"""Height of a dropped node above its floor, m."""


def node_floors(nodes: Mapping[str, tuple[float, float, float]]) -> dict[str, int]:
    """Each node's floor, from its height (:data:`NODE_HEIGHT_M` above its floor)."""
    return {k: int(floor_of(np.array([v[2] - NODE_HEIGHT_M]), floor_height_m=FLOOR_HEIGHT_M)[0])
            for k, v in nodes.items()}


def stair_leg(*, up: bool) -> list[Waypoint]:
    """Way points from the stair foot (floor 0) to the stair top (floor 1), or back."""
    fh = FLOOR_HEIGHT_M
    (fx, fy), (tx, ty) = STAIR_FOOT_XY, STAIR_TOP_XY
    up_pts = [(fx, fy, 0.0), (60.0, fy, 0.0), (63.0, fy, fh / 2), (63.0, ty, fh / 2),
              (60.0, ty, fh), (tx, ty, fh)]
    pts = up_pts if up else up_pts[::-1]
    return [Waypoint(x=x, y=y, z=z, speed_m_s=0.55, corner_radius_m=0.0) for x, y, z in pts]


def _route_to(router: CorridorRouter, start: Waypoint, goal_xy: tuple[float, float],
              z_m: float) -> list[Waypoint]:
    pts = router.route(np.array([start.x, start.y]), np.asarray(goal_xy, dtype=np.float64))
    out = [Waypoint(x=float(x), y=float(y), z=z_m, speed_m_s=1.2, corner_radius_m=0.5)
           for x, y in pts[1:]]
    return [*out[:-1], Waypoint(x=goal_xy[0], y=goal_xy[1], z=z_m, speed_m_s=1.2)]


def _floor_walk(free_space: BaseGeometry, rng: np.random.Generator, *, distance_m: float,
                start: tuple[float, float], z_m: float) -> list[Waypoint]:
    """A random corridor walk from ``start`` at height ``z_m``, without its first point."""
    wps = random_floorplan_walk(free_space, rng, distance_m=distance_m,
                                start=start, stop_probability=0.1, stop_range_s=(2.0, 8.0),
                                min_leg_m=3.0)
    return [dataclasses.replace(w, z=z_m) for w in wps[1:]]


def two_floor_walk(free_space: BaseGeometry, router: CorridorRouter, rng: np.random.Generator, *,
                   distance_m: float, start: tuple[float, float]) -> list[Waypoint]:
    """A rescuer's route through both floors (module doc), about ``distance_m`` long."""
    back = bool(rng.random() < 0.5)
    shares = (0.3, 0.45, 0.25) if back else (0.35, 0.65, 0.0)
    wps = [Waypoint(x=start[0], y=start[1])]
    wps += _floor_walk(free_space, rng, distance_m=shares[0] * distance_m, start=start, z_m=0.0)
    wps += _route_to(router, wps[-1], STAIR_FOOT_XY, 0.0)
    wps += stair_leg(up=True)[1:]
    wps += _floor_walk(free_space, rng, distance_m=shares[1] * distance_m, start=STAIR_TOP_XY,
                       z_m=FLOOR_HEIGHT_M)
    if back:
        wps += _route_to(router, wps[-1], STAIR_TOP_XY, FLOOR_HEIGHT_M)
        wps += stair_leg(up=False)[1:]
        wps += _floor_walk(free_space, rng, distance_m=shares[2] * distance_m,
                           start=STAIR_FOOT_XY, z_m=0.0)
    return wps


def floor_tags(tags: list[RfidTag], n_floors: int) -> list[RfidTag]:
    """``tags`` (floor 0) repeated on every floor: floor ``k``'s ids end in ``F<k>``."""
    out = list(tags)
    for k in range(1, n_floors):
        out += [dataclasses.replace(t, id=f"{t.id}F{k}", floor=k,
                                    position=(t.position[0], t.position[1],
                                              t.position[2] + k * FLOOR_HEIGHT_M))
                for t in tags]
    return out


def spread_nodes(nodes: Mapping[str, tuple[float, float, float]], n_floors: int
                 ) -> dict[str, tuple[float, float, float]]:
    """Node ``N<j>`` on floor ``(j - 1) mod n_floors``, :data:`NODE_HEIGHT_M` above it."""
    return {k: (x, y, NODE_HEIGHT_M + ((int(k[1:]) - 1) % n_floors) * FLOOR_HEIGHT_M)
            for k, (x, y, _) in nodes.items()}


def slab_ranges(nodes: Mapping[str, tuple[float, float, float]], model: RangeModel,
                motion: MotionTruth, rng: np.random.Generator) -> RangeMeasurements | None:
    """Ranges to ``nodes`` read only while the agent is on the node's floor (module doc)."""
    track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading, speed=motion.speed)
    got = range_measurements(nodes, model, track, rng)
    if got is None:
        return None
    node_floor = node_floors(nodes)
    agent_floor = floor_of(np.interp(got.t, motion.t, motion.xyz[:, 2]),
                           floor_height_m=FLOOR_HEIGHT_M)
    keep = agent_floor == np.array([node_floor[str(n)] for n in got.node], dtype=np.int64)
    if not keep.any():
        return None
    return RangeMeasurements(got.t[keep], got.node[keep], got.range_m[keep], got.sigma_m[keep])
