"""Inderst thesis Sec. 6.3: ring corridor with RFID tags, multi-floor walk, two users."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.sim.barometer import with_barometer
from hrtls.sim.devices import get_device
from hrtls.sim.gait_model import GaitParams
from hrtls.sim.infrastructure import RfidTag
from hrtls.sim.magnetic import MagneticEnvironment, random_anomalies
from hrtls.sim.motion_truth import MotionParams, Waypoint, circle_waypoints
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["inderst_multifloor", "inderst_ring", "inderst_two_users"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


_RING_TAGS = {  # id: (x, y, lobe direction deg, set)
    "T1": (20.0, 0.05, 90.0, "corner"), "T2": (30.0, 1.95, -90.0, "corridor"),
    "T3": (39.95, 0.05, 135.0, "corner"), "T4": (38.05, 10.0, 180.0, "corridor"),
    "T5": (39.95, 19.95, -135.0, "corner"), "T6": (20.0, 18.05, -90.0, "corridor"),
    "T7": (0.05, 19.95, -45.0, "corner"), "T8": (1.95, 10.0, 0.0, "corridor"),
    "T9": (0.05, 0.05, 45.0, "corner")}


def inderst_ring(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.3.2: ~500 m penetration mission around a ring corridor with 9 RFID tags."""
    o = scenario_options(options, DEFAULTS["inderst_ring"])
    sets = {"all": set(_RING_TAGS), "no_tag5": set(_RING_TAGS) - {"T5"},
            "corners": {k for k, v in _RING_TAGS.items() if v[3] == "corner"},
            "corridor": {k for k, v in _RING_TAGS.items() if v[3] == "corridor"},
            "none": set()}
    if o["tags"] not in sets:
        raise InputError(f"tag set {o['tags']!r}", where="inderst_ring tags",
                         expected="all, no_tag5, corners, corridor or none")
    r = scenario_rngs(seed)
    speed = o["speed_m_s"]
    loop = [(39.0, 1.0), (39.0, 19.0), (1.0, 19.0), (1.0, 1.0), (20.0, 1.0)]
    wps = [Waypoint(x=20.0, y=1.0)]
    walked = 0.0
    while walked < o["distance_m"]:
        for x, y in loop:
            prev = wps[-1]
            stop = float(r[0].uniform(2.0, 8.0)) if r[0].random() < 0.25 else 0.0
            wps.append(Waypoint(x=x, y=y, speed_m_s=speed * float(r[0].uniform(0.9, 1.1)),
                                corner_radius_m=0.8, stop_s=stop))
            walked += float(np.hypot(x - prev.x, y - prev.y))
    tags = []
    for k in sorted(sets[o["tags"]], key=lambda s: int(s[1:])):
        x, y, lobe, _ = _RING_TAGS[k]
        along = [0.0, np.pi] if y < 2.5 or y > 17.5 else [np.pi / 2, -np.pi / 2]
        tags.append(RfidTag(id=k, position=(x, y, 2.2), lobe_orientation_rad=np.deg2rad(lobe),
                            floor=0, bearings_rad=tuple(along)))
    cps = {"1": (20.0, 1.0, 0.0), "2": (39.0, 1.0, 0.0), "3": (39.0, 10.0, 0.0),
           "4": (39.0, 19.0, 0.0), "5": (20.0, 19.0, 0.0), "6": (1.0, 10.0, 0.0)}
    anomalies = random_anomalies(r[7], np.column_stack([
        r[7].uniform(0, 40, 8), r[7].choice([0.0, 2.0, 18.0, 20.0], 8), np.full(8, 0.8)]))
    ref = {"paper": "Inderst thesis Sec. 6.3.2, Tables 6.10 and 6.13", "tag_set": o["tags"],
           "pdr_final_error_m": 9.71, "pdr_max_error_m": 16.13,
           "corrected_error_all_tags_m": 2.62, "corrected_max_error_corners_m": 4.28,
           "corrected_max_error_corridor_m": 13.34, "rfid_radius_m": 2.5}
    return simulate_person(
        "inderst_ring", seed, o, wps, device=get_device("inemo"),
        magnetic=MagneticEnvironment(anomalies=anomalies),
        infra=Infrastructure(tags=tags, checkpoints=cps),
        reference=ref, placement="belt",
        description=f"Inderst Sec. 6.3.2: {o['distance_m']:.0f} m around a 40x20 m ring "
                    f"corridor, iNEMO 100 Hz, RFID reader 5 Hz, tag set '{o['tags']}'",
        notes=["ring layout, tag and checkpoint positions are ours (Fig. 6.7 is not in the "
               "text): corner set = T1 (entrance junction), T3, T5, T7, T9; corridor set = "
               "T2, T4, T6, T8"], rngs=r)


def inderst_multifloor(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.3.1 first experiment: ~280 m with three circles, stairs up and down."""
    o = scenario_options(options, DEFAULTS["inderst_multifloor"])
    r = scenario_rngs(seed)
    mp = MotionParams(stair_tread_m=0.30, stair_riser_m=0.165)
    v = o["speed_m_s"]
    fh = 3.3
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=10.0, y=0.0, speed_m_s=v)]
    # three full circles of radius 1.5 m, tangent to the corridor at (10, 0), turning left
    for _ in range(3):
        c = circle_waypoints(center=(10.0, 1.5), radius_m=1.5, laps=1.0, speed_m_s=0.9 * v)
        wps += c[1:]
    wps += [Waypoint(x=40.0, y=0.0, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=20.0, speed_m_s=v, corner_radius_m=0.5),
            Waypoint(x=43.0, y=20.0, z=fh / 2, speed_m_s=0.55, corner_radius_m=0.0),
            Waypoint(x=43.0, y=21.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=40.0, y=21.2, z=fh, speed_m_s=0.55, corner_radius_m=0.5),
            Waypoint(x=0.0, y=21.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=0.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=21.2, z=fh, speed_m_s=v, corner_radius_m=0.0),
            Waypoint(x=43.0, y=21.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=43.0, y=20.0, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=40.0, y=20.0, z=0.0, speed_m_s=0.6, corner_radius_m=0.5),
            Waypoint(x=40.0, y=0.0, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=0.0, y=0.0, speed_m_s=v)]
    cps = {"1": (0.0, 0.0, 0.0), "2": (40.0, 0.0, 0.0), "3": (40.0, 20.0, 0.0),
           "4": (40.0, 21.2, fh), "5": (0.0, 21.2, fh), "6": (0.0, 36.2, fh)}
    anomalies = random_anomalies(r[7], np.column_stack([
        r[7].uniform(0, 40, 10), r[7].uniform(-1, 37, 10), r[7].choice([0.8, 4.1], 10)]))
    ref = {"paper": "Inderst thesis Sec. 6.3.1, Table 6.8", "path_length_m": 280.0,
           "pdr_errors_m": [0, 7, 8.5, 10, 10, 22, 26, 22, 24],
           "activity_accuracy": 0.832}
    result = simulate_person(
        "inderst_multifloor", seed, o, wps, device=get_device("mpu9150_motionfit"),
        motion_params=mp, magnetic=MagneticEnvironment(anomalies=anomalies),
        infra=Infrastructure(checkpoints=cps),
        floor_height_m=fh, reference=ref,
        description="Inderst Sec. 6.3.1: flat walk with three circles, two flights up, a loop "
                    "on the first floor, two flights down and back to the start (~270 m)",
        notes=["reading: 'going upstairs and upstairs' taken as up, then down again, since the "
               "last phase is flat back to the start", "stairs: 0.30 m treads, 0.165 m risers, "
               "two flights of 10 per floor"], rngs=r)
    # a barometer with noise, weather drift and door/ventilation steps (its own random stream)
    return with_barometer(result) if o["pressure"] else result


def inderst_two_users(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.3.1: ~305 m with curves; user A stops and turns, user B turns while walking."""
    o = scenario_options(options, DEFAULTS["inderst_two_users"])
    user = str(o["user"]).upper()
    if user not in ("A", "B"):
        raise InputError(f"user {user!r}", where="inderst_two_users user", expected="A or B")
    r = scenario_rngs(seed)
    scale = 1.0
    course = [(0.0, 0.0), (40.0, 0.0), (50.0, 25.0), (38.0, 35.0), (30.0, 38.0), (20.0, 40.0),
              (-5.0, 20.0)]
    labels = {0: "1", 1: "2", 2: "3", 5: "4", 6: "5"}
    pts = [(scale * x, scale * y) for x, y in course]
    a_style = user == "A"
    wps = [Waypoint(x=pts[0][0], y=pts[0][1])]
    for _ in range(2):
        for i in [*range(1, len(pts)), 0]:
            x, y = pts[i]
            curve = i in (3, 4)  # the bend between checkpoints 3 and 4 is a curve for both
            wps.append(Waypoint(x=x, y=y, speed_m_s=1.2,
                                corner_radius_m=6.0 if curve else (0.0 if a_style else 3.0),
                                stop_s=0.5 if (a_style and not curve) else 0.0,
                                turn_rate_rad_s=3.0))
    cps = {labels[i]: (pts[i][0], pts[i][1], 0.0) for i in labels}
    tags: list[RfidTag] = []
    if o["tags"]:
        for i, lab in labels.items():
            if lab == "1":
                continue
            prev = pts[i - 1]
            nxt = pts[(i + 1) % len(pts)]
            h_in = float(np.arctan2(pts[i][1] - prev[1], pts[i][0] - prev[0]))
            h_out = float(np.arctan2(nxt[1] - pts[i][1], nxt[0] - pts[i][0]))
            tags.append(RfidTag(id=f"T{lab}", position=(pts[i][0], pts[i][1] + 0.0, 2.2),
                                lobe_orientation_rad=h_in + np.pi, floor=0,
                                bearings_rad=(h_in, h_out)))
    gait = GaitParams() if user == "B" else GaitParams(step_a_m=0.34, pelvis_yaw_rad=0.09)
    ref = {"paper": "Inderst thesis Sec. 6.3.1-6.3.2, Tables 6.11-6.12, 6.14-6.15",
           "user": user, "path_length_m": 305.0,
           "pdr_mean_error_m": 7.2 if a_style else 5.0,
           "pdr_max_error_m": 15.6 if a_style else 8.9,
           "position_corrected_max_m": 3.97 if a_style else 2.62,
           "position_heading_corrected_mean_m": 1.07 if a_style else 0.84}
    return simulate_person(
        "inderst_two_users", seed, {**o, "user": user}, wps,
        device=get_device("mpu6150_phone"), gait=gait,
        infra=Infrastructure(tags=tags, checkpoints=cps, checkpoint_radius_m=1.5),
        reference=ref, placement="belt",
        description=f"Inderst Sec. 6.3.1: user {user} "
                    f"({'stops and turns' if a_style else 'turns while walking'}) twice around "
                    "a ~150 m course with straight lines and a curve; MPU-6150 phone, "
                    "acc/gyro 100 Hz, magnetometer 50 Hz",
        notes=["course geometry is ours (Fig. 6.6 is not in the text); RFID tags with bearings "
               "at checkpoints 2-5 stand in for the exteroceptive position/heading sensors"],
        rngs=r)
