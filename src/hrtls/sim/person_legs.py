"""A simulated person walking to way points given one at a time: the session part by part.

:class:`WalkingPerson` is :func:`hrtls.sim.person.simulate_person` cut into legs for a closed
loop (issue 18): each :meth:`WalkingPerson.walk_to` starts from the person's **true** state (the
person sees the building), turns on the spot toward the route, stands for a short pause (none
when the route continues within ``straight_rad`` of the heading), then walks the shortest
corridor route (:class:`hrtls.sim.robot_driver.CorridorRouter`, grid of the free space
straightened where the line of sight allows) to the way point and stops there (turn
first, then stand: the order of :func:`hrtls.sim.motion_truth.simulate_motion` at a stop); a
route longer than ``max_walk_s`` of walking is cut and the person stops on it (the caller gives
the next way point then). The first walk starts with ``enter_m`` straight ahead in the start
heading: the rescuer's tracker takes its start pose's heading as that of its first steps (turns
before them are not integrated, :mod:`hrtls.fusion.state`), as in the pre-generated walks,
whose start heading is that of their first leg. Legs are joined at rest, where the gait
oscillation is zero (:mod:`hrtls.sim.gait_model`: its envelope vanishes at zero speed), so the
waist pose, its velocity and the heading are continuous across a join (the acceleration steps
as at any start or stop of :func:`~hrtls.sim.motion_truth.simulate_motion`); the gait phase of
a leg starts at 0.

One device for the whole walk: the mounting (declared belt clip plus its true tilt,
:data:`hrtls.sim.person.BELT_TILT_SIGMA_RAD`) and each sensor's turn-on bias, scale and
misalignment are drawn once; the bias random walk continues from leg to leg. Each sensor follows
the model of :mod:`hrtls.sim.errors`, ``y = sat(quant((I + S) M x + b0 + b_rw(t) + n))``, with
``b_rw`` carried over. The magnetometer is sampled on the accelerometer's times (one rate, as the
mission's device has). Each part holds the IMU samples after the previous part's last one, the
tag reads and node ranges of its time (:mod:`hrtls.sim.infrastructure`, on the track from the
previous part's last sample on) and its ground truth; no barometer (the floor is flat).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity, GroundTruth, Session, SessionMeta, StepEvents
from hrtls.data.series import ImuStream, SensorSeries
from hrtls.data.session import StartPose, UserProfile
from hrtls.errors import InputError
from hrtls.frames import quat_conjugate, quat_rotate, wrap_angle
from hrtls.sim._speed_profile import still_headings
from hrtls.sim.devices import DeviceModel
from hrtls.sim.errors import (
    ErrorRealization,
    SensorErrorModel,
    apply_sensor_errors,
    realize_errors,
    sample_times,
)
from hrtls.sim.gait_model import GaitParams, fill_step_extremes, simulate_gait
from hrtls.sim.imu_model import IdealImu, body_kinematics, ideal_imu, interp_quat, interp_rows
from hrtls.sim.infrastructure import TrackSample, range_measurements, rfid_detections
from hrtls.sim.magnetic import MagneticEnvironment
from hrtls.sim.motion_truth import GAIT_WALK, MotionParams, MotionTruth, Waypoint, simulate_motion
from hrtls.sim.person import PERSON_STREAM, Infrastructure, mountings
from hrtls.sim.robot_driver import CorridorRouter
from hrtls.sim.simulation_result import SimulationResult

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class LegParams:
    """How the person walks a leg (speeds m/s, times s, lengths m)."""

    speed_range_m_s: tuple[float, float] = (0.9, 1.5)
    pause_range_s: tuple[float, float] = (1.0, 3.0)
    """The stop at the start of a leg, after the turn toward the route, drawn per leg."""
    straight_rad: float = 0.35
    """A leg whose first direction is within this of the heading continues: no pause."""
    corner_radius_range_m: tuple[float, float] = (0.0, 1.0)
    arrive_m: float = 0.5
    """A way point closer than this to the person: no walk, the person only stands."""
    turn_rate_rad_s: float = 2.0
    enter_m: float = 2.0
    """The first walk starts with this much straight ahead (module doc)."""

    def __post_init__(self) -> None:
        lo, hi = self.speed_range_m_s
        p0, p1 = self.pause_range_s
        if not (0 < lo <= hi and 0 < p0 <= p1 and self.arrive_m > 0
                and self.turn_rate_rad_s > 0 and self.straight_rad >= 0):
            raise InputError("invalid leg parameters", where="LegParams",
                             expected="speeds > 0, pauses > 0 (low <= high), arrive_m > 0")


@dataclass(kw_only=True)
class _DeviceState:
    """The device's drawn errors and the current value of each bias random walk."""

    realizations: dict[str, ErrorRealization]
    walk: dict[str, FloatArray]
    t_last_s: float | None = None


@dataclass(kw_only=True)
class _Record:
    """What the person did so far, for the joined session and its truth extras."""

    parts: list[Session] = field(default_factory=list)
    steps: list[StepEvents] = field(default_factory=list)
    activity_t: list[FloatArray] = field(default_factory=list)
    activity: list[NDArray[np.int64]] = field(default_factory=list)
    walked: bool = False


def _cut(route: FloatArray, length_m: float) -> FloatArray:
    """The first ``length_m`` of the polyline ``route`` ``(k, 2)``."""
    seg = np.hypot(*np.diff(route, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= length_m:
        return route
    j = int(np.searchsorted(cum, length_m, side="right"))
    f = (length_m - cum[j - 1]) / seg[j - 1]
    return np.vstack([route[:j], route[j - 1] + f * (route[j] - route[j - 1])])


def _still(t_s: NDArray[np.floating], xy: FloatArray, heading: FloatArray) -> MotionTruth:
    """Standing (possibly turning on the spot) at ``xy`` at times ``t_s``."""
    t = np.asarray(t_s, dtype=np.float64)
    n = len(t)
    return MotionTruth(t=t, s=np.zeros(n), xyz=np.column_stack([np.tile(xy, (n, 1)),
                                                               np.zeros(n)]),
                       heading=heading, speed=np.zeros(n),
                       gait=np.full(n, GAIT_WALK, dtype=np.int64), moving=np.zeros(n, bool),
                       run_id=np.full(n, -1, dtype=np.int64),
                       activity=np.full(n, int(Activity.STANDING), dtype=np.int64),
                       step_length_override=np.full(n, np.nan))


def _concat(parts: list[MotionTruth]) -> MotionTruth:
    """Motions one after the other (run indices of each part kept apart)."""
    run, off = [], 0
    for p in parts:
        run.append(np.where(p.run_id >= 0, p.run_id + off, -1))
        off += int(p.run_id.max()) + 1 if len(p.run_id) and p.run_id.max() >= 0 else 0
    cat = {k: np.concatenate([getattr(p, k) for p in parts])
           for k in ("t", "s", "xyz", "heading", "speed", "gait", "moving", "activity",
                     "step_length_override")}
    return MotionTruth(run_id=np.concatenate(run).astype(np.int64), **cat)


class WalkingPerson:
    """A person with a waist device walking legs in a floor plan (module doc)."""

    def __init__(self, *, name: str, seed: int, device: DeviceModel, router: CorridorRouter,
                 start_xy_m: FloatArray, start_heading_rad: float,
                 infra: Infrastructure, magnetic: MagneticEnvironment,
                 rngs: list[np.random.Generator], params: LegParams | None = None,
                 source: dict[str, Any] | None = None, description: str = "") -> None:
        self.name = name
        self.params = params or LegParams()
        self.device = device
        self.router = router
        self.infra = infra
        self.magnetic = magnetic
        self.rngs = rngs
        self.gait = GaitParams().drawn(np.random.default_rng([seed, PERSON_STREAM]))
        q_declared, self.q_bd = mountings("belt", rngs[7])
        assert q_declared is not None
        self.motion_params = MotionParams()
        sensors = {"accelerometer": device.accel, "gyroscope": device.gyro,
                   "magnetometer": device.mag}
        self.dev = _DeviceState(
            realizations={k: realize_errors(m, rngs[2]) for k, m in sensors.items()},
            walk={k: np.zeros(3) for k in sensors})
        self.xy_m = np.asarray(start_xy_m, dtype=np.float64).copy()
        self.heading_rad = float(start_heading_rad)
        self.t_s = -np.inf
        """Time of the last sample produced (``-inf`` before :meth:`stand_until`)."""
        self.arrived = False
        """The last :meth:`walk_to` ended at its way point (the person sees it is there)."""
        self.description = description
        self.record = _Record()
        self.meta = SessionMeta(
            start_pose=StartPose(x=float(self.xy_m[0]), y=float(self.xy_m[1]), z=0.0,
                                 heading=self.heading_rad, sigma_xy_m=0.1,
                                 sigma_heading_rad=0.05),
            placement="belt", mounting_q_bd=(float(q_declared[0]), float(q_declared[1]),
                                                float(q_declared[2]), float(q_declared[3])),
            user=UserProfile(height_m=1.75), floor_height_m=3.0,
            source={"format": "hrtls-sim", "device": device.name, **(source or {})},
            notes=[description, f"device: {device.description}"])
        self.landmarks = {tag.id: tag.landmark() for tag in infra.tags}

    @property
    def dt_s(self) -> float:
        """The device's sample period, s."""
        return 1.0 / self.device.rate_hz

    def stand_until(self, *, start_s: float, until_s: float) -> Session:
        """The first part: standing at the start from ``start_s`` to ``until_s``."""
        if self.t_s > -np.inf or not until_s > start_s:
            raise InputError(f"stand from {start_s} to {until_s} s", where="WalkingPerson",
                             expected="the first part, until after its start")
        n = int(np.floor((until_s - start_s) / self.dt_s + 1e-9)) + 1
        t = start_s + self.dt_s * np.arange(n)
        return self._part(_still(t, self.xy_m, np.full(n, self.heading_rad)), first=True)

    def walk_to(self, target_m: FloatArray, *, max_walk_s: float, until_s: float) -> Session:
        """Turn toward ``target_m``, pause, walk there (at most ``max_walk_s``), stop; the part.

        The part ends on arrival or at ``until_s``, whichever is first.
        """
        if self.t_s == -np.inf:
            raise InputError("walk before the first part", where="WalkingPerson.walk_to",
                             expected="stand_until() first")
        if not until_s >= self.t_s + self.dt_s:
            raise InputError(f"until {until_s} s", where="WalkingPerson.walk_to",
                             expected=f"at least one sample after {self.t_s} s")
        target = np.asarray(target_m, dtype=np.float64)
        motion = self._leg_motion(target, max_walk_s)
        keep = motion.t <= until_s + 1e-9
        end = motion.xyz[np.flatnonzero(keep)[-1], :2]
        self.arrived = bool(np.hypot(*(end - self.router.inside(target))) < self.params.arrive_m)
        motion = MotionTruth(**{f: getattr(motion, f)[keep] for f in MotionTruth.__slots__})
        return self._part(motion, first=False)

    def _leg_motion(self, target_m: FloatArray, max_walk_s: float) -> MotionTruth:
        """The leg's motion from the last sample on (that sample first), module doc."""
        prm, rng, dt = self.params, self.rngs[0], self.dt_s
        speed = float(rng.uniform(*prm.speed_range_m_s))
        pause = float(rng.uniform(*prm.pause_range_s))
        here = _still(np.array([self.t_s]), self.xy_m, np.array([self.heading_rad]))
        start = [self.xy_m]
        if not self.record.walked:  # the first steps go straight ahead (module doc)
            c, s = np.cos(self.heading_rad), np.sin(self.heading_rad)
            start.append(self.router.inside(self.xy_m + prm.enter_m * np.array([c, s])))
        route = self.router.route(start[-1], target_m)
        pts = _cut(np.vstack([*start, *route[1:]]), speed * max_walk_s)
        keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-6])
        pts = pts[keep]
        length = float(np.sum(np.hypot(*np.diff(pts, axis=0).T)))
        if length < prm.arrive_m:
            n = max(1, round(pause / dt))
            t = self.t_s + dt * np.arange(1, n + 1)
            return _concat([here, _still(t, self.xy_m, np.full(n, self.heading_rad))])
        self.record.walked = True
        wps = [Waypoint(x=float(p[0]), y=float(p[1]), speed_m_s=speed,
                        corner_radius_m=float(rng.uniform(*prm.corner_radius_range_m)))
               for p in pts]
        first = float(np.arctan2(*(pts[1] - pts[0])[::-1]))
        turn = float(wrap_angle(first - self.heading_rad))
        n_turn = 0
        if abs(turn) > 1e-3:
            t_turn = max(abs(turn) * 1.875 / prm.turn_rate_rad_s, self.motion_params.min_turn_s)
            n_turn = round(t_turn / dt)
        h = still_headings(duration_s=n_turn * dt, heading_rad=self.heading_rad, turn_rad=turn,
                           turn_rate_rad_s=prm.turn_rate_rad_s, dt_s=dt,
                           min_turn_s=self.motion_params.min_turn_s)
        n_pause = 1 if abs(turn) < prm.straight_rad else max(1, round(pause / dt))
        h = np.concatenate([h, np.full(n_pause, first)])
        turning = _still(self.t_s + dt * np.arange(1, len(h) + 1), self.xy_m, h)
        walk = simulate_motion(wps, rate_hz=self.device.rate_hz, params=self.motion_params,
                               start_pause_s=0.0, end_pause_s=0.0,
                               t0_s=self.t_s + dt * (len(h) + 1))
        return _concat([here, turning, walk])

    def _part(self, motion: MotionTruth, *, first: bool) -> Session:
        """The session part of ``motion`` (its first sample is the previous part's last)."""
        gres = simulate_gait(motion, self.gait, self.rngs[1])
        kin = body_kinematics(motion, gres)
        ideal = ideal_imu(kin, q_bd=self.q_bd)
        k0 = 0 if first else 1
        imu = self._imu(ideal, float(motion.t[k0]), float(motion.t[-1]))
        track = TrackSample(t=motion.t, xyz=motion.xyz, heading=motion.heading,
                            speed=motion.speed)
        infra = self.infra
        ranges = (range_measurements(infra.nodes, infra.range_model, track, self.rngs[6])
                  if infra.range_model is not None and infra.nodes else None)
        tags = rfid_detections(infra.tags, infra.reader, track, self.rngs[5]) \
            if infra.tags else None
        t = motion.t[k0:]
        part = Session(meta=self.meta, imu=imu, tags=tags, ranges=ranges,
                       landmarks=self.landmarks if first else {},
                       truth=GroundTruth(t, motion.xyz[k0:], motion.heading[k0:]))
        rec = self.record
        rec.parts.append(part)
        rec.steps.append(fill_step_extremes(gres.steps, motion.t, ideal.accel_n[:, 2]))
        rec.activity_t.append(t)
        rec.activity.append(motion.activity[k0:])
        self.t_s = float(motion.t[-1])
        self.xy_m = motion.xyz[-1, :2].copy()
        self.heading_rad = float(motion.heading[-1])
        return part

    def _imu(self, ideal: IdealImu, t0_s: float, t1_s: float) -> ImuStream:
        """The device's samples from ``t0_s`` to ``t1_s`` (errors carried over, module doc)."""
        dev, rng = self.device, self.rngs[2]
        t = sample_times(t0_s, t1_s, dev.rate_hz, dev.jitter_s, rng)
        f = self._errors("accelerometer", dev.accel,
                         interp_rows(t, ideal.t, ideal.specific_force), t)
        w = self._errors("gyroscope", dev.gyro, interp_rows(t, ideal.t, ideal.angular_rate), t)
        q_nd = interp_quat(t, ideal.t, ideal.q_nd)
        m_n = self.magnetic.field_at(interp_rows(t, ideal.t, ideal.device_position))
        m = self._errors("magnetometer", dev.mag, quat_rotate(quat_conjugate(q_nd), m_n), t)
        self.dev.t_last_s = float(t[-1])
        return ImuStream(SensorSeries(t, f, "accelerometer"), SensorSeries(t, w, "gyroscope"),
                         SensorSeries(t, m, "magnetometer"), check_units=False)

    def _errors(self, key: str, model: SensorErrorModel, x: FloatArray,
                t: FloatArray) -> FloatArray:
        """Measurements of ``x`` with the drawn errors, the bias walk continued (module doc)."""
        rng = self.rngs[2]
        base = replace(model, bias_walk_density=0.0, resolution=0.0, full_scale=float("inf"))
        y = apply_sensor_errors(x, t, base, self.dev.realizations[key], rng)
        if model.bias_walk_density > 0:
            t_prev = t[0] if self.dev.t_last_s is None else self.dev.t_last_s
            dt = np.diff(t, prepend=t_prev)
            walk = self.dev.walk[key] + np.cumsum(
                rng.standard_normal((len(t), 3)) * (model.bias_walk_density
                                                    * np.sqrt(dt))[:, None], axis=0)
            self.dev.walk[key] = walk[-1].copy()
            y = y + walk
        if model.resolution > 0:
            y = np.round(y / model.resolution) * model.resolution
        if np.isfinite(model.full_scale):
            y = np.clip(y, -model.full_scale, model.full_scale)
        return np.asarray(y, dtype=np.float64)

    def session(self) -> Session:
        """Every part so far joined into one session."""
        from hrtls.mission.buffer import merge

        parts = self.record.parts
        out = parts[0]
        for p in parts[1:]:
            out = merge(out, p)
        truth = [p.truth for p in parts if p.truth is not None]
        return out.with_parts(truth=GroundTruth(
            np.concatenate([g.t for g in truth]), np.vstack([g.xyz for g in truth]),
            np.concatenate([np.asarray(g.heading_rad) for g in truth])))

    def result(self, *, scenario: str, seed: int, options: dict[str, Any]) -> SimulationResult:
        """The joined session with its truth extras (true steps, activity, hidden truth)."""
        rec = self.record
        return SimulationResult(
            scenario=scenario, seed=seed, options=options, session=self.session(),
            true_steps=StepEvents.concatenate(rec.steps),
            activity_t=np.concatenate(rec.activity_t),
            activity=np.concatenate(rec.activity).astype(np.int64),
            description=self.description,
            hidden_truth={"mounting_q_bd": self.q_bd.tolist(),
                          "gait": dataclasses.asdict(self.gait),
                          "device": self.device.name,
                          "sensor_errors": {k: v.to_dict()
                                            for k, v in self.dev.realizations.items()}})
