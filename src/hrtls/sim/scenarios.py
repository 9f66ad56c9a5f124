"""Named, seeded scenarios reproducing the papers' experiments, and their on-disk form.

``SCENARIOS`` maps a name to a :class:`ScenarioSpec`; ``run_scenario(name, seed, **options)``
returns a :class:`SimulationResult` holding a :class:`~hrtls.data.Session` (sensor streams,
observations, landmarks, ground truth, checkpoints) plus the true steps and the per-sample
activity. :func:`write_result` writes the session folder and, next to its files,
``truth_steps.csv`` (steps.csv columns), ``activity.csv`` (``t_start,t_end,activity``
intervals, the labelled-session form the activity trainer reads),
``scenario.json`` (name, seed, options, paper reference numbers) and for sensor-network
scenarios ``wsn.json`` (positions of anchors only) and ``wsn_truth.json`` (all positions).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from shapely.geometry import box
from shapely.ops import unary_union

from hrtls.errors import InputError
from hrtls.sim.devices import get_device
from hrtls.sim.infrastructure import CameraSystem, RangeModel, RfidTag, RssChannel
from hrtls.sim.magnetic import MagneticEnvironment, random_anomalies
from hrtls.sim.motion_truth import random_floorplan_walk
from hrtls.sim.person import CALIBRATION_LEG_M, Infrastructure, mounting_quaternion, simulate_person
from hrtls.sim.scenario_options import DEFAULTS, scenario_options, scenario_rngs
from hrtls.sim.scenarios_basso import BASSO_TABLE, basso_test
from hrtls.sim.scenarios_colombo import colombo_circle, colombo_natural, colombo_square
from hrtls.sim.scenarios_inderst import inderst_multifloor, inderst_ring, inderst_two_users
from hrtls.sim.scenarios_tarrio import TARRIO_OFFICE_TABLE, tarrio_circle, tarrio_office
from hrtls.sim.scenarios_wsn import inderst_wsn_building, inderst_wsn_random
from hrtls.sim.simulation_result import SimulationResult, write_extras, write_result

__all__ = ["CALIBRATION_LEG_M", "SCENARIOS", "TARRIO_OFFICE_TABLE", "Infrastructure",
           "ScenarioSpec", "SimulationResult", "mounting_quaternion", "office_random_walk",
           "run_scenario", "simulate_person", "write_extras", "write_result"]


# --------------------------------------------------------------------------------------------
# A long office walk with every kind of infrastructure (benchmark)
# --------------------------------------------------------------------------------------------
def office_random_walk(seed: int, **options: Any) -> SimulationResult:
    """Random natural walk in a 60x30 m office floor with cameras, beacons, tags and nodes."""
    o = scenario_options(options, DEFAULTS["office_random_walk"])
    r = scenario_rngs(seed)
    free = unary_union([box(0, 0, 60, 3), box(0, 27, 60, 30), box(0, 0, 3, 30),
                        box(57, 0, 60, 30), box(28.5, 0, 31.5, 30), box(5, 5, 25, 12),
                        box(35, 18, 55, 25), box(14, 2, 16, 6), box(44, 24, 46, 28)])
    mean_speed = 1.15  # m of walk per s of duration, stops included (measured)
    wps = random_floorplan_walk(free, r[0], distance_m=o["duration_s"] * mean_speed,
                                start=(1.5, 1.5), stop_probability=0.15,
                                stop_range_s=(2.0, 15.0), min_leg_m=3.0)
    anchors = {f"B{i + 1}": (float(x), float(y), 2.5) for i, (x, y) in enumerate(
        [(0, 0), (30, 0), (60, 0), (0, 30), (30, 30), (60, 30), (15, 15), (45, 15)])}
    tags = [RfidTag(id=f"T{i + 1}", position=(x, y, 2.2), lobe_orientation_rad=a, floor=0)
            for i, (x, y, a) in enumerate([(30.0, 1.5, np.pi / 2), (1.5, 15.0, 0.0),
                                           (58.5, 15.0, np.pi), (30.0, 28.5, -np.pi / 2),
                                           (15.0, 4.9, -np.pi / 2), (45.0, 25.1, np.pi / 2)])]
    nodes = {f"N{i + 1}": (float(x), float(y), 0.5) for i, (x, y) in enumerate(
        [(10, 1.5), (50, 1.5), (10, 28.5), (50, 28.5), (30, 15)])}
    sites = np.column_stack([r[7].uniform(0, 60, 15), r[7].uniform(0, 30, 15), np.full(15, 0.8)])
    infra = Infrastructure(
        camera=CameraSystem(period_s=1.0, sigma_m=0.05, coverage=box(5, 5, 25, 12)),
        anchors=anchors, channel=RssChannel(a_dbm=-60.0, eta=2.5, sigma_db=5.0,
                                            beacon_rate_hz=2.0),
        tags=tags, nodes=nodes,
        range_model=RangeModel(rate_hz=1.0, sigma_m=0.3, max_range_m=10.0))
    return simulate_person(
        "office_random_walk", seed, o, wps, device=get_device(o["device"]),
        magnetic=MagneticEnvironment(anomalies=random_anomalies(r[7], sites)), infra=infra,
        description=f"random natural walk of about {o['duration_s']:.0f} s in a 60x30 m office "
                    "with cameras (one room), 8 BLE beacons, 6 RFID tags and 5 range nodes",
        rngs=r)


# --------------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class ScenarioSpec:
    """A registered scenario: the function, a one-line summary and its options' defaults."""

    run: Callable[..., SimulationResult]
    summary: str
    options: dict[str, Any] = field(default_factory=dict)


def _spec(run: Callable[..., SimulationResult], summary: str, key: str) -> ScenarioSpec:
    return ScenarioSpec(run, summary, DEFAULTS[key])


SCENARIOS: dict[str, ScenarioSpec] = {
    "colombo_circle": _spec(colombo_circle, "Colombo V Case A: circles, 250 Hz, cameras",
                            "colombo_circle"),
    "colombo_square": _spec(colombo_square, "Colombo V Case B: squares, sharp turns",
                            "colombo_square"),
    "colombo_natural": _spec(colombo_natural, "Colombo V Fig. 12: natural path, stops",
                             "colombo_natural"),
    **{f"basso_test{i}": _spec(basso_test(i),
                               f"Basso IV Table I test {i}: {BASSO_TABLE[i][2]:.0f} m "
                               f"{BASSO_TABLE[i][1]}, user {BASSO_TABLE[i][0]}", "basso")
       for i in range(1, 7)},
    "tarrio_circle": _spec(tarrio_circle, "Tarrio IV: 9 anchors, circle r=8 m, RSS 2 s",
                           "tarrio_circle"),
    "tarrio_office": _spec(tarrio_office, "Tarrio V: 100 m^2 office, 9 anchors",
                           "tarrio_office"),
    "inderst_ring": _spec(inderst_ring, "Inderst 6.3.2: 500 m ring corridor, 9 RFID tags",
                          "inderst_ring"),
    "inderst_multifloor": _spec(inderst_multifloor,
                                "Inderst 6.3.1: ~270 m multi-floor path with stairs",
                                "inderst_multifloor"),
    "inderst_two_users": _spec(inderst_two_users,
                               "Inderst 6.3.1: ~305 m, users A (stop-turn) / B",
                               "inderst_two_users"),
    "inderst_wsn_random": _spec(inderst_wsn_random,
                                "Inderst 6.4: 50 nodes, unit square, radius 0.2",
                                "inderst_wsn_random"),
    "inderst_wsn_building": _spec(inderst_wsn_building,
                                  "Inderst 6.4: 12-node building network, ~5 m range",
                                  "inderst_wsn_building"),
    "office_random_walk": _spec(office_random_walk,
                                "random office walk with all infrastructure",
                                "office_random_walk"),
}


def run_scenario(name: str, seed: int = 0, **options: Any) -> SimulationResult:
    """Run a registered scenario by name."""
    if name not in SCENARIOS:
        raise InputError(f"unknown scenario {name!r}", where="scenario",
                         expected="one of " + ", ".join(SCENARIOS))
    return SCENARIOS[name].run(seed, **options)
