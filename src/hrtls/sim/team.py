"""A simulated team mission: rescuers and a robot in the thesis' two-floor building.

The building is the one of Inderst Sec. 6.3.1 (``inderst_multifloor``): a ground-floor corridor
(0, 0)-(40, 0)-(40, 20), two flights of stairs at x = 40..43, and a loop on the first floor
(40, 21.2)-(0, 21.2)-(0, 36.2)-(40, 36.2). Ours on top of it (the thesis ran one
person at a time):

- five RFID tags on the corridor walls (two on the ground floor, three on the first floor),
  read by the rescuers' readers;
- rescuer A walks the thesis' route (ground floor, stairs up, the first-floor loop, back down);
- rescuer B goes up to the far corridor of the first floor and stops halfway for ``stop_s`` (long
  enough for a PASS alarm: pre-alarm after 20 s, alarm after 30 s), then walks back out;
- a robot patrols the ground-floor corridor at 0.5 m/s; its wheel odometry is reported as poses
  with a growing sigma (drift 1 % of the distance, heading drift as a random walk).

Every member has its own session (IMU for the rescuers, odometry poses for the robot) with
ground truth, so the same mission is tracked offline or streamed live to ``hrtls serve``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from hrtls.data import Session
from hrtls.data.landmarks import Landmark
from hrtls.data.observations import GroundTruth, PositionFixes
from hrtls.data.session import SessionMeta, StartPose
from hrtls.errors import InputError
from hrtls.sim.devices import get_device
from hrtls.sim.floorplan import route_floorplan
from hrtls.sim.infrastructure import RfidTag
from hrtls.sim.motion_truth import MotionParams, Waypoint, simulate_motion
from hrtls.sim.scenarios import Infrastructure, simulate_person

FLOOR_HEIGHT_M = 3.3
ROBOT_RATE_HZ = 5.0


@dataclass(frozen=True, slots=True)
class TeamMember:
    """One agent of the mission: its name, kind, tracker preset and session (with truth)."""

    name: str
    kind: Literal["rescuer", "robot"]
    preset: str
    session: Session
    note: str


@dataclass(frozen=True, slots=True)
class TeamMission:
    """Floors, floor plan, landmarks and members of a simulated team mission."""

    name: str
    floor_height_m: float
    floors: tuple[tuple[int, str], ...]
    plan: dict[str, Any]
    landmarks: tuple[Landmark, ...]
    members: tuple[TeamMember, ...]

    @property
    def duration_s(self) -> float:
        """Time of the last sample of any member, s."""
        return max(float(m.session.truth.t[-1]) for m in self.members
                   if m.session.truth is not None)

    def floor_plan(self, floor: int) -> dict[str, Any]:
        """The plan's features of one floor (GeoJSON FeatureCollection)."""
        return {"type": "FeatureCollection",
                "features": [f for f in self.plan["features"]
                             if f["properties"]["floor"] == floor]}


def _tags(fh: float) -> list[RfidTag]:
    # on the corridor walls (1.1 m from the way's centre line), lobes into the corridor
    up, ew, ns = np.pi / 2, (0.0, np.pi), (np.pi / 2, -np.pi / 2)
    return [RfidTag(id="T1", position=(20.0, -1.1, 2.2), lobe_orientation_rad=up, floor=0,
                    bearings_rad=ew),
            RfidTag(id="T2", position=(41.1, 10.0, 2.2), lobe_orientation_rad=np.pi, floor=0,
                    bearings_rad=ns),
            RfidTag(id="T3", position=(20.0, 22.3, fh + 2.2), lobe_orientation_rad=-up,
                    floor=1, bearings_rad=ew),
            RfidTag(id="T4", position=(-1.1, 28.7, fh + 2.2), lobe_orientation_rad=0.0,
                    floor=1, bearings_rad=ns),
            RfidTag(id="T5", position=(30.0, 37.3, fh + 2.2), lobe_orientation_rad=-up,
                    floor=1, bearings_rad=ew)]


def _stairs_up(v: float, fh: float) -> list[Waypoint]:
    return [Waypoint(x=40.0, y=20.0, speed_m_s=v, corner_radius_m=0.5),
            Waypoint(x=43.0, y=20.0, z=fh / 2, speed_m_s=0.55, corner_radius_m=0.0),
            Waypoint(x=43.0, y=21.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=40.0, y=21.2, z=fh, speed_m_s=0.55, corner_radius_m=0.5)]


def _stairs_down(v: float, fh: float) -> list[Waypoint]:
    return [Waypoint(x=43.0, y=21.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=43.0, y=20.0, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=40.0, y=20.0, z=0.0, speed_m_s=0.6, corner_radius_m=0.5),
            Waypoint(x=40.0, y=0.0, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=0.0, y=0.0, speed_m_s=v)]


def _route_a(v: float, fh: float) -> list[Waypoint]:
    return [Waypoint(x=0.0, y=0.0), Waypoint(x=40.0, y=0.0, speed_m_s=v, corner_radius_m=1.0),
            *_stairs_up(v, fh),
            Waypoint(x=0.0, y=21.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=0.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=21.2, z=fh, speed_m_s=v, corner_radius_m=0.0),
            *_stairs_down(v, fh)]


def _route_b(v: float, fh: float, stop_s: float) -> list[Waypoint]:
    return [Waypoint(x=0.0, y=0.0), Waypoint(x=40.0, y=0.0, speed_m_s=v, corner_radius_m=1.0),
            *_stairs_up(v, fh),
            Waypoint(x=40.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=20.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=0.0, stop_s=stop_s),
            Waypoint(x=40.0, y=36.2, z=fh, speed_m_s=v, corner_radius_m=1.0),
            Waypoint(x=40.0, y=21.2, z=fh, speed_m_s=v, corner_radius_m=0.0),
            *_stairs_down(v, fh)]


def odometry_poses(t: np.ndarray, xyz: np.ndarray, rng: np.random.Generator, *,
                   scale_sigma: float = 0.01, heading_step_sigma_rad: float = np.deg2rad(0.05)
                   ) -> PositionFixes:
    """Wheel odometry of a true track, as poses.

    The true displacement integrated with one scale error (``scale_sigma``) and a heading random
    walk (``heading_step_sigma_rad`` per sample), from the true start; sigma 0.05 m + 1 % of the
    distance.
    """
    step = np.diff(xyz[:, :2], axis=0)
    heading_err = np.cumsum(rng.normal(0.0, heading_step_sigma_rad, len(step)))
    c, s = np.cos(heading_err), np.sin(heading_err)
    scale = 1.0 + rng.normal(0.0, scale_sigma)
    moved = scale * np.column_stack([c * step[:, 0] - s * step[:, 1],
                                     s * step[:, 0] + c * step[:, 1]])
    xy = xyz[0, :2] + np.vstack([[0.0, 0.0], np.cumsum(moved, axis=0)])
    travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(step, axis=1))])
    return PositionFixes(t, np.column_stack([xy, np.zeros(len(xy))]), 0.05 + 0.01 * travelled)


def _robot(seed: int, *, speed_m_s: float, laps: int) -> TeamMember:
    rng = np.random.default_rng([seed, 991])
    legs = [Waypoint(x=2.0, y=0.0)]
    for _ in range(laps):
        legs += [Waypoint(x=39.0, y=0.0, speed_m_s=speed_m_s, corner_radius_m=1.0),
                 Waypoint(x=39.0, y=18.0, speed_m_s=speed_m_s, corner_radius_m=0.0),
                 Waypoint(x=39.0, y=0.0, speed_m_s=speed_m_s, corner_radius_m=1.0),
                 Waypoint(x=2.0, y=0.0, speed_m_s=speed_m_s, corner_radius_m=0.0)]
    motion = simulate_motion(legs, rate_hz=ROBOT_RATE_HZ, start_pause_s=2.0, end_pause_s=2.0)
    fixes = odometry_poses(motion.t, motion.xyz, rng)
    meta = SessionMeta(start_pose=StartPose(x=float(motion.xyz[0, 0]), y=float(motion.xyz[0, 1]),
                                            z=0.0, heading=float(motion.heading[0]),
                                            sigma_xy_m=0.1, sigma_heading_rad=0.05),
                       floor_height_m=FLOOR_HEIGHT_M,
                       source={"format": "hrtls-sim", "scenario": "team robot", "seed": seed},
                       notes=["robot odometry poses with sigma 0.05 m + 1 % of the distance"])
    session = Session(meta=meta, fixes=fixes,
                      truth=GroundTruth(motion.t, motion.xyz, motion.heading))
    return TeamMember("Robot 1", "robot", "default", session,
                      f"patrols the ground-floor corridor at {speed_m_s} m/s (odometry)")


def team_mission(seed: int = 0, *, stop_s: float = 45.0, speed_m_s: float = 1.1,
                 robot_laps: int = 1, waypoints: int | None = None) -> TeamMission:
    """Two rescuers and a robot in the two-floor building; rescuer B stops for ``stop_s``.

    ``waypoints``: keep only the first ones of each rescuer's route (a shorter mission).
    """
    if not stop_s >= 0 or not speed_m_s > 0 or robot_laps < 1:
        raise InputError(f"stop_s={stop_s}, speed_m_s={speed_m_s}, robot_laps={robot_laps}",
                         where="team_mission", expected="stop_s >= 0, speed > 0, laps >= 1")
    fh = FLOOR_HEIGHT_M
    tags = _tags(fh)
    infra = Infrastructure(tags=tags)
    params = MotionParams(stair_tread_m=0.30, stair_riser_m=0.165)
    device = get_device("mpu9150_motionfit")
    members = []
    for name, route, offset, note in (
            ("Rescuer A", _route_a(speed_m_s, fh), 0, "the thesis' two-floor route"),
            ("Rescuer B", _route_b(speed_m_s, fh, stop_s), 1,
             f"stops {stop_s:.0f} s at the far end of the first floor (PASS)")):
        sim = simulate_person(f"team {name}", seed * 10 + offset, {"stop_s": stop_s},
                              route[:waypoints],
                              device=device, motion_params=params, infra=infra,
                              with_pressure=True, floor_height_m=fh,
                              description=f"{name}: {note}")
        members.append(TeamMember(name, "rescuer", "default", sim.session, note))
    members.append(_robot(seed, speed_m_s=0.5, laps=robot_laps))
    plan = route_floorplan([m.session.truth.xyz for m in members if m.session.truth is not None],
                           floor_height_m=fh)
    return TeamMission(name="Two-floor rescue (simulated team)", floor_height_m=fh,
                       floors=((0, "Ground floor"), (1, "First floor")), plan=plan,
                       landmarks=tuple(t.landmark() for t in tags), members=tuple(members))
