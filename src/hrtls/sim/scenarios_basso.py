"""Basso et al. 2017, Sec. IV: long outdoor walks and walk+run paths, phone at the waist."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.sim.devices import get_device
from hrtls.sim.gait_model import GaitParams
from hrtls.sim.magnetic import EarthField, MagneticEnvironment
from hrtls.sim.motion_truth import Waypoint
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["BASSO_TABLE", "basso_test"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


BASSO_TABLE = {1: ("A", "W", 433.0, 0.005, 0.01), 2: ("B", "W", 399.0, 0.01, 0.021),
                3: ("B", "W", 551.0, 0.009, 0.009), 4: ("A", "W", 578.0, 0.015, 0.016),
                5: ("B", "W+R", 1124.0, 0.005, 0.016), 6: ("A", "W+R", 3262.0, 0.003, 0.014)}
_BASSO_USERS = {"A": GaitParams(step_a_m=0.36, step_b_s=0.26, run_a_m=0.60, run_b_s=0.20),
                "B": GaitParams(step_a_m=0.30, step_b_s=0.25, run_a_m=0.52, run_b_s=0.19,
                                pelvis_yaw_rad=0.09)}


def _basso_run(test: int, seed: int, options: Mapping[str, Any]) -> SimulationResult:
    o = scenario_options(options, DEFAULTS["basso"])
    user, pace, length, len_err, pos_err = BASSO_TABLE[test]
    r = scenario_rngs(seed)
    rng = r[0]
    wps = [Waypoint(x=0.0, y=0.0)]
    heading = float(rng.uniform(-np.pi, np.pi))
    walked = 0.0
    run_next = False
    corners: dict[str, tuple[float, float, float]] = {}
    while walked < length - 1e-6:
        leg = min(float(rng.uniform(25.0, 90.0)), length - walked)
        if length - walked - leg < 10.0:
            leg = length - walked
        heading += float(rng.choice([-1, 1]) * rng.uniform(np.deg2rad(45), np.deg2rad(120)))
        x = wps[-1].x + leg * np.cos(heading)
        y = wps[-1].y + leg * np.sin(heading)
        running = pace == "W+R" and run_next
        wps.append(Waypoint(x=x, y=y, speed_m_s=float(rng.uniform(2.6, 3.2)) if running
                            else float(rng.uniform(1.25, 1.5)), run=running,
                            corner_radius_m=0.8))
        corners[f"wp{len(wps) - 1}"] = (x, y, 0.0)
        run_next = not run_next if pace == "W+R" else False
        walked += leg
    device = get_device(o["device"]).with_rate(o["rate_hz"])
    ref = {"paper": "Basso et al. 2017, Table I", "test": test, "user": user, "pace": pace,
           "length_m": length, "length_error": len_err, "mean_position_error_of_length": pos_err}
    return simulate_person(
        f"basso_test{test}", seed, {**o, "test": test}, wps, device=device,
        gait=_BASSO_USERS[user], placement=o["placement"], lever_arm_b=(0.0, 0.15, -0.05),
        magnetic=MagneticEnvironment(earth=EarthField(inclination_rad=float(np.deg2rad(60.0)))),
        with_orientation=True, infra=Infrastructure(checkpoints=corners,
                                                    checkpoint_radius_m=2.0),
        reference=ref, user_height_m=1.80 if user == "A" else 1.70,
        description=f"Basso Table I test {test}: user {user}, {pace}, {length:.0f} m outdoor "
                    f"path with sharp turns, {o['rate_hz']:.0f} Hz, placement {o['placement']}",
        notes=["orientation.csv: the device's AHRS attitude with a slowly wandering heading "
               "error (Basso uses the built-in AHRS)",
               "checkpoints: the path's way-points (turns and end), as Basso scored"], rngs=r)


def basso_test(test: int) -> Callable[..., SimulationResult]:
    """The scenario of Basso Table I test ``test`` (1-6), called with a seed and options."""
    def run(seed: int, **options: Any) -> SimulationResult:
        return _basso_run(test, seed, options)

    run.__doc__ = f"Basso Table I test {test}."
    return run
