"""One simulated person walking way points with a device past an infrastructure.

:func:`simulate_person` assembles the session a scenario returns: motion, gait, IMU,
placement and whatever the :class:`Infrastructure` observes, with the truth kept apart;
:func:`calibration_waypoints` gives the same person's calibration course.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from hrtls.data import Checkpoints, GroundTruth, Landmark, Session, SessionMeta
from hrtls.data.session import StartPose, UserProfile
from hrtls.errors import InputError
from hrtls.frames import quat_from_rotation, quat_from_rotvec, quat_multiply
from hrtls.sim.devices import DeviceModel
from hrtls.sim.gait_model import GaitParams, fill_step_extremes, simulate_gait
from hrtls.sim.imu_model import body_kinematics, simulate_imu
from hrtls.sim.infrastructure import (
    CameraSystem,
    RangeModel,
    RfidReader,
    RfidTag,
    RssChannel,
    TrackSample,
    anchor_landmarks,
    camera_fixes,
    range_measurements,
    rfid_detections,
    rss_readings,
)
from hrtls.sim.magnetic import MagneticEnvironment
from hrtls.sim.motion_truth import MotionParams, MotionTruth, Waypoint, simulate_motion
from hrtls.sim.scenario_options import scenario_rngs
from hrtls.sim.simulation_result import SimulationResult

__all__ = ["BELT_TILT_SIGMA_RAD", "CALIBRATION_LEG_M", "PERSON_STREAM", "Infrastructure",
           "calibration_summary", "calibration_waypoints", "checkpoint_passes",
           "mounting_quaternion", "mountings", "simulate_person"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


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
    r = rngs or scenario_rngs(seed)
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
    q_declared, q_bd = mountings(placement, r[7])
    sim = simulate_imu(kin, device, r[2], q_bd=q_bd, lever_arm_b=lever_arm_b,
                       magnetic=magnetic or MagneticEnvironment(), with_gyro=with_gyro,
                       with_mag=with_mag, with_orientation=with_orientation,
                       with_pressure=with_pressure)
    steps = fill_step_extremes(gres.steps, motion.t, sim.ideal.accel_n[:, 2])
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
                      orientation=sim.orientation,
                      truth=GroundTruth(motion.t, motion.xyz, motion.heading),
                      **_observations(infra, motion, r))
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


def mountings(placement: str, rng: np.random.Generator) -> tuple[FloatArray | None, FloatArray]:
    """The declared mounting of a placement (None for ``"random"``) and the true one.

    The true mounting of a fixed placement is off its nominal one by
    :data:`BELT_TILT_SIGMA_RAD` per axis; a random placement declares none.
    """
    q_declared = None if placement == "random" else mounting_quaternion(placement, rng)
    q_bd = mounting_quaternion(placement, rng) if q_declared is None else quat_multiply(
        q_declared, quat_from_rotvec(rng.normal(0.0, 1.0, 3) * BELT_TILT_SIGMA_RAD))
    return q_declared, q_bd


def _observations(infra: Infrastructure, motion: MotionTruth,
                  rngs: list[np.random.Generator]) -> dict[str, Any]:
    """What ``infra`` observes of ``motion``: the :class:`Session` fields it fills.

    Camera fixes, RSS readings, tag detections, ranges (each from its own generator of
    ``rngs``), the landmarks of anchors, tags and nodes, and the checkpoint passes.
    """
    track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading, speed=motion.speed)
    landmarks: dict[str, Landmark] = {}
    if infra.anchors:
        landmarks.update(anchor_landmarks(infra.anchors, kind="anchor"))
    for tag in infra.tags:
        landmarks[tag.id] = tag.landmark()
    if infra.nodes:
        landmarks.update(anchor_landmarks(infra.nodes, kind="node"))
    return {
        "fixes": camera_fixes(infra.camera, track, rngs[3]) if infra.camera is not None else None,
        "rss": (rss_readings(infra.anchors, infra.channel, track, rngs[4])
                if infra.channel is not None and infra.anchors else None),
        "tags": rfid_detections(infra.tags, infra.reader, track, rngs[5]) if infra.tags else None,
        "ranges": (range_measurements(infra.nodes, infra.range_model, track, rngs[6])
                   if infra.range_model is not None and infra.nodes else None),
        "landmarks": landmarks,
        "checkpoints": (checkpoint_passes(motion.t, motion.xyz, infra.checkpoints,
                                          radius_m=infra.checkpoint_radius_m)
                        if infra.checkpoints else None),
    }


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
