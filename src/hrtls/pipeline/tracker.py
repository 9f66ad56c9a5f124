"""The tracker: attitude -> gait -> position filter with every correction, offline and live.

:class:`Tracker` wires the parts named by a :class:`~hrtls.pipeline.config.TrackerConfig`.
``run(session)`` is ``start`` + one ``update`` with the whole session + ``finish``; the live
service calls ``update`` with successive chunks (a :class:`~hrtls.data.Session` holding the new
samples and observations) and gets the same result.

Per-sample work (attitude, gait, velocity prediction) runs in the compiled kernels of those
stages. The position filter then handles *events* in time order — steps, position fixes, RSS
scans, tag reads, ranges — at a few Hz, in Python. Observations are held back until the gait stage
has released every step that ends before them, so a chunked run processes events in exactly
the order of an offline run.
"""

from __future__ import annotations

import heapq
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.attitude.base import AttitudeFilter, AttitudeResult
from hrtls.attitude.device import DeviceOrientation
from hrtls.attitude.registry import make_filter
from hrtls.data import (
    Activity,
    Landmark,
    Session,
    SessionMeta,
    StartPose,
    StepEvents,
    Trajectory,
)
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import quat_conjugate, quat_multiply, quat_rotate, wrap_angle
from hrtls.fusion.fixes import FixCorrector, FixParams, FixSchedule
from hrtls.fusion.floors import floor_level_update
from hrtls.fusion.gating import UpdateDiagnostics, kalman_update, skipped, summarize
from hrtls.fusion.random_walk import RandomWalkParams, predict_random_walk
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.rss import (
    ChannelEstimator,
    ChannelState,
    PathLossModel,
    group_scans,
    rss_update,
    scan_position,
)
from hrtls.fusion.state import IH, FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import TagCorrector, TagMemory, TagParams, bearing_heading_correction
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds
from hrtls.gait.peak_steps import PeakStepDetector
from hrtls.gait.pipeline import GaitAnalyzer, GaitResult
from hrtls.gait.pll import PllStepDetector
from hrtls.gait.step_length import FrequencyLawModel, StepModel, WeinbergModel, step_model_from_dict
from hrtls.gait.velocity_automaton import VelocityAutomaton
from hrtls.pipeline.config import TrackerConfig, preset

FloatArray = np.ndarray

# event kinds in the order they are applied when they share a time
_STEP, _FIX, _RSS, _TAGS, _RANGE = 0, 1, 2, 3, 4
_KIND_NAMES = {_STEP: "step", _FIX: "fix", _RSS: "rss", _TAGS: "tags", _RANGE: "range"}
MOVING_SIGMA_M_S2 = 0.2
"""Colombo's sigma_min: the user moves when the 2 s std of vertical acceleration exceeds it."""


@dataclass(frozen=True, slots=True, eq=False)
class TrackResult:
    """What the tracker produced.

    Attributes
    ----------
    trajectory: estimated track (one row per processed event), ENU, with covariance.
    steps: detected steps (length, heading, dz, activity).
    attitude: per-sample attitude (None without an IMU or with ``method = "none"``).
    diagnostics: one record per correction attempt (accepted, rejected or skipped).
    report: JSON-able summary (inputs used, degraded modes, counts, rejected observations).
    """

    trajectory: Trajectory
    steps: StepEvents
    attitude: AttitudeResult | None
    diagnostics: list[UpdateDiagnostics]
    report: dict[str, Any]


@dataclass
class _Track:
    """Accumulated output rows."""

    t: list[float] = field(default_factory=list)
    x: list[np.ndarray] = field(default_factory=list)
    p: list[np.ndarray] = field(default_factory=list)
    activity: list[int] = field(default_factory=list)

    def add(self, state: FilterState, activity: int) -> None:
        if self.t and state.t <= self.t[-1]:
            # several events at one time: keep the latest state for that time
            self.x[-1], self.p[-1], self.activity[-1] = state.x, state.P, activity
            return
        self.t.append(state.t)
        self.x.append(state.x)
        self.p.append(state.P)
        self.activity.append(activity)

    def trajectory(self) -> Trajectory:
        if not self.t:
            return Trajectory.build(t=np.zeros(0), xyz=np.zeros((0, 3)))
        x = np.asarray(self.x)
        p = np.asarray(self.p)
        return Trajectory.build(t=np.asarray(self.t), xyz=x[:, :3], heading_rad=x[:, IH],
                                cov_xy=p[:, :2, :2], var_heading=p[:, IH, IH],
                                activity=np.asarray(self.activity))


class Tracker:
    """Track one agent from a session (offline) or from chunks of it (live).

    Parameters
    ----------
    config:
        What to run; the ``default`` preset when None.
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else preset("default")
        self._started = False

    # ------------------------------------------------------------------ set-up
    def start(self, meta: SessionMeta, landmarks: dict[str, Landmark], *,
              has_imu: bool, has_gyro: bool, has_mag: bool, has_orientation: bool,
              rate_hz: float, t0: float) -> None:
        """Prepare for a recording with these sensors; the next ``update`` continues from t0."""
        cfg = self.config
        self.meta = meta
        geo = None if meta.georeference is None else meta.georeference.to_georeference()
        self.landmarks = {k: lm.resolved(geo) if (lm.position is not None or geo is not None)
                          else lm for k, lm in landmarks.items()}
        self.notes: list[str] = []
        self.diagnostics: list[UpdateDiagnostics] = []
        self._track = _Track()
        self._steps: list[StepEvents] = []
        self._attitude: list[AttitudeResult] = []
        self._pending: list[tuple[float, int, int, Any]] = []
        self._seq = 0
        self._horizon = -math.inf
        self._motion_t: list[np.ndarray] = []
        self._motion_sigma: list[np.ndarray] = []
        self._last_activity = int(Activity.UNKNOWN)
        self._last_step_end = -math.inf
        self.has_imu = has_imu
        pose = meta.start_pose or StartPose()
        self.heading_known = pose.heading is not None
        self.state = FilterState.from_start_pose(pose, t=t0)
        self._track.add(self.state, int(Activity.UNKNOWN))
        # --- attitude
        self.attitude_filter: AttitudeFilter | DeviceOrientation | None = None
        method = cfg.attitude.method
        if has_imu and method == "device" and not has_orientation:
            self._degrade("attitude 'device' asked but the session has no device orientation; "
                          "using 'quat-ekf'")
            method = "quat-ekf"
        if has_imu and method not in ("device", "none") and not has_gyro and not has_mag:
            self._degrade("no gyroscope and no magnetometer: heading is unobservable, "
                          "using accelerometer-only levelling and relative walking directions")
            method = "none"
        if has_imu and method not in ("device", "none") and not has_gyro:
            self._degrade("no gyroscope: attitude from accelerometer and magnetometer only")
        self.attitude_method = method if has_imu else "none"
        if has_imu and method == "device":
            self.attitude_filter = DeviceOrientation()
        elif has_imu and method != "none":
            self.attitude_filter = make_filter(method)
        self._use_mag = cfg.attitude.use_magnetometer and has_mag
        # --- gait
        self.gait: GaitAnalyzer | None = None
        if has_imu:
            self.gait = GaitAnalyzer(
                rate_hz=rate_hz,
                step_detector=PllStepDetector() if cfg.gait.step_detector == "pll"
                else PeakStepDetector(),
                step_model=self._step_model(meta),
                activity=self._activity_model(),
                heading=cfg.gait.heading if self.attitude_method != "none" else "fourier",
                velocity=VelocityAutomaton() if (cfg.gait.velocity_automaton
                                                 or cfg.prediction.model == "velocity")
                else None,
                mounting_q_bd=None if meta.mounting_q_bd is None
                else np.asarray(meta.mounting_q_bd, dtype=np.float64),
                gate_steps_with_motion=cfg.gait.gate_steps_with_motion,
            )
            if meta.mounting_q_bd is None and cfg.gait.heading == "yaw":
                self.notes.append("device mounting unknown: step headings follow the device x "
                                  "axis; only their changes are used (heading in the state)")
        # --- position filter parts
        heading_mode = cfg.prediction.heading_mode
        self.step_predictor = StepPredictor(StepPredictionParams(
            q_along=cfg.prediction.q_along, q_across=cfg.prediction.q_across,
            heading_mode=heading_mode, stairs_from_model=cfg.prediction.stairs_from_model,
            sigma_heading_increment_rad=cfg.prediction.sigma_heading_increment_rad))
        self.velocity_predictor = VelocityPredictor(VelocityPredictionParams())
        self.fix_corrector = FixCorrector(FixParams(
            period_s=cfg.fixes.period_s, require_motion=cfg.fixes.require_motion,
            gate_probability=cfg.gate_probability))
        self.fix_schedule = FixSchedule()
        self.tag_corrector = TagCorrector(TagParams(strategy=cfg.tags.strategy,
                                                    gate_probability=cfg.gate_probability))
        self.tag_memory = TagMemory()
        self.range_params = RangeParams(gate_probability=cfg.gate_probability)
        channel = meta.channel
        self.path_loss = (PathLossModel.from_channel(channel) if channel is not None
                          else PathLossModel(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
        self.channel_estimator = ChannelEstimator() if cfg.rss.estimate_channel else None
        self.channel_state: ChannelState | None = (
            None if self.channel_estimator is None
            else self.channel_estimator.start(self.path_loss))
        if channel is None and cfg.rss.mode != "off":
            self.notes.append("no channel model in session.json: RSS starts from A = -59 dBm, "
                              "eta = 2" + (" and re-estimates them online"
                                           if cfg.rss.estimate_channel else ""))
        self._t_last_sample = t0
        self._started = True

    def _degrade(self, message: str) -> None:
        self.notes.append(message)
        warnings.warn(message, DegradedInputWarning, stacklevel=3)

    def _step_model(self, meta: SessionMeta) -> StepModel:
        cfg = self.config.gait
        profile = meta.user.step_model
        if cfg.step_length == "weinberg":
            if cfg.weinberg_k is not None:
                return WeinbergModel(k=cfg.weinberg_k)
            if profile and profile.get("kind") == "weinberg":
                return step_model_from_dict(profile)
            return WeinbergModel()
        if profile and profile.get("kind") == "frequency":
            return step_model_from_dict(profile)
        return FrequencyLawModel()

    def _activity_model(self) -> LdaModel | TreeThresholds | None:
        kind = self.config.gait.activity
        if kind == "lda":
            return LdaModel.default()
        if kind == "tree":
            return TreeThresholds()
        return None

    # ------------------------------------------------------------------ processing
    def run(self, session: Session) -> TrackResult:
        """Track a whole session (the same code path as the live chunks)."""
        imu = session.imu
        rate = imu.accel.rate_hz if imu is not None else 0.0
        t0 = session.time_span()[0]
        self.start(session.meta, session.landmarks, has_imu=imu is not None,
                   has_gyro=imu is not None and imu.gyro is not None,
                   has_mag=imu is not None and imu.mag is not None,
                   has_orientation=session.orientation is not None, rate_hz=rate, t0=t0)
        self.update(session)
        return self.finish()

    def update(self, chunk: Session) -> None:
        """Consume the samples and observations of one chunk (in time order across chunks)."""
        if not self._started:
            raise InputError("update() before start()", where="Tracker",
                             expected="start() (or run()) first")
        self._queue_observations(chunk)
        if chunk.imu is not None and self.gait is not None:
            t, acc, gyr, mag = chunk.imu.aligned()
            q_nd = self._attitude_update(chunk, t, acc, gyr, mag)
            result = self.gait.update(t, acc, q_nd)
            self._consume_gait(result, t, q_nd)
            self._t_last_sample = float(t[-1])
            # everything before the last classified sample is final
            if len(result.activity_t):
                self._horizon = max(self._horizon, float(result.activity_t[-1]))
        elif self.gait is None:
            self._horizon = max(self._horizon, chunk.time_span()[1])
        self._drain(self._horizon)

    def finish(self) -> TrackResult:
        """End of the recording: release held steps and observations, build the result."""
        if self.gait is not None:
            self._consume_gait(self.gait.flush(), None, None)
        self._drain(math.inf)
        trajectory = self._track.trajectory()
        steps = (StepEvents.empty() if not self._steps else _concat_steps(self._steps))
        attitude = AttitudeResult.concatenate(self._attitude) if self._attitude else None
        return TrackResult(trajectory, steps, attitude, list(self.diagnostics),
                           self._report(trajectory, steps))

    # ------------------------------------------------------------------ stages
    def _attitude_update(self, chunk: Session, t: np.ndarray, acc: np.ndarray,
                         gyr: np.ndarray | None, mag: np.ndarray | None) -> np.ndarray | None:
        filt = self.attitude_filter
        if filt is None:
            return None
        if isinstance(filt, DeviceOrientation):
            assert chunk.orientation is not None
            res = filt.run(chunk.orientation, t)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DegradedInputWarning)
                res = filt.update(t, acc, gyr, mag if self._use_mag else None)
        self._attitude.append(res)
        q = res.q
        if res.frame == "nb" and self.meta.mounting_q_bd is not None:
            q = quat_multiply(q, np.asarray(self.meta.mounting_q_bd, dtype=np.float64))
        self._var_yaw_t = res.t
        self._var_yaw = (res.var_rpy[:, 2] if res.var_rpy is not None
                         else np.full(len(res.t), 0.01))
        return np.asarray(q)

    def _consume_gait(self, result: GaitResult, t: np.ndarray | None,
                      q_nd: np.ndarray | None) -> None:
        if len(result.motion_sigma_m_s2) and t is not None:
            self._motion_t.append(t)
            self._motion_sigma.append(result.motion_sigma_m_s2)
        steps = result.steps
        if len(steps):
            self._steps.append(steps)
            for i in range(len(steps)):
                self._push(float(steps.t_end[i]), _STEP, i_payload=(steps, i))
        if self.config.prediction.model == "velocity" and len(result.velocity_t) and \
                q_nd is not None and t is not None:
            self._push_velocity(result, t, q_nd)

    def _push_velocity(self, result: GaitResult, t: np.ndarray, q_nd: np.ndarray) -> None:
        """Queue a velocity segment (Colombo eq. 16-17) as one event at its last sample."""
        vt = result.velocity_t
        q_bd = (np.array([1.0, 0, 0, 0]) if self.meta.mounting_q_bd is None
                else np.asarray(self.meta.mounting_q_bd, dtype=np.float64))
        q_nb = quat_multiply(q_nd, quat_conjugate(q_bd))
        fwd = quat_rotate(q_nb, np.array([1.0, 0.0, 0.0]))
        yaw_all = np.arctan2(fwd[:, 1], fwd[:, 0])
        idx = np.clip(np.searchsorted(t, vt), 0, len(t) - 1)
        var = np.interp(vt, self._var_yaw_t, self._var_yaw)
        self._push(float(vt[-1]), _STEP, i_payload=("velocity", vt, result.velocity_m_s,
                                                     yaw_all[idx], var))

    def _push(self, t: float, kind: int, *, i_payload: Any) -> None:
        self._seq += 1
        heapq.heappush(self._pending, (t, kind, self._seq, i_payload))

    def _queue_observations(self, chunk: Session) -> None:
        cfg = self.config
        if chunk.fixes is not None and cfg.fixes.enabled:
            f = chunk.fixes
            for i in range(len(f)):
                self._push(float(f.t[i]), _FIX, i_payload=(f.xyz[i], float(f.sigma_m[i]),
                                                           f.has_z))
        if chunk.rss is not None and cfg.rss.mode != "off":
            if cfg.rss.mode == "tight":
                keep = chunk.rss.rss_dbm >= cfg.rss.sensitivity_dbm
                for i in np.flatnonzero(keep):
                    self._push(float(chunk.rss.t[i]), _RSS,
                               i_payload=("reading", str(chunk.rss.anchor[i]),
                                          float(chunk.rss.rss_dbm[i])))
            else:
                for scan in group_scans(chunk.rss, self.landmarks, window_s=cfg.rss.window_s,
                                        sensitivity_dbm=cfg.rss.sensitivity_dbm):
                    self._push(scan.t, _RSS, i_payload=("scan", scan))
        if chunk.tags is not None and cfg.tags.enabled:
            from hrtls.fusion.tags import group_detections

            for t, ids in group_detections(chunk.tags, self.tag_corrector.params.group_window_s):
                self._push(t, _TAGS, i_payload=ids)
        if chunk.ranges is not None and cfg.ranges.enabled:
            r = chunk.ranges
            for i in range(len(r)):
                self._push(float(r.t[i]), _RANGE, i_payload=(str(r.node[i]), float(r.range_m[i]),
                                                             float(r.sigma_m[i])))

    # ------------------------------------------------------------------ event loop
    def _drain(self, horizon: float) -> None:
        while self._pending and self._pending[0][0] <= horizon:
            t, kind, _, payload = heapq.heappop(self._pending)
            if kind == _STEP:
                self._apply_motion(t, payload)
            else:
                self._advance_without_steps(t)
                self._apply_observation(t, kind, payload)
            self._track.add(self.state, self._last_activity)

    def _advance_without_steps(self, t: float) -> None:
        """Bring the state to ``t`` before a correction when no step or velocity drives it."""
        if t <= self.state.t:
            return
        if not self.has_imu:
            self.state = predict_random_walk(self.state, t, RandomWalkParams())
        else:
            self.state = self.state.evolve(t=t)

    def _apply_motion(self, t: float, payload: Any) -> None:
        if payload[0] == "velocity":
            _, vt, speed, yaw, var = payload
            keep = vt > self.state.t
            if np.any(keep):
                res = self.velocity_predictor.run(self.state, vt[keep], speed[keep], yaw[keep],
                                                  var[keep])
                self.state = res.state
            return
        steps, i = payload
        activity = int(steps.activity[i])
        self._last_activity = activity
        var_h = None
        if getattr(self, "_var_yaw", None) is not None and len(self._var_yaw):
            var_h = float(np.interp(t, self._var_yaw_t, self._var_yaw))
        heading = float(steps.heading_rad[i])
        if (self.heading_known and not self.state.has_input_heading
                and math.isfinite(heading)):
            # the start pose fixes the heading: the first step input only sets the reference
            self.state = self.state.evolve(input_heading_rad=heading, has_input_heading=True)
        self.state = self.step_predictor.predict(
            self.state, t=max(t, self.state.t), length_m=float(steps.length_m[i]),
            heading_rad=heading, dz_m=float(steps.dz_m[i]), activity=activity,
            var_heading_rad2=var_h)
        self._last_step_end = t
        if self.config.floor_snap and activity in (int(Activity.WALKING),
                                                   int(Activity.STANDING)):
            self.state, diag = floor_level_update(self.state, self.meta.floor_height_m,
                                                  gate_probability=None)

    def _moving(self, t: float) -> bool:
        if self._motion_t:
            mt = self._motion_t[-1]
            ms = self._motion_sigma[-1]
            for tt, ss in zip(reversed(self._motion_t), reversed(self._motion_sigma),
                              strict=True):
                if len(tt) and tt[0] <= t:
                    mt, ms = tt, ss
                    break
            return bool(np.interp(t, mt, ms) > MOVING_SIGMA_M_S2)
        return t - self._last_step_end < 1.5

    def _apply_observation(self, t: float, kind: int, payload: Any) -> None:
        cfg = self.config
        if kind == _FIX:
            xyz, sigma, has_z = payload
            upd = self.fix_corrector.update(self.state, self.fix_schedule, t=t, xyz=xyz,
                                            sigma_m=sigma, moving=self._moving(t), has_z=has_z)
            self.state, self.fix_schedule = upd.state, upd.schedule
            self.diagnostics.append(upd.diagnostics)
        elif kind == _RSS:
            self._apply_rss(t, payload)
        elif kind == _TAGS:
            ids: list[str] = payload
            upd = self.tag_corrector.update_ids(self.state, t=t, ids=ids,
                                                landmarks=self.landmarks, memory=self.tag_memory)
            self.state, self.tag_memory = upd.state, upd.memory
            self.diagnostics.extend(upd.diagnostics)
            if cfg.tags.bearing_correction and upd.strategy != -1:
                for tag_id in ids:
                    lm = self.landmarks.get(tag_id)
                    if lm is None or not lm.bearings_rad:
                        continue
                    hc = bearing_heading_correction(self.state, lm.bearings_rad, t=t,
                                                    source=tag_id)
                    self.state = hc.state
                    self.diagnostics.append(hc.diagnostics)
        elif kind == _RANGE:
            node, rng, sigma = payload
            lm = self.landmarks.get(node)
            if lm is None or lm.position is None:
                self.diagnostics.append(skipped("range", t, "node without a known position",
                                                node))
                return
            upd_r = range_update(self.state, lm.xyz(), rng, sigma, params=self.range_params,
                                 t=t, source=node)
            self.state = upd_r.state
            self.diagnostics.append(upd_r.diagnostics)

    def _apply_rss(self, t: float, payload: Any) -> None:
        cfg = self.config
        if payload[0] == "reading":
            _, anchor, value = payload
            lm = self.landmarks.get(anchor)
            if lm is None or lm.position is None:
                self.diagnostics.append(skipped("rss", t, "anchor without a known position",
                                                anchor))
                return
            model = self.path_loss
            if self.channel_estimator is not None and self.channel_state is not None:
                d_est = float(np.linalg.norm(self.state.x[:2] - lm.xyz()[:2]))
                self.channel_state, _ = self.channel_estimator.update(
                    self.channel_state, rss_dbm=[value], distance_m=[d_est],
                    distance_var_m2=float(np.trace(self.state.P[:2, :2])))
                model = self.channel_state.model()
            upd = rss_update(self.state, lm.xyz(), value, model,
                             gate_probability=cfg.gate_probability, t=t, source=anchor)
            self.state = upd.state
            self.diagnostics.append(upd.diagnostics)
            return
        scan = payload[1]
        if len(scan.anchor) < 3:
            self.diagnostics.append(skipped("rss", t, f"{len(scan.anchor)} anchors heard "
                                            "(WLS needs 3)", ",".join(scan.anchor)))
            return
        fix = scan_position(scan, self.path_loss)
        if cfg.rss.mode == "wls":
            # RSS alone: the estimate jumps to each WLS position (Tarrio's baseline)
            x = self.state.x.copy()
            x[:2] = fix.xy
            p = self.state.P.copy()
            p[:2, :] = 0.0
            p[:, :2] = 0.0
            p[:2, :2] = fix.cov
            self.state = self.state.evolve(t=t, x=x, P=p)
            return
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        res = kalman_update(self.state.x, self.state.P, h, fix.cov, fix.xy - self.state.x[:2],
                            gate_probability=cfg.gate_probability, kind="rss", t=t,
                            source=",".join(scan.anchor), angle_index=IH)
        self.state = self.state.evolve(x=res.x, P=res.P)
        self.diagnostics.append(res.diagnostics)

    # ------------------------------------------------------------------ report
    def _report(self, trajectory: Trajectory, steps: StepEvents) -> dict[str, Any]:
        counts = summarize(self.diagnostics)
        rejected = [d.to_dict() for d in self.diagnostics if d.status == "rejected"][:200]
        final = self.state
        report: dict[str, Any] = {
            "config": self.config.model_dump(),
            "attitude_method": self.attitude_method,
            "notes": self.notes,
            "corrections": counts,
            "rejected": rejected,
            "summary": {
                "duration_s": float(trajectory.t[-1] - trajectory.t[0]) if len(trajectory) else 0,
                "steps": len(steps),
                "distance_walked_m": steps.distance_m,
                "path_length_m": trajectory.path_length_m,
                "final_position_m": final.x[:3].tolist(),
                "final_sigma_xy_m": float(math.sqrt(max(np.trace(final.P[:2, :2]), 0.0) / 2)),
            },
        }
        if self.channel_state is not None and self.config.rss.mode != "off":
            report["channel"] = {"a_dbm": float(self.channel_state.theta[0]),
                                 "eta": float(self.channel_state.theta[1]),
                                 "sigma_db": math.sqrt(self.channel_state.residual_var_db2)}
        return report


def _concat_steps(parts: list[StepEvents]) -> StepEvents:
    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in parts])

    return StepEvents(cat("t_start"), cat("t_end"), cat("length_m"),
                      wrap_angle(cat("heading_rad")), cat("dz_m"), cat("activity"),
                      cat("frequency_hz"), cat("acc_max"), cat("acc_min"))
