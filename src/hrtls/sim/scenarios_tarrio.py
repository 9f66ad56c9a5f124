"""Tarrio et al., Sec. IV (simulated circle) and Sec. V (office): RSS anchors and PDR."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.sim.devices import get_device
from hrtls.sim.gait_model import GaitParams
from hrtls.sim.infrastructure import RssChannel
from hrtls.sim.motion_truth import Waypoint, circle_waypoints
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["TARRIO_OFFICE_TABLE", "tarrio_circle", "tarrio_office"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def tarrio_circle(seed: int, **options: Any) -> SimulationResult:
    """9 anchors on a grid over 400 m^2, circle of radius 8 m at 1 m/s, 50 Hz, RSS every 2 s."""
    o = scenario_options(options, DEFAULTS["tarrio_circle"])
    r = scenario_rngs(seed)
    anchors = {f"A{3 * i + j + 1}": (10.0 * j, 10.0 * i, 1.0) for i in range(3) for j in range(3)}
    channel = RssChannel(a_dbm=-60.0, eta=2.5, sigma_db=5.0, sensitivity_dbm=-95.0,
                         beacon_rate_hz=o["readings_per_period"] / o["rss_period_s"])
    wps = circle_waypoints(center=(10.0, 10.0), radius_m=8.0, laps=o["laps"],
                           speed_m_s=o["speed_m_s"])
    infra = Infrastructure(anchors=anchors, channel=channel)
    ref = {"paper": "Tarrio et al., Sec. IV", "p90_error_m": 2.4,
           "kalman_improvement_over_rss_m": 1.5, "rss_period_s": o["rss_period_s"]}
    return simulate_person(
        "tarrio_circle", seed, o, wps, device=get_device("tarrio_sim"),
        gait=GaitParams(step_a_m=0.32, step_b_s=0.26), infra=infra,
        reference=ref, with_mag=False,
        description="Tarrio Sec. IV: 9 anchors on a 3x3 grid over 20x20 m, circle r = 8 m at "
                    f"{o['speed_m_s']} m/s, 50 Hz, A=-60 dBm, eta=2.5, sigma=5 dB, S=-95 dBm",
        notes=[f"{o['readings_per_period']} beacons per anchor per {o['rss_period_s']} s "
               "(the paper's n is not stated)",
               "receiver and anchors at the same height (2-D distances)"], rngs=r)


TARRIO_OFFICE_TABLE = {  # Tables I-II per user: mean RSS, RSS+PDR, KF; max RSS, RSS+PDR, KF (m)
    1: (3.31, 3.05, 2.39, 11.06, 11.17, 3.91), 2: (2.68, 2.54, 2.26, 6.45, 6.20, 4.36),
    3: (2.48, 2.32, 1.64, 8.03, 8.03, 4.02), 4: (3.83, 3.60, 2.92, 10.60, 9.93, 4.30),
    5: (2.59, 2.47, 2.30, 6.58, 6.33, 4.65), 6: (2.82, 2.48, 2.22, 5.98, 5.97, 4.33),
    7: (3.72, 3.42, 2.63, 7.75, 7.67, 3.92), 8: (2.70, 2.61, 2.22, 5.87, 5.61, 4.62)}


def tarrio_office(seed: int, **options: Any) -> SimulationResult:
    """Sec. V: 100 m^2 NLOS office, 9 anchors, L-shaped out-and-back path, RSS every 2 s."""
    o = scenario_options(options, DEFAULTS["tarrio_office"])
    user = int(o["user"])
    if user not in TARRIO_OFFICE_TABLE:
        raise InputError(f"user {user}", where="tarrio_office user", expected="1..8")
    r = scenario_rngs(seed)
    speed = 0.8 + 0.08 * user
    anchors = {"M1": (0.2, 0.2, 1.0), "M2": (6.0, 0.2, 1.0), "M3": (12.3, 0.2, 1.0),
               "M4": (0.2, 4.0, 1.0), "M5": (6.5, 3.5, 1.0), "M6": (12.3, 4.2, 1.0),
               "M7": (0.2, 7.8, 1.0), "M8": (5.5, 7.8, 1.0), "M9": (12.3, 7.8, 1.0)}
    # the real channel is worse than the model the system assumes (NLOS walls and furniture)
    channel = RssChannel(a_dbm=-60.0, eta=2.8, sigma_db=6.0, sensitivity_dbm=-95.0,
                         beacon_rate_hz=o["readings_per_period"] / 2.0,
                         anchor_offset_sigma_db=3.0)
    wps = [Waypoint(x=1.0, y=1.0), Waypoint(x=1.0, y=6.5, speed_m_s=speed, corner_radius_m=0.5),
           Waypoint(x=11.5, y=6.5, speed_m_s=speed, stop_s=3.0, corner_radius_m=0.0),
           Waypoint(x=1.0, y=6.5, speed_m_s=speed, corner_radius_m=0.5),
           Waypoint(x=1.0, y=1.0, speed_m_s=speed)]
    row = TARRIO_OFFICE_TABLE[user]
    ref = {"paper": "Tarrio et al., Sec. V, Tables I-II", "user": user,
           "mean_error_m": {"rss": row[0], "rss_pdr": row[1], "kf": row[2]},
           "max_error_m": {"rss": row[3], "rss_pdr": row[4], "kf": row[5]}}
    return simulate_person(
        "tarrio_office", seed, o, wps, device=get_device("mpu6150_phone").with_rate(50.0),
        gait=GaitParams(),
        infra=Infrastructure(anchors=anchors, channel=channel),
        reference=ref, with_mag=False,
        description=f"Tarrio Sec. V: 12.5x8 m office, 9 anchors, user {user} walks up, turns "
                    "right to the end of the room, stops, turns back; 50 Hz, RSS every 2 s",
        notes=["channel eta=2.8, sigma=6 dB, per-anchor offsets 3 dB (NLOS), in scenario.json "
               "only", "device: MPU-6150 class at 50 Hz stands in for the Shimmer mote"],
        rngs=r)
