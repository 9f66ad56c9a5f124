"""Colombo et al. 2014, Sec. V: a room with cameras; circles, squares and a natural walk."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import box
from shapely.ops import unary_union

from hrtls.sim.devices import get_device
from hrtls.sim.infrastructure import CameraSystem
from hrtls.sim.motion_truth import Waypoint, circle_waypoints, random_floorplan_walk
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["colombo_circle", "colombo_natural", "colombo_square"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


_COLOMBO_ROOM = box(0.0, 0.0, 6.0, 5.0)
_COLOMBO_REF = {
    "paper": "Colombo et al. 2014, Sec. V",
    "velocity_rmse_m_s": 0.25,
    "position_error_bound_m": 0.5,
    "position_error_bound_probability": 0.97,
    "position_sigma_m": 0.25,
    "update_periods_s": [1, 2, 4, 8, 10, 16],
}


def _colombo_camera(tp_s: float) -> CameraSystem:
    return CameraSystem(period_s=tp_s, sigma_m=0.03, coverage=_COLOMBO_ROOM,
                        only_while_moving=True)


def colombo_circle(seed: int, **options: Any) -> SimulationResult:
    """Case A: repeated circles (31 m in total over 5 laps) at 1-2 m/s, fixes every Tp."""
    o = scenario_options(options, DEFAULTS["colombo_circle"])
    r = scenario_rngs(seed)
    speed = o["speed_m_s"] if o["speed_m_s"] > 0 else float(r[0].uniform(1.0, 2.0))
    radius = o["total_m"] / (o["laps"] * 2 * np.pi)
    wps = circle_waypoints(center=(3.0, 2.5), radius_m=radius, laps=o["laps"], speed_m_s=speed)
    return simulate_person(
        "colombo_circle", seed, {**o, "speed_m_s": speed}, wps,
        device=get_device("bma180_imu3000"), infra=Infrastructure(camera=_colombo_camera(
            o["tp_s"])), reference=_COLOMBO_REF,
        description=f"Colombo Case A: {o['laps']} circles of radius {radius:.2f} m at "
                    f"{speed:.2f} m/s, camera fixes every {o['tp_s']} s while moving, 250 Hz",
        notes=["reading: 31 m is the total length of the 5 laps (Fig. 9 caption)"], rngs=r)


def colombo_square(seed: int, **options: Any) -> SimulationResult:
    """Case B: repeated squares (40 m in total over 5 laps) with sharp 90-degree turns."""
    o = scenario_options(options, DEFAULTS["colombo_square"])
    r = scenario_rngs(seed)
    speed = o["speed_m_s"] if o["speed_m_s"] > 0 else float(r[0].uniform(1.0, 2.0))
    side = o["total_m"] / (4 * o["laps"])
    x0, y0 = 2.0, 1.5
    corners = [(x0 + side, y0), (x0 + side, y0 + side), (x0, y0 + side), (x0, y0)]
    wps = [Waypoint(x=x0, y=y0)]
    for _ in range(o["laps"]):
        wps += [Waypoint(x=c[0], y=c[1], speed_m_s=speed, corner_radius_m=0.15) for c in corners]
    return simulate_person(
        "colombo_square", seed, {**o, "speed_m_s": speed}, wps,
        device=get_device("bma180_imu3000"),
        infra=Infrastructure(camera=_colombo_camera(o["tp_s"])), reference=_COLOMBO_REF,
        description=f"Colombo Case B: {o['laps']} squares of side {side:.2f} m at "
                    f"{speed:.2f} m/s with sharp corners, fixes every {o['tp_s']} s", rngs=r)


def colombo_natural(seed: int, **options: Any) -> SimulationResult:
    """Natural paths in the living room with stops of 1-20 s at points of interest."""
    o = scenario_options(options, DEFAULTS["colombo_natural"])
    r = scenario_rngs(seed)
    furniture = unary_union([box(0.0, 0.0, 2.0, 0.8), box(4.5, 3.8, 6.0, 5.0),
                             box(2.6, 2.0, 3.4, 2.8)])
    free = _COLOMBO_ROOM.difference(furniture)
    wps = random_floorplan_walk(free, r[0], distance_m=o["distance_m"], stop_probability=0.6,
                                stop_range_s=(1.0, 20.0), speed_range_m_s=(0.8, 1.4),
                                corner_radius_range_m=(0.0, 0.6), min_leg_m=1.5, margin_m=0.35)
    return simulate_person(
        "colombo_natural", seed, o, wps, device=get_device("bma180_imu3000"),
        infra=Infrastructure(camera=_colombo_camera(o["tp_s"])), reference=_COLOMBO_REF,
        description="Colombo Fig. 12: natural walk between points of interest with stops of "
                    f"1-20 s, fixes every {o['tp_s']} s while moving", rngs=r)
