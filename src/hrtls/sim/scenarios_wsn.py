"""Inderst thesis Sec. 6.4.1: sensor networks ranged by a robot or a walking rescuer."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import LineString, box
from shapely.ops import unary_union

from hrtls.data import Activity, GroundTruth, Session, SessionMeta, StepEvents
from hrtls.data.session import StartPose
from hrtls.errors import InputError
from hrtls.sim.devices import get_device
from hrtls.sim.infrastructure import (
    RangeModel,
    TrackSample,
    WsnDeployment,
    anchor_landmarks,
    random_wsn,
    range_measurements,
)
from hrtls.sim.motion_truth import MotionParams, Waypoint, simulate_motion
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["inderst_wsn_building", "inderst_wsn_random"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _robot_wsn(seed: int, name: str, wsn: WsnDeployment, waypoints: list[Waypoint],
               range_model: RangeModel, reference: dict[str, Any], description: str,
               options: dict[str, Any], rngs: list[np.random.Generator]) -> SimulationResult:
    """A mobile agent without IMU that only ranges to the network's nodes."""
    motion = simulate_motion(waypoints, rate_hz=10.0, start_pause_s=1.0, end_pause_s=1.0,
                             params=MotionParams(accel_m_s2=0.2, decel_m_s2=0.2,
                                                 lateral_accel_m_s2=0.2))
    track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading, speed=motion.speed)
    nodes = {k: tuple(float(c) for c in (*wsn.positions[i, :2], 0.0))
             for i, k in enumerate(wsn.ids)}
    ranges = range_measurements(nodes, range_model, track, rngs[6])
    anchors = {k: nodes[k] for i, k in enumerate(wsn.ids) if wsn.anchor[i]}
    if ranges is None:
        raise InputError("the agent never came in range of a node", where=name,
                         expected="a path through the network")
    meta = SessionMeta(
        start_pose=StartPose(x=float(motion.xyz[0, 0]), y=float(motion.xyz[0, 1]),
                             heading=float(motion.heading[0]), sigma_xy_m=0.01),
        placement="robot", source={"format": "hrtls-sim", "scenario": name, "seed": seed,
                                   "options": options},
        notes=[description, "landmarks: the anchor (seed) nodes only; all true positions are "
                            "in wsn_truth.json"])
    session = Session(meta=meta, ranges=ranges,
                      landmarks=anchor_landmarks({k: (*v[:2], 0.0) for k, v in anchors.items()},
                                                 kind="node"),
                      truth=GroundTruth(motion.t, motion.xyz, motion.heading))
    return SimulationResult(scenario=name, seed=seed, options=options, session=session,
                            true_steps=StepEvents.empty(), activity_t=motion.t,
                            activity=np.full(len(motion.t), int(Activity.UNKNOWN)),
                            motion=motion, wsn=wsn, reference=reference,
                            description=description)


def inderst_wsn_random(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.4.1: 50 random nodes in the unit square, radius 0.2, seeds in the lower left."""
    o = scenario_options(options, DEFAULTS["inderst_wsn_random"])
    r = scenario_rngs(seed)
    wsn = random_wsn(r[7], n_nodes=int(o["n_nodes"]), region=box(0.0, 0.0, 1.0, 1.0),
                     radius=float(o["radius"]), n_anchors=int(o["n_anchors"]),
                     distance_sigma=float(o["distance_sigma"]))
    lanes = [0.1, 0.3, 0.5, 0.7, 0.9]
    wps = [Waypoint(x=0.05, y=0.1)]
    for i, y in enumerate(lanes):
        xs = (0.95, 0.05) if i % 2 == 0 else (0.05, 0.95)
        wps += [Waypoint(x=xs[0], y=y, speed_m_s=0.05, corner_radius_m=0.05)]
        if i + 1 < len(lanes):
            wps += [Waypoint(x=xs[0], y=lanes[i + 1], speed_m_s=0.05, corner_radius_m=0.05)]
    model = RangeModel(rate_hz=1.0, sigma_m=0.005, max_range_m=float(o["radius"]),
                       nlos_bias_mean_m=0.0, agent_height_m=0.0, dropout_probability=0.0)
    return _robot_wsn(seed, "inderst_wsn_random", wsn, wps, model,
                      {"paper": "Inderst thesis Sec. 6.4.1, Fig. 6.11", "n_nodes": 50,
                       "radius": 0.2, "sela_localized_before_agent": 5},
                      "Inderst Sec. 6.4.1: 50 nodes uniform in the unit square, radius 0.2, "
                      "seeds nearest the lower-left corner; a mobile agent sweeps the square "
                      "at 0.05 units/s ranging to nodes within 0.2", o, r)


def inderst_wsn_building(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.4.1: 12 nodes in a building with ~5 m range; a rescuer walks ~40 m through it."""
    o = scenario_options(options, DEFAULTS["inderst_wsn_building"])
    r = scenario_rngs(seed)
    hall = unary_union([box(0.0, 0.0, 20.0, 3.0), box(17.0, 0.0, 20.0, 14.0),
                        box(4.0, 3.0, 12.0, 9.0)])
    wsn = random_wsn(r[7], n_nodes=12, region=hall, radius=float(o["range_m"]),
                     n_anchors=int(o["n_anchors"]), distance_sigma=0.2, z=0.0)
    walls = unary_union([LineString([(4.0, 3.0), (7.0, 3.0)]),
                         LineString([(9.0, 3.0), (12.0, 3.0)]),
                         LineString([(17.0, 3.0), (17.0, 14.0)])])
    wps = [Waypoint(x=1.0, y=1.5), Waypoint(x=8.0, y=1.5, corner_radius_m=0.6),
           Waypoint(x=8.0, y=7.0, stop_s=3.0, corner_radius_m=0.0),
           Waypoint(x=8.0, y=1.5, corner_radius_m=0.6), Waypoint(x=18.5, y=1.5,
                                                                 corner_radius_m=0.8),
           Waypoint(x=18.5, y=12.5)]
    nodes = {k: (float(wsn.positions[i, 0]), float(wsn.positions[i, 1]), 0.5)
             for i, k in enumerate(wsn.ids)}
    model = RangeModel(rate_hz=1.0, sigma_m=0.3, max_range_m=float(o["range_m"]), walls=walls)
    res = simulate_person(
        "inderst_wsn_building", seed, o, wps, device=get_device("mpu6150_phone"),
        infra=Infrastructure(nodes=nodes, range_model=model),
        reference={"paper": "Inderst thesis Sec. 6.4.1, Fig. 6.12", "n_nodes": 12,
                   "range_m": 5.0, "path_length_m": 40.0, "sela_localized_before_agent": 6},
        description="Inderst Sec. 6.4.1: 12 range-capable nodes (~5 m range) in a building, "
                    "3 seeds; a rescuer walks ~40 m through it with a phone at the waist",
        notes=["landmarks hold all nodes; wsn.json gives positions of the seeds only"], rngs=r)
    return SimulationResult(**{**{f: getattr(res, f) for f in res.__dataclass_fields__},
                               "wsn": wsn})
