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

import dataclasses
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation
from shapely.geometry import LineString, box
from shapely.ops import unary_union

from hrtls.data import (
    Activity,
    Checkpoints,
    GroundTruth,
    Landmark,
    Session,
    SessionMeta,
    StepEvents,
    activity_labels,
)
from hrtls.data.session import StartPose, UserProfile
from hrtls.errors import InputError
from hrtls.frames import quat_from_rotation, quat_from_rotvec, quat_multiply
from hrtls.sim.barometer import with_barometer
from hrtls.sim.devices import DeviceModel, get_device
from hrtls.sim.gait_model import GaitParams, fill_step_extremes, simulate_gait
from hrtls.sim.imu_model import BodyKinematics, SimulatedImu, body_kinematics, simulate_imu
from hrtls.sim.infrastructure import (
    CameraSystem,
    RangeModel,
    RfidReader,
    RfidTag,
    RssChannel,
    TrackSample,
    WsnDeployment,
    anchor_landmarks,
    camera_fixes,
    random_wsn,
    range_measurements,
    rfid_detections,
    rss_readings,
)
from hrtls.sim.magnetic import EarthField, MagneticEnvironment, random_anomalies
from hrtls.sim.motion_truth import (
    MotionParams,
    MotionTruth,
    Waypoint,
    circle_waypoints,
    random_floorplan_walk,
    simulate_motion,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class SimulationResult:
    """A simulated session with everything that is true about it.

    Attributes
    ----------
    scenario, seed, options: how it was made.
    session: the recording (with ``truth`` and, where the paper had them, ``checkpoints``).
    true_steps: true step events (heel strike to heel strike).
    activity_t, activity: per-sample true activity codes on the simulation grid.
    motion, kinematics, imu: internals (nominal motion, waist pose, device signals) or None.
    wsn: sensor-network deployment, or None.
    reference: the paper's numbers for this experiment (for comparison in reports).
    description: one line on what is simulated.
    hidden_truth: what the session does not tell an algorithm (true mounting, drawn sensor
        biases / scales / misalignments), written to ``scenario.json`` under ``"truth"``.
    """

    scenario: str
    seed: int
    options: dict[str, Any]
    session: Session
    true_steps: StepEvents
    activity_t: FloatArray
    activity: IntArray
    motion: MotionTruth | None = None
    kinematics: BodyKinematics | None = None
    imu: SimulatedImu | None = None
    wsn: WsnDeployment | None = None
    reference: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    hidden_truth: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------------------------
def _rngs(seed: int, n: int = 8) -> list[np.random.Generator]:
    """Independent generators: 0 path, 1 gait, 2 imu, 3 camera, 4 rss, 5 tags, 6 ranges, 7 misc."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)]


def mounting_quaternion(kind: str, rng: np.random.Generator) -> FloatArray:
    """Device -> body rotation for a placement: belt, pocket, rotated, or random."""
    if kind == "belt":
        return np.array([1.0, 0.0, 0.0, 0.0])
    if kind == "pocket":  # phone upright in a front pocket, screen facing forward
        return quat_from_rotation(Rotation.from_euler("ZYX", [90.0, 0.0, 90.0], degrees=True))
    if kind == "rotated":  # belt clip, phone turned 90 deg about its normal and tilted
        return quat_from_rotation(Rotation.from_euler("ZYX", [90.0, 15.0, -10.0], degrees=True))
    if kind == "random":
        return quat_from_rotation(Rotation.random(random_state=rng))
    raise InputError(f"placement {kind!r}", where="mounting",
                     expected="belt, pocket, rotated or random")


def checkpoint_passes(t: FloatArray, xyz: FloatArray, points: Mapping[str, Sequence[float]], *,
                      radius_m: float = 1.0) -> Checkpoints | None:
    """Times the track passes closest to each labelled point (one row per pass, sorted)."""
    rows: list[tuple[float, str, FloatArray]] = []
    for label, p in points.items():
        pp = np.asarray(p, dtype=np.float64)
        d = np.hypot(xyz[:, 0] - pp[0], xyz[:, 1] - pp[1]) + 10.0 * np.abs(xyz[:, 2] - pp[2])
        inside = d < radius_m
        if not np.any(inside):
            continue
        edges = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
        starts = np.flatnonzero(edges == 1)
        ends = np.flatnonzero(edges == -1)
        for a, b in zip(starts, ends, strict=True):
            k = a + int(np.argmin(d[a:b]))
            rows.append((float(t[k]), label, xyz[k]))
    if not rows:
        return None
    rows.sort(key=lambda r: r[0])
    return Checkpoints(np.array([r[0] for r in rows]), np.array([r[2] for r in rows]),
                       np.array([r[1] for r in rows]))


@dataclass(frozen=True, slots=True, kw_only=True)
class Infrastructure:
    """What the environment offers a passing person (all optional)."""

    camera: CameraSystem | None = None
    anchors: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    channel: RssChannel | None = None
    tags: list[RfidTag] = field(default_factory=list)
    reader: RfidReader = field(default_factory=RfidReader)
    nodes: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    range_model: RangeModel | None = None
    checkpoints: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    checkpoint_radius_m: float = 1.0


def simulate_person(name: str, seed: int, options: dict[str, Any], waypoints: list[Waypoint], *,
                    device: DeviceModel, gait: GaitParams | None = None,
                    motion_params: MotionParams | None = None, placement: str = "belt",
                    lever_arm_b: Sequence[float] = (0.0, 0.0, 0.0),
                    magnetic: MagneticEnvironment | None = None, with_gyro: bool = True,
                    with_mag: bool = True, with_orientation: bool = False,
                    with_pressure: bool = False, infra: Infrastructure | None = None,
                    floor_height_m: float = 3.0, user_height_m: float = 1.75,
                    reference: dict[str, Any] | None = None, description: str = "",
                    notes: Sequence[str] = (), start_pause_s: float = 3.0,
                    end_pause_s: float = 2.0, rngs: list[np.random.Generator] | None = None
                    ) -> SimulationResult:
    """Walk ``waypoints`` with a device and an infrastructure; assemble the session.

    With ``options["calibration"]`` the same person (same gait, device, placement, magnetic
    surroundings, anchors) walks the calibration course of :func:`calibration_waypoints`
    instead, with checkpoints at the leg ends and no other infrastructure.

    The session holds only what a user would know: the declared placement and, for a belt
    clip, its nominal mounting (the true one is off by a few degrees,
    :data:`BELT_TILT_SIGMA_RAD`), the user's height, no step-length model and no channel. The
    truth (gait law, mounting, channel, sensor errors) is in ``hidden_truth``.
    """
    r = rngs or _rngs(seed)
    # the person of this seed (also on its calibration course): its own generator
    gp = (gait or GaitParams()).drawn(np.random.default_rng([seed, PERSON_STREAM]))
    infra = infra or Infrastructure()
    if options.get("calibration"):
        waypoints, legs = calibration_waypoints(waypoints)
        infra = Infrastructure(anchors=infra.anchors, channel=infra.channel,
                               checkpoints=legs, checkpoint_radius_m=1.0)
        reference = {"calibration_of": name}
        description = f"calibration walk of the {name} person: {calibration_summary(waypoints)}"
        notes = ["checkpoints: the ends of the calibration legs (walks of known length)"]
    motion = simulate_motion(waypoints, rate_hz=device.rate_hz, params=motion_params,
                             start_pause_s=start_pause_s, end_pause_s=end_pause_s)
    gres = simulate_gait(motion, gp, r[1])
    kin = body_kinematics(motion, gres)
    q_declared = None if placement == "random" else mounting_quaternion(placement, r[7])
    q_bd = mounting_quaternion(placement, r[7]) if q_declared is None else quat_multiply(
        q_declared, quat_from_rotvec(r[7].normal(0.0, 1.0, 3) * BELT_TILT_SIGMA_RAD))
    sim = simulate_imu(kin, device, r[2], q_bd=q_bd, lever_arm_b=lever_arm_b,
                       magnetic=magnetic or MagneticEnvironment(), with_gyro=with_gyro,
                       with_mag=with_mag, with_orientation=with_orientation,
                       with_pressure=with_pressure)
    steps = fill_step_extremes(gres.steps, motion.t, sim.ideal.accel_n[:, 2])
    track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading, speed=motion.speed)
    fixes = camera_fixes(infra.camera, track, r[3]) if infra.camera is not None else None
    rss = (rss_readings(infra.anchors, infra.channel, track, r[4])
           if infra.channel is not None and infra.anchors else None)
    tags = rfid_detections(infra.tags, infra.reader, track, r[5]) if infra.tags else None
    ranges = (range_measurements(infra.nodes, infra.range_model, track, r[6])
              if infra.range_model is not None and infra.nodes else None)
    landmarks: dict[str, Landmark] = {}
    if infra.anchors:
        landmarks.update(anchor_landmarks(infra.anchors, kind="anchor"))
    for tag in infra.tags:
        landmarks[tag.id] = tag.landmark()
    if infra.nodes:
        landmarks.update(anchor_landmarks(infra.nodes, kind="node"))
    checkpoints = (checkpoint_passes(motion.t, motion.xyz, infra.checkpoints,
                                     radius_m=infra.checkpoint_radius_m)
                   if infra.checkpoints else None)
    truth = GroundTruth(motion.t, motion.xyz, motion.heading)
    meta = SessionMeta(
        start_pose=StartPose(x=float(motion.xyz[0, 0]), y=float(motion.xyz[0, 1]),
                             z=float(motion.xyz[0, 2]), heading=float(motion.heading[0]),
                             sigma_xy_m=0.1, sigma_heading_rad=0.05),
        placement=placement,
        # a phone put anywhere has an unknown mounting: only fixed placements declare one,
        # their nominal mounting
        mounting_q_bd=None if q_declared is None else (
            float(q_declared[0]), float(q_declared[1]), float(q_declared[2]),
            float(q_declared[3])),
        user=UserProfile(height_m=user_height_m),
        floor_height_m=floor_height_m,
        source={"format": "hrtls-sim", "scenario": name, "seed": seed, "device": device.name,
                "options": options},
        notes=[description, f"device: {device.description}", *notes],
    )
    session = Session(meta=meta, imu=sim.imu, pressure=sim.pressure,
                      orientation=sim.orientation, fixes=fixes, rss=rss, tags=tags,
                      ranges=ranges, landmarks=landmarks, truth=truth, checkpoints=checkpoints)
    return SimulationResult(scenario=name, seed=seed, options=options, session=session,
                            true_steps=steps, activity_t=motion.t, activity=motion.activity,
                            motion=motion, kinematics=kin, imu=sim, reference=reference or {},
                            description=description, hidden_truth={
                                "mounting_q_bd": q_bd.tolist(),
                                "gait": dataclasses.asdict(gp),
                                "channel": None if infra.channel is None
                                else dataclasses.asdict(infra.channel),
                                "lever_arm_b_m": [float(v) for v in lever_arm_b],
                                "device": device.name,
                                "sensor_errors": {k: v.to_dict()
                                                  for k, v in sim.realizations.items()}})


PERSON_STREAM = 16
"""Generator key of the simulated person (``default_rng([seed, PERSON_STREAM])``)."""

BELT_TILT_SIGMA_RAD = float(np.deg2rad(2.0))
"""Per-axis standard deviation of a belt clip's true mounting about its nominal one, rad."""

CALIBRATION_LEG_M = 30.0
"""Length of each walking leg of a calibration course, m (running legs: 1.5 times)."""


def calibration_waypoints(waypoints: Sequence[Waypoint]
                          ) -> tuple[list[Waypoint], dict[str, tuple[float, float, float]]]:
    """A calibration course for the person who walks ``waypoints``, and its leg ends.

    Straight legs of :data:`CALIBRATION_LEG_M`, back and forth from the first waypoint with a
    3 m offset between legs and a 3 s stop at each end (where the user marks the time), at four
    walking speeds spread over the scenario's walking speeds (10 % below the slowest to 10 %
    above the fastest) and, when the scenario runs, two running legs at its running speeds.
    """
    walk = [w.speed_m_s for w in waypoints[1:] if not w.run] or [1.2]
    run = [w.speed_m_s for w in waypoints[1:] if w.run]
    legs = [(float(v), False) for v in np.linspace(0.9 * min(walk), 1.1 * max(walk), 4)]
    if run:
        legs += [(float(min(run)), True), (float(max(run)), True)]
    x0, y0, z0 = waypoints[0].x, waypoints[0].y, waypoints[0].z
    wps = [Waypoint(x=x0, y=y0, z=z0)]
    ends: dict[str, tuple[float, float, float]] = {}
    for i, (v, running) in enumerate(legs):
        length = CALIBRATION_LEG_M * (1.5 if running else 1.0)
        x = x0 + (length if i % 2 == 0 else 0.0)
        y = y0 + 3.0 * (i + 1)
        wps.append(Waypoint(x=x, y=y, z=z0, speed_m_s=v, run=running, stop_s=3.0,
                            corner_radius_m=0.0))
        ends[f"L{i + 1}"] = (x, y, z0)
    return wps, ends


def calibration_summary(waypoints: Sequence[Waypoint]) -> str:
    """One line on a calibration course: its legs' speeds."""
    speeds = ", ".join(f"{w.speed_m_s:.2f}{' run' if w.run else ''}" for w in waypoints[1:])
    return f"{len(waypoints) - 1} straight legs with stops, speeds {speeds} m/s"


def _opt(options: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    defaults = {**defaults, "calibration": False}
    unknown = set(options) - set(defaults)
    if unknown:
        raise InputError(f"unknown option(s) {sorted(unknown)}", where="scenario options",
                         expected="one of " + ", ".join(sorted(defaults)))
    out = dict(defaults)
    for k, v in options.items():
        out[k] = type(defaults[k])(v) if defaults[k] is not None and not isinstance(
            v, type(defaults[k])) else v
    return out


DEFAULTS: dict[str, dict[str, Any]] = {
    "colombo_circle": {"laps": 5, "total_m": 31.0, "speed_m_s": 0.0, "tp_s": 8.0},
    "colombo_square": {"laps": 5, "total_m": 40.0, "speed_m_s": 0.0, "tp_s": 8.0},
    "colombo_natural": {"distance_m": 35.0, "tp_s": 10.0},
    "basso": {"placement": "random", "device": "mpu6150_phone", "rate_hz": 50.0},
    "tarrio_circle": {"laps": 5.0, "speed_m_s": 1.0, "rss_period_s": 2.0,
                      "readings_per_period": 5},
    "tarrio_office": {"user": 1, "readings_per_period": 5},
    "inderst_ring": {"tags": "all", "distance_m": 500.0, "speed_m_s": 0.9},
    "inderst_multifloor": {"speed_m_s": 1.1, "pressure": True},
    "inderst_two_users": {"user": "A", "tags": True},
    "inderst_wsn_random": {"n_nodes": 50, "radius": 0.2, "n_anchors": 4,
                           "distance_sigma": 0.005},
    "inderst_wsn_building": {"n_anchors": 3, "range_m": 5.0},
    "office_random_walk": {"duration_s": 600.0, "device": "mpu6150_phone"},
}
"""Options of each scenario and their defaults (``-O key=value`` on the command line)."""


# --------------------------------------------------------------------------------------------
# Colombo Sec. V: room with cameras
# --------------------------------------------------------------------------------------------
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
    o = _opt(options, DEFAULTS["colombo_circle"])
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["colombo_square"])
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["colombo_natural"])
    r = _rngs(seed)
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


# --------------------------------------------------------------------------------------------
# Basso Sec. IV: long outdoor walks and walk+run paths, phone at the waist in any orientation
# --------------------------------------------------------------------------------------------
_BASSO_TABLE = {1: ("A", "W", 433.0, 0.005, 0.01), 2: ("B", "W", 399.0, 0.01, 0.021),
                3: ("B", "W", 551.0, 0.009, 0.009), 4: ("A", "W", 578.0, 0.015, 0.016),
                5: ("B", "W+R", 1124.0, 0.005, 0.016), 6: ("A", "W+R", 3262.0, 0.003, 0.014)}
_BASSO_USERS = {"A": GaitParams(step_a_m=0.36, step_b_s=0.26, run_a_m=0.60, run_b_s=0.20),
                "B": GaitParams(step_a_m=0.30, step_b_s=0.25, run_a_m=0.52, run_b_s=0.19,
                                pelvis_yaw_rad=0.09)}


def _basso(test: int, seed: int, options: Mapping[str, Any]) -> SimulationResult:
    o = _opt(options, DEFAULTS["basso"])
    user, pace, length, len_err, pos_err = _BASSO_TABLE[test]
    r = _rngs(seed)
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


def _basso_factory(test: int) -> Callable[..., SimulationResult]:
    def run(seed: int, **options: Any) -> SimulationResult:
        return _basso(test, seed, options)

    run.__doc__ = f"Basso Table I test {test}."
    return run


# --------------------------------------------------------------------------------------------
# Tarrio Sec. IV (simulation) and Sec. V (office)
# --------------------------------------------------------------------------------------------
def tarrio_circle(seed: int, **options: Any) -> SimulationResult:
    """9 anchors on a grid over 400 m^2, circle of radius 8 m at 1 m/s, 50 Hz, RSS every 2 s."""
    o = _opt(options, DEFAULTS["tarrio_circle"])
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["tarrio_office"])
    user = int(o["user"])
    if user not in TARRIO_OFFICE_TABLE:
        raise InputError(f"user {user}", where="tarrio_office user", expected="1..8")
    r = _rngs(seed)
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


# --------------------------------------------------------------------------------------------
# Inderst Ch. 6
# --------------------------------------------------------------------------------------------
_RING_TAGS = {  # id: (x, y, lobe direction deg, set)
    "T1": (20.0, 0.05, 90.0, "corner"), "T2": (30.0, 1.95, -90.0, "corridor"),
    "T3": (39.95, 0.05, 135.0, "corner"), "T4": (38.05, 10.0, 180.0, "corridor"),
    "T5": (39.95, 19.95, -135.0, "corner"), "T6": (20.0, 18.05, -90.0, "corridor"),
    "T7": (0.05, 19.95, -45.0, "corner"), "T8": (1.95, 10.0, 0.0, "corridor"),
    "T9": (0.05, 0.05, 45.0, "corner")}


def inderst_ring(seed: int, **options: Any) -> SimulationResult:
    """Sec. 6.3.2: ~500 m penetration mission around a ring corridor with 9 RFID tags."""
    o = _opt(options, DEFAULTS["inderst_ring"])
    sets = {"all": set(_RING_TAGS), "no_tag5": set(_RING_TAGS) - {"T5"},
            "corners": {k for k, v in _RING_TAGS.items() if v[3] == "corner"},
            "corridor": {k for k, v in _RING_TAGS.items() if v[3] == "corridor"},
            "none": set()}
    if o["tags"] not in sets:
        raise InputError(f"tag set {o['tags']!r}", where="inderst_ring tags",
                         expected="all, no_tag5, corners, corridor or none")
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["inderst_multifloor"])
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["inderst_two_users"])
    user = str(o["user"]).upper()
    if user not in ("A", "B"):
        raise InputError(f"user {user!r}", where="inderst_two_users user", expected="A or B")
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["inderst_wsn_random"])
    r = _rngs(seed)
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
    o = _opt(options, DEFAULTS["inderst_wsn_building"])
    r = _rngs(seed)
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


# --------------------------------------------------------------------------------------------
# A long office walk with every kind of infrastructure (benchmark)
# --------------------------------------------------------------------------------------------
def office_random_walk(seed: int, **options: Any) -> SimulationResult:
    """Random natural walk in a 60x30 m office floor with cameras, beacons, tags and nodes."""
    o = _opt(options, DEFAULTS["office_random_walk"])
    r = _rngs(seed)
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
# Registry and writing
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
    **{f"basso_test{i}": _spec(_basso_factory(i),
                               f"Basso IV Table I test {i}: {_BASSO_TABLE[i][2]:.0f} m "
                               f"{_BASSO_TABLE[i][1]}, user {_BASSO_TABLE[i][0]}", "basso")
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


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def write_result(result: SimulationResult, path: Path | str, *, overwrite: bool = False
                 ) -> Path:
    """Write the session folder plus the truth extras (see the module docstring)."""
    from hrtls.io.session import write_session

    out = write_session(result.session, Path(path), overwrite=overwrite)
    write_extras(result, out)
    return out


def write_extras(result: SimulationResult, out: Path) -> None:
    """Write the truth extras of :func:`write_result` into the session folder ``out``."""
    from hrtls.io.tables import steps_table

    (out / "truth_steps.csv").write_text(steps_table(result.true_steps))
    (out / "activity.csv").write_text(activity_intervals_table(result.activity_t,
                                                               result.activity))
    info = {"scenario": result.scenario, "seed": result.seed, "options": result.options,
            "description": result.description, "reference": result.reference,
            "truth": result.hidden_truth}
    (out / "scenario.json").write_text(json.dumps(_jsonable(info), indent=2) + "\n")
    if result.wsn is not None:
        (out / "wsn.json").write_text(json.dumps(result.wsn.to_json(), indent=2) + "\n")
        (out / "wsn_truth.json").write_text(json.dumps(result.wsn.to_json(truth=True),
                                                       indent=2) + "\n")


def activity_intervals_table(t: FloatArray, codes: IntArray) -> str:
    """``activity.csv`` text: one ``t_start,t_end,activity`` row per constant stretch."""
    if len(t) == 0:
        return "t_start,t_end,activity\n"
    change = np.flatnonzero(np.concatenate([[True], codes[1:] != codes[:-1]]))
    ends = np.concatenate([t[change[1:]], [t[-1]]])
    labels = activity_labels(codes[change])
    rows = [f"{t[i]:.6f},{e:.6f},{lab}" for i, e, lab in zip(change, ends, labels, strict=True)
            if e > t[i]]
    return "t_start,t_end,activity\n" + "\n".join(rows) + "\n"
