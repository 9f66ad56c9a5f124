"""Simulated hybrid mission: rescuers and a robot entering a floor with dropped range nodes.

``inderst_hybrid_mission`` (Inderst Ch. 3, 5, 6): a 60x30 m office floor (a 3 m ring corridor and
a middle corridor around two blocks of offices whose walls block the radio line of sight), RFID
tags with location messages (``tag_layout``: ``doors``, the default, has two tags at the entrance
corner and one at each office door of the blocks' walls, ``door_spacing_m`` apart, 2.2 m up the
wall, lobe into the corridor, bearings through the door; ``entrance``: the two corner tags only;
:func:`mission_tags`), and ``n_nodes`` range nodes dropped at random in the corridors without
positions. ``n_rescuers`` rescuers with a waist IMU and a shoulder RFID reader enter one after
the other (``stagger_s`` apart) from the entrance and walk random routes through the corridors
(never through a door: the door tags are read from the corridor), ranging to every node within
``max_range_m`` (Gaussian noise ``range_sigma_m`` plus ``range_sigma_fraction`` of the distance,
exponential NLOS bias behind walls, dropouts, failed nodes never answer); one magnetic
environment (15 random disturbances) for the floor, the same field for every rescuer. With
``peer_ranges`` the agents also range to each other (:mod:`hrtls.sim.peers`: node id = the other
agent's name, ``peer_rate_hz``, ``peer_max_range_m``). With ``node_ranges`` the alive nodes range
each other (:mod:`hrtls.sim.node_links`, ``node_range_rate_hz``): :attr:`Mission.network_ranges`.

The agents' sessions hold only what an agent knows (start pose at the entrance, the tags'
location messages, ranges to node ids); the nodes' true positions are in :class:`Mission` apart,
for scoring only. ``n_robots`` robots (default one) enter ``stagger_s / 2`` after the first
rescuer and drive random corridor routes at about 0.5 m/s; a robot's session holds its wheel
odometry poses (:func:`hrtls.sim.team.odometry_poses`, 5 Hz) and its ranges to the nodes (the
same radio model; no tag reader), tracked by :class:`hrtls.mission.robot.RobotTracker`. With
``robot_driver="planner"`` the robots are instead driven in closed loop by the way-point planner
on the mission tracker's estimates (:mod:`hrtls.sim.planner_loop`; the rescuers' walks are
unchanged). With ``rescuer_driver="planner"`` the rescuers walk, leg by leg, to the way points
the planner picks from their trackers' estimates (:mod:`hrtls.sim.rescuer_loop`; robots then on
random routes; inter-agent ranges are added after the loop, which does not see them).

``n_floors = 2`` (default 1): the issue's two-floor building (:mod:`hrtls.sim.mission_floors`):
floor 1 repeats the corridors 3.3 m up, a stairwell at the north-east corner joins them; nodes
alternate between the floors (``N1`` floor 0, ``N2`` floor 1, ...), every tag is repeated on
floor 1 (id suffix ``F1``, ``floor = 1``); each rescuer walks floor 0, climbs, walks floor 1
(about half come down again) and carries a barometer (:func:`hrtls.sim.barometer.with_barometer`);
the slab blocks the radio (ranges only to the nodes of the agent's floor); robots stay on floor
0. :attr:`Mission.node_floor` holds each node's floor (scoring only). Not with planner-driven
rescuers or peer ranges.

:func:`write_mission_result` saves a mission as a mission folder (:mod:`hrtls.io.mission`): the
agents' sessions with their truth tables and the simulator's extras, ``network.json`` (node ids),
the tags in ``landmarks.json``, the ranges between nodes in ``network_ranges.csv`` (with
``node_ranges``) and the node positions in ``network_truth.json`` (scoring only).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import Point, box
from shapely.ops import unary_union

from hrtls.data import Session
from hrtls.data.observations import GroundTruth
from hrtls.data.results import Activity, StepEvents
from hrtls.data.session import SessionMeta, StartPose
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.sim.devices import get_device
from hrtls.sim.infrastructure import RangeModel, RfidTag, TrackSample, range_measurements
from hrtls.sim.magnetic import MagneticEnvironment, random_anomalies
from hrtls.sim.mission_floors import (
    FLOOR_HEIGHT_M,
    STAIR_MOTION,
    floor_tags,
    node_floors,
    slab_ranges,
    spread_nodes,
    two_floor_walk,
)
from hrtls.sim.motion_truth import MotionTruth, random_floorplan_walk, simulate_motion
from hrtls.sim.node_links import node_network_ranges
from hrtls.sim.peers import peer_ranges
from hrtls.sim.person import Infrastructure, simulate_person
from hrtls.sim.scenario_options import scenario_rngs
from hrtls.sim.simulation_result import SimulationResult
from hrtls.sim.team import ROBOT_RATE_HZ, odometry_poses

FloatArray = NDArray[np.float64]

CORRIDORS = (box(0, 0, 60, 3), box(0, 27, 60, 30), box(0, 0, 3, 30), box(57, 0, 60, 30),
             box(28.5, 0, 31.5, 30))
"""The floor's corridors, one box each (they overlap where they cross)."""
FREE_SPACE = unary_union(CORRIDORS)
"""Corridors of the floor (the rescuers walk here; nodes are dropped here)."""
ROOM_BLOCKS: tuple[tuple[float, float, float, float], ...] = ((3.0, 3.0, 28.5, 27.0),
                                                               (31.5, 3.0, 57.0, 27.0))
"""The two blocks of offices (x0, y0, x1, y1); every side faces a corridor."""
ROOMS = unary_union([box(*b) for b in ROOM_BLOCKS]).boundary
"""Room walls (radio line of sight through them is NLOS)."""
ENTRANCE_XY = (1.5, 1.5)
TAG_HEIGHT_M = 2.2
RESCUER_PREDICTION: dict[str, float] = {"q_along": 0.04, "sigma_heading_increment_rad": 0.02}
"""The ``[prediction]`` noise of the tracker whose estimate the planner-driven rescuers follow
(:func:`hrtls.sim.rescuer_loop.drive_rescuers`; the recordings depend on it). The study's and
the service's rescuers run the ``rescue-mission`` preset: a larger ``q_along``, the default
heading increment, the magnetic offset's error shared (``offset_model = "consider"``)."""


@dataclass(frozen=True, kw_only=True)
class MissionOptions:
    """Options of :func:`inderst_hybrid_mission` (lengths m, times s)."""

    n_rescuers: int = 3
    n_robots: int = 1
    n_nodes: int = 40
    walk_s: float = 300.0
    stagger_s: float = 60.0
    range_sigma_m: float = 0.1
    range_sigma_fraction: float = 0.0
    """Range noise proportional to the distance (0.02: 2 %), in variance added to the above."""
    max_range_m: float = 10.0
    nlos_bias_mean_m: float = 1.0
    node_failure_fraction: float = 0.0
    robot_driver: str = "random"
    """``random``: fixed random corridor routes; ``planner``: driven in closed loop by the
    way-point planner on the mission tracker's estimates (:mod:`hrtls.sim.planner_loop`)."""
    rescuer_driver: str = "random"
    """``random``: pre-generated random corridor routes; ``planner``: each rescuer walks to the
    way points the planner picks from the mission tracker's estimates, leg by leg
    (:mod:`hrtls.sim.rescuer_loop`)."""
    peer_ranges: bool = False
    """Agents range to each other too (:mod:`hrtls.sim.peers`, the same radio model)."""
    peer_max_range_m: float = 10.0
    peer_rate_hz: float = 1.0
    tag_layout: str = "doors"
    """``entrance``: the two tags at the entrance corner; ``doors``: those plus one tag at each
    office door of the room blocks' walls (:func:`mission_tags`)."""
    door_spacing_m: float = 12.0
    """Distance between doors along a wall (every other door of a 6 m office module)."""
    node_ranges: bool = False
    """The dropped nodes range each other (:mod:`hrtls.sim.node_links`: same floor, within
    ``max_range_m``, the agents' radio model): :attr:`Mission.network_ranges`."""
    node_range_rate_hz: float = 0.2
    """Ranging attempts per pair of nodes per second (a UWB node sharing its air time with
    its neighbours and the agents)."""
    n_floors: int = 1
    """1: one floor; 2: the two-floor building of :mod:`hrtls.sim.mission_floors` (nodes
    alternate between the floors, tags on both, rescuers climb the stairs, robots stay on
    floor 0, rescuers carry a barometer)."""

    def __post_init__(self) -> None:
        if self.n_floors not in (1, 2):
            raise InputError(f"n_floors = {self.n_floors}", where="MissionOptions",
                             expected="1 or 2")
        if self.n_floors > 1 and (self.rescuer_driver != "random" or self.peer_ranges):
            raise InputError("n_floors = 2 with planner-driven rescuers or peer ranges",
                             where="MissionOptions",
                             expected="random rescuer routes and no peer ranges on two floors")
        if self.tag_layout not in ("entrance", "doors"):
            raise InputError(f"tag_layout = {self.tag_layout!r}", where="MissionOptions",
                             expected="entrance or doors")
        if not self.door_spacing_m > 0.0:
            raise InputError(f"door_spacing_m = {self.door_spacing_m}", where="MissionOptions",
                             expected="> 0 m")
        if self.robot_driver not in ("random", "planner"):
            raise InputError(f"robot_driver = {self.robot_driver!r}", where="MissionOptions",
                             expected="random or planner")
        if self.rescuer_driver not in ("random", "planner"):
            raise InputError(f"rescuer_driver = {self.rescuer_driver!r}", where="MissionOptions",
                             expected="random or planner")
        if self.rescuer_driver == "planner" and self.robot_driver == "planner" and self.n_robots:
            raise InputError("rescuer_driver = planner with robot_driver = planner",
                             where="MissionOptions",
                             expected="at most one planner-driven kind of agent (robots then "
                                      "on random routes)")
        if self.n_robots < 0:
            raise InputError(f"{self.n_robots} robots", where="MissionOptions", expected=">= 0")
        if self.n_rescuers < 1 or self.n_nodes < 1:
            raise InputError(f"{self.n_rescuers} rescuers, {self.n_nodes} nodes",
                             where="MissionOptions", expected=">= 1 each")
        if not (0.0 <= self.range_sigma_fraction < 1.0 and self.range_sigma_m >= 0.0):
            raise InputError(f"range_sigma_m = {self.range_sigma_m}, range_sigma_fraction = "
                             f"{self.range_sigma_fraction}", where="MissionOptions",
                             expected="sigma >= 0 m and a fraction in [0, 1)")
        if not (self.peer_rate_hz > 0 and self.peer_max_range_m > 0):
            raise InputError(f"peer_rate_hz = {self.peer_rate_hz}, peer_max_range_m = "
                             f"{self.peer_max_range_m}", where="MissionOptions", expected="> 0")
        if not (np.isfinite(self.node_range_rate_hz) and self.node_range_rate_hz > 0):
            raise InputError(f"node_range_rate_hz = {self.node_range_rate_hz}",
                             where="MissionOptions", expected="> 0 Hz")
        if not 0.0 <= self.node_failure_fraction < 1.0:
            raise InputError(f"node_failure_fraction = {self.node_failure_fraction}",
                             where="MissionOptions", expected="in [0, 1)")


@dataclass(frozen=True, eq=False)
class Mission:
    """Agents' sessions (what they know) and the truth kept apart for scoring."""

    agents: dict[str, Session]
    simulations: dict[str, SimulationResult]
    node_truth_m: dict[str, FloatArray]
    options: MissionOptions
    scenario: str = "inderst_hybrid_mission"
    seed: int = 0
    kinds: dict[str, Literal["rescuer", "robot"]] = dataclasses.field(default_factory=dict)
    """Agent kind by name (``rescuer`` when missing)."""
    node_floor: dict[str, int] = dataclasses.field(default_factory=dict)
    """True floor of each node (scoring only; 0 when missing)."""
    network_ranges: NetworkRanges = dataclasses.field(default_factory=NetworkRanges.empty)
    """Ranges between the dropped nodes (``node_ranges``; an input of the estimator)."""


def _drop_nodes(rng: np.random.Generator, n: int) -> dict[str, tuple[float, float, float]]:
    x0, y0, x1, y1 = FREE_SPACE.bounds
    out: dict[str, tuple[float, float, float]] = {}
    while len(out) < n:
        x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
        if FREE_SPACE.contains(Point(x, y)):
            out[f"N{len(out) + 1}"] = (float(x), float(y), 0.5)
    return out


def _door_offsets(length_m: float, spacing_m: float) -> FloatArray:
    """Doors ``spacing_m`` apart along a wall of ``length_m``, centred (one when it is shorter)."""
    n = max(1, int(np.floor(length_m / spacing_m)))
    return np.asarray((length_m - (n - 1) * spacing_m) / 2.0 + spacing_m * np.arange(n),
                      dtype=np.float64)


def mission_tags(*, layout: str, door_spacing_m: float) -> list[RfidTag]:
    """The floor's RFID tags with their location messages (floor 0, 2.2 m up the wall).

    ``entrance``: T1 and T2 at the entrance corner. ``doors``: also one tag ``D<k>`` at each
    door of the room blocks' walls, ``door_spacing_m`` apart along each wall (centred on it),
    its lobe facing the corridor perpendicular to the wall, the bearings those of the way
    through the door (into the room and out).
    """
    tags = [RfidTag(id="T1", position=(1.5, 0.2, TAG_HEIGHT_M), lobe_orientation_rad=np.pi / 2,
                    floor=0),
            RfidTag(id="T2", position=(0.2, 1.5, TAG_HEIGHT_M), lobe_orientation_rad=0.0,
                    floor=0)]
    if layout == "entrance":
        return tags
    if layout != "doors":
        raise InputError(f"tag layout {layout!r}", where="mission_tags",
                         expected="entrance or doors")
    for x0, y0, x1, y1 in ROOM_BLOCKS:
        # (start, direction along the wall, length, lobe into the corridor)
        walls = [((x0, y0), (1.0, 0.0), x1 - x0, -np.pi / 2),
                 ((x0, y1), (1.0, 0.0), x1 - x0, np.pi / 2),
                 ((x0, y0), (0.0, 1.0), y1 - y0, np.pi),
                 ((x1, y0), (0.0, 1.0), y1 - y0, 0.0)]
        for (sx, sy), (dx, dy), length, lobe in walls:
            for u in _door_offsets(length, door_spacing_m):
                out = float(wrap_angle(lobe))
                xy = (float(sx + dx * u), float(sy + dy * u))
                tags.append(RfidTag(
                    id=f"D{len(tags) - 1}", position=(*xy, TAG_HEIGHT_M),
                    lobe_orientation_rad=out, floor=0,
                    bearings_rad=(float(wrap_angle(lobe + np.pi)), out)))
    return tags


def inderst_hybrid_mission(seed: int, options: MissionOptions | None = None) -> Mission:
    """Rescuers enter an office floor with tags at the doors and range nodes without positions.

    See the module doc.
    """
    o = options or MissionOptions()
    r = scenario_rngs(seed)
    nodes = _drop_nodes(r[7], o.n_nodes)
    if o.n_floors > 1:
        nodes = spread_nodes(nodes, o.n_floors)
    alive = {k: v for k, v in nodes.items() if r[7].random() >= o.node_failure_fraction}
    tags = floor_tags(mission_tags(layout=o.tag_layout, door_spacing_m=o.door_spacing_m),
                      o.n_floors)
    sites = np.column_stack([r[7].uniform(0, 60, 15), r[7].uniform(0, 30, 15), np.full(15, 0.8)])
    model = RangeModel(rate_hz=1.0, sigma_m=o.range_sigma_m,
                       sigma_fraction=o.range_sigma_fraction, max_range_m=o.max_range_m,
                       nlos_bias_mean_m=o.nlos_bias_mean_m, walls=ROOMS)
    if o.rescuer_driver == "planner":
        return _driven_team(seed, o, nodes, alive, model, tags, r[7], sites)
    agents: dict[str, Session] = {}
    sims: dict[str, SimulationResult] = {}
    magnetic = MagneticEnvironment(anomalies=random_anomalies(r[7], sites))  # one building
    for i in range(o.n_rescuers):
        rr = scenario_rngs(seed * 1000 + 17 * (i + 1))
        if o.n_floors > 1:
            agents[f"R{i + 1}"], sims[f"R{i + 1}"] = _climbing_rescuer(
                seed, i, o, rr, magnetic, Infrastructure(tags=tags, nodes=alive,
                                                         range_model=model))
            continue
        wps = random_floorplan_walk(FREE_SPACE, rr[0], distance_m=o.walk_s * 1.15,
                                    start=ENTRANCE_XY, stop_probability=0.1,
                                    stop_range_s=(2.0, 8.0), min_leg_m=3.0)
        sim = simulate_person(
            "inderst_hybrid_mission", seed, {"rescuer": i}, wps, device=get_device("inemo"),
            magnetic=magnetic,
            infra=Infrastructure(tags=tags, nodes=alive, range_model=model),
            description=f"hybrid mission, rescuer {i + 1} of {o.n_rescuers}",
            start_pause_s=3.0 + i * o.stagger_s, rngs=rr)
        known = {k: lm for k, lm in sim.session.landmarks.items() if lm.kind != "node"}
        agents[f"R{i + 1}"] = dataclasses.replace(sim.session, landmarks=known)
        sims[f"R{i + 1}"] = sim
    kinds: dict[str, Literal["rescuer", "robot"]] = dict.fromkeys(agents, "rescuer")
    rescuers = dict(agents)
    alive_all = alive
    alive = {k: v for k, v in alive.items() if v[2] < FLOOR_HEIGHT_M / 2}   # robots: floor 0
    for i in range(o.n_robots):
        name = f"B{i + 1}"
        if o.robot_driver == "planner":
            agents[name], sims[name] = _driven_robot(seed, i, o, alive, model, rescuers)
        else:
            agents[name], sims[name] = _robot(seed, i, o, alive, model)
        kinds[name] = "robot"
    return _finish(seed, o, nodes, model, agents, sims, kinds, alive_all)


def _finish(seed: int, o: MissionOptions, nodes: dict[str, tuple[float, float, float]],
            model: RangeModel, agents: dict[str, Session], sims: dict[str, SimulationResult],
            kinds: dict[str, Literal["rescuer", "robot"]],
            alive: dict[str, tuple[float, float, float]]) -> Mission:
    """The mission, with the inter-agent and node-node ranges when asked (module doc)."""
    if o.peer_ranges:
        peer_model = dataclasses.replace(model, rate_hz=o.peer_rate_hz,
                                         max_range_m=o.peer_max_range_m)
        agents = peer_ranges(agents, peer_model, scenario_rngs(seed * 1000 + 999)[6])
        sims = {k: dataclasses.replace(v, session=agents[k]) for k, v in sims.items()}
    truth = {k: np.asarray(v[:2], dtype=np.float64) for k, v in nodes.items()}
    floors = node_floors(nodes)
    network = NetworkRanges.empty()
    if o.node_ranges:
        spans = [s.truth.t[[0, -1]] for s in agents.values() if s.truth is not None]
        network = node_network_ranges(
            alive, model, rate_hz=o.node_range_rate_hz, t0_s=float(min(a for a, _ in spans)),
            t1_s=float(max(b for _, b in spans)), floor_height_m=FLOOR_HEIGHT_M,
            rng=scenario_rngs(seed * 1000 + 998)[6])
    return Mission(agents=agents, simulations=sims, node_truth_m=truth, options=o, seed=seed,
                   kinds=kinds, node_floor=floors, network_ranges=network)


def _climbing_rescuer(seed: int, i: int, o: MissionOptions, rr: list[np.random.Generator],
                      magnetic: MagneticEnvironment, infra: Infrastructure
                      ) -> tuple[Session, SimulationResult]:
    """Rescuer ``i`` of the two-floor building (:mod:`hrtls.sim.mission_floors`)."""
    from hrtls.sim.barometer import with_barometer
    from hrtls.sim.robot_driver import CorridorRouter, DriverParams

    router = CorridorRouter(FREE_SPACE, grid_m=DriverParams().grid_m,
                            margin_m=DriverParams().margin_m)
    wps = two_floor_walk(FREE_SPACE, router, rr[0], distance_m=o.walk_s * 1.15,
                         start=ENTRANCE_XY)
    sim = simulate_person(
        "inderst_hybrid_mission", seed, {"rescuer": i}, wps, device=get_device("inemo"),
        motion_params=STAIR_MOTION, magnetic=magnetic,
        infra=dataclasses.replace(infra, nodes={}), floor_height_m=FLOOR_HEIGHT_M,
        description=f"hybrid mission, rescuer {i + 1} of {o.n_rescuers}, two floors",
        start_pause_s=3.0 + i * o.stagger_s, rngs=rr)
    assert sim.motion is not None and infra.range_model is not None
    ranges = slab_ranges(infra.nodes, infra.range_model, sim.motion, rr[6])
    sim = with_barometer(sim)
    known = {k: lm for k, lm in sim.session.landmarks.items() if lm.kind != "node"}
    session = sim.session.with_parts(ranges=ranges)
    session = dataclasses.replace(session, landmarks=known)
    return session, dataclasses.replace(sim, session=session)


def _driven_team(seed: int, o: MissionOptions, nodes: dict[str, tuple[float, float, float]],
                 alive: dict[str, tuple[float, float, float]], model: RangeModel,
                 tags: list[RfidTag], rng: np.random.Generator, sites: FloatArray) -> Mission:
    """Planner-driven rescuers (:mod:`hrtls.sim.rescuer_loop`) and robots on random routes."""
    from hrtls.pipeline.config import TrackerConfig
    from hrtls.sim.person_legs import WalkingPerson
    from hrtls.sim.rescuer_loop import drive_rescuers
    from hrtls.sim.robot_driver import CorridorRouter, DriverParams

    router = CorridorRouter(FREE_SPACE, grid_m=DriverParams().grid_m,
                            margin_m=DriverParams().margin_m)
    persons: dict[str, WalkingPerson] = {}
    magnetic = MagneticEnvironment(anomalies=random_anomalies(rng, sites))  # one building
    for i in range(o.n_rescuers):
        name = f"R{i + 1}"
        persons[name] = WalkingPerson(
            name=name, seed=seed, device=get_device("inemo"), router=router,
            start_xy_m=np.array(ENTRANCE_XY), start_heading_rad=np.pi / 2,
            infra=Infrastructure(tags=tags, nodes=alive, range_model=model),
            magnetic=magnetic,
            rngs=scenario_rngs(seed * 1000 + 17 * (i + 1)),
            source={"scenario": "inderst_hybrid_mission", "seed": seed,
                    "options": {"rescuer": i, "driver": "planner"}},
            description=f"hybrid mission, rescuer {i + 1} of {o.n_rescuers} (planner driver)")
    robots = {f"B{i + 1}": _robot(seed, i, o, alive, model) for i in range(o.n_robots)}
    enter = {k: 3.0 + i * o.stagger_s for i, k in enumerate(persons)}
    drive_rescuers(persons, {k: s for k, (s, _) in robots.items()},
                   kinds=dict.fromkeys(robots, "robot"), enter_s=enter,
                   end_s={k: t + o.walk_s for k, t in enter.items()},
                   config=TrackerConfig.model_validate({"prediction": RESCUER_PREDICTION}))
    sims = {k: p.result(scenario="inderst_hybrid_mission", seed=seed,
                        options={"rescuer": i, "driver": "planner"})
            for i, (k, p) in enumerate(persons.items())}
    sims.update({k: sim for k, (_, sim) in robots.items()})
    agents = {k: v.session for k, v in sims.items()}
    kinds: dict[str, Literal["rescuer", "robot"]] = {
        **dict.fromkeys(persons, "rescuer"), **dict.fromkeys(robots, "robot")}
    return _finish(seed, o, nodes, model, agents, sims, kinds, alive)


def _robot(seed: int, i: int, o: MissionOptions, nodes: dict[str, tuple[float, float, float]],
           model: RangeModel) -> tuple[Session, SimulationResult]:
    """Robot ``i``: a corridor route at about 0.5 m/s, odometry poses and ranges (module doc)."""
    rr = scenario_rngs(seed * 1000 + 500 + 17 * (i + 1))
    wps = random_floorplan_walk(FREE_SPACE, rr[0], distance_m=o.walk_s * 0.5, start=ENTRANCE_XY,
                                speed_range_m_s=(0.4, 0.6), stop_probability=0.05,
                                stop_range_s=(2.0, 5.0), min_leg_m=3.0)
    motion = simulate_motion(wps, rate_hz=ROBOT_RATE_HZ,
                             start_pause_s=3.0 + (i + 0.5) * o.stagger_s)
    track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading, speed=motion.speed)
    meta = SessionMeta(start_pose=StartPose(x=float(motion.xyz[0, 0]), y=float(motion.xyz[0, 1]),
                                            z=0.0, heading=float(motion.heading[0]),
                                            sigma_xy_m=0.1, sigma_heading_rad=0.02),
                       source={"format": "hrtls-sim", "scenario": "inderst_hybrid_mission",
                               "seed": seed, "robot": i},
                       notes=["robot wheel odometry poses (fixes.csv) and ranges to nodes"])
    session = Session(meta=meta, fixes=odometry_poses(motion.t, motion.xyz, rr[1]),
                      ranges=range_measurements(nodes, model, track, rr[6]),
                      truth=GroundTruth(motion.t, motion.xyz, motion.heading))
    z = np.zeros(0)
    moving = np.where(motion.speed > 0.05, int(Activity.WALKING), int(Activity.STANDING))
    return session, SimulationResult(
        scenario="inderst_hybrid_mission", seed=seed, options={"robot": i}, session=session,
        true_steps=StepEvents(z, z, z, z, z, np.zeros(0, dtype=np.int64), z, z, z),
        activity_t=motion.t, activity=moving.astype(np.int64), motion=motion,
        description=f"hybrid mission, robot {i + 1} of {o.n_robots} (wheel odometry)")


def _robot_meta(seed: int, i: int, xy: tuple[float, float], heading_rad: float) -> SessionMeta:
    return SessionMeta(start_pose=StartPose(x=xy[0], y=xy[1], z=0.0, heading=heading_rad,
                                            sigma_xy_m=0.1, sigma_heading_rad=0.02),
                       source={"format": "hrtls-sim", "scenario": "inderst_hybrid_mission",
                               "seed": seed, "robot": i},
                       notes=["robot wheel odometry poses (fixes.csv) and ranges to nodes"])


def _robot_result(seed: int, i: int, o: MissionOptions, session: Session,
                  motion: MotionTruth | None) -> SimulationResult:
    assert session.truth is not None
    t = session.truth.t
    speed = np.concatenate([[0.0], np.hypot(*np.diff(session.truth.xyz[:, :2], axis=0).T)
                            / np.maximum(np.diff(t), 1e-9)])
    z = np.zeros(0)
    moving = np.where(speed > 0.05, int(Activity.WALKING), int(Activity.STANDING))
    return SimulationResult(
        scenario="inderst_hybrid_mission", seed=seed, options={"robot": i}, session=session,
        true_steps=StepEvents(z, z, z, z, z, np.zeros(0, dtype=np.int64), z, z, z),
        activity_t=t, activity=moving.astype(np.int64), motion=motion,
        description=f"hybrid mission, robot {i + 1} of {o.n_robots} (wheel odometry, "
                    f"{o.robot_driver} driver)")


def _driven_robot(seed: int, i: int, o: MissionOptions,
                  nodes: dict[str, tuple[float, float, float]], model: RangeModel,
                  rescuers: dict[str, Session]) -> tuple[Session, SimulationResult]:
    """Robot ``i`` driven by the planner in closed loop (:mod:`hrtls.sim.planner_loop`)."""
    from hrtls.sim.planner_loop import drive_robot
    from hrtls.sim.robot_driver import CorridorRouter, DrivenRobot, DriverParams

    rr = scenario_rngs(seed * 1000 + 500 + 17 * (i + 1))
    prm = DriverParams()
    t0 = 3.0 + (i + 0.5) * o.stagger_s
    robot = DrivenRobot(meta=_robot_meta(seed, i, ENTRANCE_XY, np.pi / 2),
                        start_xy_m=np.array(ENTRANCE_XY), start_t_s=t0, nodes=nodes,
                        model=model, rng=rr[1],
                        router=CorridorRouter(FREE_SPACE, grid_m=prm.grid_m,
                                              margin_m=prm.margin_m),
                        params=prm)
    out = drive_robot(f"B{i + 1}", robot, rescuers, end_s=t0 + o.walk_s)
    return out.session, _robot_result(seed, i, o, out.session, None)


def mission_summary(mission: Mission) -> dict[str, Any]:
    """Counts of the mission (for tables)."""
    return {"agents": len(mission.agents), "nodes": len(mission.node_truth_m),
            "ranges": {k: 0 if s.ranges is None else len(s.ranges.t)
                       for k, s in mission.agents.items()}}


MISSIONS: dict[str, Callable[[int, MissionOptions | None], Mission]] = {
    "inderst_hybrid_mission": inderst_hybrid_mission}
"""Simulated missions by name (``hrtls simulate NAME`` writes a mission folder for these)."""


def run_mission(name: str, seed: int, **options: Any) -> Mission:
    """The mission ``name`` of seed ``seed``; ``options`` are fields of :class:`MissionOptions`."""
    if name not in MISSIONS:
        raise InputError(f"unknown mission {name!r}", where="scenario",
                         expected="one of " + ", ".join(MISSIONS))
    fields = {f.name: f for f in dataclasses.fields(MissionOptions)}
    for key, value in options.items():
        if key not in fields:
            raise InputError(f"unknown option {key!r}", where=f"{name} options",
                             expected="one of " + ", ".join(fields))
        default = fields[key].default
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise InputError(f"{key} = {value!r}", where=f"{name} options",
                                 expected=f"true or false (default {default})")
            continue
        if isinstance(default, int | float) and (isinstance(value, bool)
                                                 or not isinstance(value, int | float)):
            raise InputError(f"{key} = {value!r}", where=f"{name} options",
                             expected=f"a number (default {default})")
        if isinstance(default, int) and not isinstance(value, int):
            raise InputError(f"{key} = {value!r}", where=f"{name} options",
                             expected=f"an integer (default {default})")
    return MISSIONS[name](seed, MissionOptions(**options))


def write_mission_result(mission: Mission, path: Path | str, *, overwrite: bool = False) -> Path:
    """Save ``mission`` as a mission folder (see the module doc); returns the folder."""
    from hrtls.io.mission import write_mission, write_network_ranges, write_network_truth
    from hrtls.sim.scenarios import write_extras

    landmarks = {k: lm for s in mission.agents.values() for k, lm in s.landmarks.items()}
    root = write_mission(
        path, agents=[(k, mission.kinds.get(k, "rescuer"), s) for k, s in mission.agents.items()],
        nodes=list(mission.node_truth_m), landmarks=landmarks, name=mission.scenario,
        source={"simulator": mission.scenario, "seed": mission.seed,
                "options": dataclasses.asdict(mission.options)},
        notes=["simulated: ground truth in each agent's truth.csv and in network_truth.json"],
        overwrite=overwrite)
    for k, sim in mission.simulations.items():
        write_extras(sim, root / "agents" / k)
    write_network_truth(root, mission.node_truth_m)
    if len(mission.network_ranges):
        write_network_ranges(root, mission.network_ranges)
    return root
