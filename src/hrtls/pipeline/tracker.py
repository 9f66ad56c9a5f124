"""The tracker: attitude -> gait -> position filter with every correction, offline and live.

:class:`Tracker` coordinates the parts named by a :class:`~hrtls.pipeline.config.TrackerConfig`:
:mod:`~hrtls.pipeline.build` makes them, :mod:`~hrtls.pipeline.imu_stage` runs the per-sample
front end, :mod:`~hrtls.pipeline.schedule` buffers and groups the events,
:mod:`~hrtls.pipeline.engine` (with :mod:`~hrtls.pipeline.observations` and
:mod:`~hrtls.pipeline.step_scale`) applies them, :mod:`~hrtls.pipeline.report` writes the report.
``run(session)`` is ``start`` + one ``update`` with the whole session + ``finish``; the live
service calls ``update`` with successive chunks (a :class:`~hrtls.data.Session` holding the new
samples and observations, see :mod:`hrtls.pipeline.chunks`) and gets the same result.

Per-sample work (attitude, gait, velocity prediction) runs in the compiled kernels of those
stages. The position filter then handles *events* in time order -- steps, position fixes, RSS
readings or scans, tag reads, ranges. Runs of consecutive steps, RSS readings or scans,
ranges and fixes go through one compiled loop (:mod:`hrtls.pipeline._events`, the same maths as
the Python fusion parts, tested equal); tags, bearings, velocity segments, the fixes the loop
hands back (and, with the velocity-driven prediction, every observation) are handled one at a
time in Python (a few per second at most). Observations are held back until
the gait stage can no longer release a step before them (``LIVE_LATENCY_S``), tag reads and RSS
scans until their grouping window has closed, so a chunked run processes events in exactly the
order of an offline run.

Prediction ``model = "velocity"`` (Colombo eq. 15-17): the hybrid-automaton speed and the
attitude yaw are buffered and integrated up to each event; an accepted fix triggers the yaw
stretching of eq. 24-28 over the samples since the previous fix (:class:`StretchMemory`,
chord-rotation reading of :mod:`hrtls.fusion.yaw_stretch`). Reading of "fed back as the yaw
pseudo-measurement of the attitude filter": the attitude filter has already run over the chunk
when the fix is processed, so the correction is applied as a yaw offset to all later yaw inputs
(and to the state heading), which is what the Euler EKF's ``yaw_rad`` input would converge to
for a constant bias; the pseudo-measurements are kept in ``Tracker.yaw_pseudo`` (count in the
report). With ``model = "step"`` the same stretching uses the dead-reckoned chord between the
two fixes. Our additions (documented at the code): the step-length scale learned from absolute
corrections (``prediction.learn_step_scale``; walking and running steps separately), a running
factor from the user's profile (``k_running``), the compass correction of the device
orientation's yaw wander (``attitude.compass_yaw``, :mod:`hrtls.pipeline.compass`), the
fall-back to the thesis' tag strategies when every lobe of a read fails the Kalman gate, slots
of eq. 19 anchored at the first fix, and without an IMU a random walk or a grid filter.

Start pose time (``StartPose.t``): attitude and gait run from the first sample so the filters
have converged, the position starts at the pose's time; steps, velocity samples and
observations before it are ignored for position (counted in ``report["notes"]``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hrtls.attitude.base import AttitudeResult
from hrtls.attitude.device import DeviceOrientation
from hrtls.calibration.hard_iron_running import RunningHardIron, RunningHardIronParams
from hrtls.data import Landmark, OrientationSeries, Session, SessionMeta, StepEvents, Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import wrap_angle
from hrtls.fusion.fixes import YawPseudoMeasurement
from hrtls.fusion.gating import UpdateDiagnostics
from hrtls.fusion.state import FilterState
from hrtls.gait.analyzer import GaitAnalyzer, GaitResult
from hrtls.gait.step_length import StepModel
from hrtls.pipeline import build
from hrtls.pipeline import report as rep
from hrtls.pipeline.baro_stage import BaroStage
from hrtls.pipeline.build import RATE_SAMPLES as RATE_SAMPLES
from hrtls.pipeline.build import Notes, Sensors
from hrtls.pipeline.build import leading_rate_hz as leading_rate_hz
from hrtls.pipeline.compass import CompassParams, CompassYaw
from hrtls.pipeline.config import TrackerConfig, params_of
from hrtls.pipeline.corrections import Corrections
from hrtls.pipeline.engine import FusionEngine, GaitHistory
from hrtls.pipeline.imu_stage import (
    AttitudeStage,
    HeldImu,
    fit_hard_iron_offline,
    note_session_mounting,
    resolve_mounting,
)
from hrtls.pipeline.mounting import uses_handheld_mounting
from hrtls.pipeline.output import Estimates
from hrtls.pipeline.schedule import EventSchedule, PoseGate, chunk_end
from hrtls.pipeline.step_scale import StepScaleLearner, StepScaleParams

LIVE_LATENCY_S = 4.0
"""Events are held until the IMU stream is this far past them (late step detections), s."""


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
    diagnostics: Sequence[UpdateDiagnostics]
    report: dict[str, Any]


class Tracker:
    """Track one agent from a session (offline) or from chunks of it (live).

    A thin coordinator of its parts: :mod:`~hrtls.pipeline.build` (components from the
    configuration), :class:`~hrtls.pipeline.imu_stage.AttitudeStage` (per-sample front end),
    the gait stage, :class:`~hrtls.pipeline.schedule.EventSchedule` (buffers, grouping,
    horizon), :class:`~hrtls.pipeline.engine.FusionEngine` (position filter) and
    :mod:`~hrtls.pipeline.report`.

    Parameters
    ----------
    config:
        What to run; ``TrackerConfig()`` (the ``default`` preset) when None.
    keep_attitude:
        Keep the per-sample attitude for :attr:`TrackResult.attitude` (None without it): about
        64 bytes per IMU sample, which long recordings streamed in chunks may not want to hold.
    """

    schedule_class: type[EventSchedule] = EventSchedule
    """Scheduler of the events (a subclass may queue them differently, e.g. a test oracle)."""

    def __init__(self, config: TrackerConfig | None = None, *, keep_attitude: bool = True
                 ) -> None:
        self.config = config if config is not None else TrackerConfig()
        self.keep_attitude = keep_attitude
        self._started = False

    # ------------------------------------------------------------------ set-up
    def start(self, meta: SessionMeta, landmarks: dict[str, Landmark], *,
              has_imu: bool, has_gyro: bool, has_mag: bool, has_orientation: bool,
              rate_hz: float, t0: float) -> None:
        """Prepare for a recording with these sensors; the next ``update`` continues from t0.

        Nothing here looks at samples: the hand-held mounting (``[attitude] mounting``) is
        estimated once ``mounting_window_s`` of accelerometer samples from the start pose have
        arrived, the hard iron (``mag_hard_iron = "fit"``) by a running fit applied from the
        time it is accepted.
        """
        self._begin(meta, landmarks, Sensors(has_imu=has_imu, has_gyro=has_gyro,
                                             has_mag=has_mag, has_orientation=has_orientation,
                                             rate_hz=rate_hz, t0=t0))

    def _begin(self, meta: SessionMeta, landmarks: dict[str, Landmark], sensors: Sensors, *,
               fixed_mounting_acc: np.ndarray | None = None,
               fixed_hard_iron_ut: np.ndarray | None = None) -> None:
        """:meth:`start`; ``fixed_*``: the whole-recording estimates of ``[offline] two_pass``."""
        cfg = self.config
        s = sensors
        self.sensors = s
        self._start_meta = meta
        self._start_landmarks = landmarks
        self.notes = notes = Notes()
        self._base = rep.empty_base()
        self._two_pass = False
        self._mounting_pending = (uses_handheld_mounting(cfg.attitude.mounting, meta.placement)
                                  and s.has_imu)
        if self._mounting_pending and fixed_mounting_acc is not None:
            meta = resolve_mounting(meta, fixed_mounting_acc, notes, cfg.attitude)
            self._mounting_pending = False
        elif not self._mounting_pending:
            note_session_mounting(meta, notes)
        self.hard_iron_fixed_ut = fixed_hard_iron_ut
        self._held = HeldImu()
        self.meta = meta
        self.landmarks = _resolved(landmarks, meta)
        self.has_imu = s.has_imu
        pose = meta.start_pose or build.unknown_start(cfg, self.landmarks, notes,
                                                      has_imu=s.has_imu)
        # the agent is placed at the start pose's time; attitude and gait run from t0 so the
        # filters have converged by then, and earlier steps/observations are ignored for
        # position (counted in the notes at the end)
        self._pose = PoseGate(s.t0 if pose.t is None else max(float(pose.t), s.t0))
        state = FilterState.from_start_pose(pose, t=self._pose.t_pose)
        self._build_attitude(fixed_hard_iron_ut)
        # --- gait (with the hand-held mounting: once it is known)
        self.gait: GaitAnalyzer | None = None
        running_factor = 1.0
        self._step_model: StepModel | None = None
        if s.has_imu:
            self._step_model, running_factor = build.step_model(cfg.gait, meta)
            if not self._mounting_pending:
                self._build_gait()
        # --- position filter
        parts = build.corrections(cfg, meta, has_imu=s.has_imu, notes=notes)
        velocity_mode = cfg.prediction.model == "velocity" and s.has_imu
        self.schedule = self.schedule_class(cfg, self.landmarks, t0=s.t0, slow_only=velocity_mode,
                                      tag_window_s=parts.tag_corrector.params.group_window_s)
        self.history = GaitHistory()
        self.engine = FusionEngine(
            cfg, parts, state=state, landmarks=self.landmarks, schedule=self.schedule,
            pose=self._pose, scale=StepScaleLearner(params_of(
                StepScaleParams, cfg.prediction.step_scale)), gait=self.history,
            params=build.kernel_params(cfg, parts, floor_height_m=meta.floor_height_m,
                                       heading_known=pose.heading is not None,
                                       yaw_relative=build.yaw_relative(cfg, has_mag=s.has_mag),
                                       has_imu=s.has_imu),
            has_imu=s.has_imu, velocity_mode=velocity_mode, running_factor=running_factor,
            t0=s.t0, notes=notes)
        self.engine.attitude = self.attitude
        # --- heights and floors from the barometer (when the chunks bring pressure)
        self.baro = (BaroStage(floor_height_m=meta.floor_height_m, t_pose=self._pose.t_pose,
                               z_pose_m=float(state.x[2])) if cfg.barometer else None)
        self._t_last_sample = s.t0
        self._t_consumed = -math.inf
        self._started = True

    def _build_attitude(self, fixed_hard_iron_ut: np.ndarray | None) -> None:
        """The attitude stage (method, filter, running hard iron, compass) for ``self.sensors``."""
        cfg = self.config
        s = self.sensors
        hard_iron = None
        if cfg.attitude.mag_hard_iron == "fit" and s.has_imu and s.has_mag and \
                fixed_hard_iron_ut is None:
            hard_iron = RunningHardIron(RunningHardIronParams(
                block_samples=max(1, round(s.rate_hz))))
        self.attitude_method = build.attitude_method(cfg, s, self.notes)
        filt = build.attitude_filter(cfg, self.attitude_method)
        # only on the device's own orientation (a black-box AHRS whose yaw wanders); with the
        # hard iron already removed, the compass needs no warm-up of its own
        compass = (CompassYaw(self._pose.t_pose, CompassParams(
                       field_corrected=hard_iron is not None or fixed_hard_iron_ut is not None))
                   if cfg.attitude.compass_yaw and s.has_mag
                   and isinstance(filt, DeviceOrientation) else None)
        compass_heading = build.compass_heading(cfg, has_mag=s.has_mag)
        self.attitude = None if filt is None else AttitudeStage(
            filt, hard_iron=hard_iron, hard_iron_fixed_ut=fixed_hard_iron_ut, compass=compass,
            use_mag=cfg.attitude.use_magnetometer and s.has_mag and compass_heading is None,
            keep_attitude=self.keep_attitude, mag_blocks=compass_heading)
        self._hard_iron = hard_iron

    def set_landmarks(self, landmarks: dict[str, Landmark]) -> None:
        """Add or replace landmarks from now on (e.g. nodes localized during a mission).

        Observations queued before the call keep the position they were queued with; a
        snapshot taken afterwards restores the current versions.
        """
        if not self._started:
            raise InputError("set_landmarks() before start()", where="Tracker",
                             expected="start() first")
        self._start_landmarks = {**self._start_landmarks, **landmarks}
        self.landmarks.update(_resolved(landmarks, self.meta))

    def _build_gait(self) -> None:
        """The gait stage, for the mounting now known (``self.meta``)."""
        assert self._step_model is not None
        self.gait = build.gait_analyzer(self.config, rate_hz=self.sensors.rate_hz,
                                        model=self._step_model,
                                        attitude=self.attitude_method, meta=self.meta,
                                        notes=self.notes)

    # ------------------------------------------------------------------ what it learned
    @property
    def state(self) -> FilterState:
        """The position filter's state now."""
        return self.engine.state

    @property
    def yaw_pseudo(self) -> list[YawPseudoMeasurement]:
        """Yaw pseudo-measurements from the trajectory stretching (eq. 24-28)."""
        return self.engine.yaw_pseudo

    @property
    def fix_jumps(self) -> list[tuple[float, float, float]]:
        """Accepted fixes: (time of the row with the corrected state, east, north change, m)."""
        return self.engine.fix_jumps

    def corrections_since(self, index: int = 0) -> Corrections:
        """The updates that moved the position from record ``index`` on (``next_index``: on)."""
        return self.engine.corrections.since(index)

    @property
    def step_scale(self) -> float:
        """Learned walking step-length scale."""
        return self.engine.scale.step_scale

    @property
    def run_scale(self) -> float:
        """Learned running step-length scale."""
        return self.engine.scale.run_scale

    # ------------------------------------------------------------------ processing
    def run(self, session: Session) -> TrackResult:
        """Track a whole session (the same code path as the live chunks).

        With ``[offline] two_pass = true`` the hard iron and the hand-held mounting are first
        fitted on the whole recording and kept fixed; with ``grid_smoother`` the grid filter's
        rows are smoothed (offline only, both named in the report).
        """
        if self.config.offline.two_pass:
            self._start_two_pass(session)
        else:
            self.start_session(session)
        if self.config.offline.grid_smoother:
            self.engine.grid.keep_densities()
        self.update(session)
        return self.finish()

    def start_session(self, session: Session) -> None:
        """:meth:`start` with the sensors this session has.

        Of its samples only the first ``RATE_SAMPLES`` accelerometer times are read (the
        nominal rate: median spacing), so a session cut later starts the same tracker.
        """
        self._begin(session.meta, session.landmarks, Sensors.of_session(session))

    def _start_two_pass(self, session: Session) -> None:
        """``[offline] two_pass``: start with the whole recording's hard iron and mounting."""
        imu = session.imu
        offline_notes: list[tuple[bool, str]] = []
        acc_mount = hard_iron = None
        if imu is not None and uses_handheld_mounting(self.config.attitude.mounting,
                                                      session.meta.placement):
            # the walk starts at the start pose: samples before it (phone lying or being
            # picked up) would bias the mean tilt
            pose_t = session.meta.start_pose.t if session.meta.start_pose is not None else None
            ta = imu.accel.t
            sel = ta >= (float(ta[0]) if pose_t is None else max(float(ta[0]), float(pose_t)))
            acc_mount = imu.accel.values[sel] if sel.any() else imu.accel.values
        if imu is not None and imu.mag is not None and \
                self.config.attitude.mag_hard_iron == "fit":
            hard_iron = fit_hard_iron_offline(imu, offline_notes)
        self._begin(session.meta, session.landmarks, Sensors.of_session(session),
                    fixed_mounting_acc=acc_mount, fixed_hard_iron_ut=hard_iron)
        self._two_pass = True
        for degraded, text in offline_notes:
            (self.notes.degrade if degraded else self.notes.add)(text)

    def update(self, chunk: Session) -> None:
        """Consume the samples and observations of one chunk (in time order across chunks).

        Landmark versions due inside it (:meth:`update_landmarks`) are applied at their times.
        """
        if not self._started:
            raise InputError("update() before start()", where="Tracker",
                             expected="start() (or run()) first")
        for piece, due in self.engine.versions.cut(chunk, chunk_end(chunk)):
            if piece is not None:
                self._update_piece(piece)
            for version in due:
                self._apply_version(version)

    def update_landmarks(self, landmarks: Sequence[Landmark]) -> None:
        """New landmark versions (moved, destroyed, a hazard nearby) from their ``updated`` on.

        ``updated`` may not lie before the data already consumed
        (:mod:`hrtls.pipeline.landmark_updates`).
        """
        if not self._started:
            raise InputError("update_landmarks() before start()", where="Tracker",
                             expected="start() first")
        self.engine.versions.add(landmarks, t_now=self._t_consumed)

    def _apply_version(self, v: Landmark) -> None:
        lm = v if v.status == "destroyed" else _resolved({v.id: v}, self.meta)[v.id]
        self.notes.add(self.engine.versions.applied(lm, self.landmarks.pop(v.id, None)))
        self._start_landmarks = {k: x for k, x in self._start_landmarks.items() if k != v.id}
        if v.status != "destroyed":
            self.landmarks[v.id], self._start_landmarks[v.id] = lm, v

    def _update_piece(self, chunk: Session) -> None:
        self._t_consumed = max(self._t_consumed, chunk_end(chunk))
        sched = self.schedule
        sched.observations(self._pose.observations(chunk), self.notes,
                           channel_estimated=self.engine.parts.channel_estimator is not None,
                           has_channel=self.meta.channel is not None)
        if chunk.imu is not None and self.has_imu:
            t, acc, gyr, mag = chunk.imu.aligned()
            if self._mounting_pending:
                self._held.add(t, acc, gyr, mag, chunk.orientation)
                t_from = max(float(self._held.t[0]), self._pose.t_pose)
                if float(t[-1]) >= t_from + self.config.attitude.mounting_window_s:
                    self._release_held()
            else:
                self._process_imu(t, acc, gyr, mag, chunk.orientation)
        elif not self.has_imu:
            sched.horizon = max(sched.horizon, chunk_end(chunk))
            self.engine.grid.add(chunk, horizon=sched.horizon)
        if self.baro is not None:
            if chunk.pressure is not None:
                self.baro.add_pressure(chunk.pressure.t, chunk.pressure.values[:, 0])
            self.baro.advance(sched.horizon)
        # tag reads / RSS readings still being grouped hold back everything after them
        self.engine.drain(sched.release_limit())
        self.history.forget_motion_before(self.engine.state.t)

    def finish(self) -> TrackResult:
        """End of the recording: release held steps and observations, build the result."""
        if self._mounting_pending:   # shorter than the mounting window: what there is
            self._release_held()
        rep.note_hard_iron(self._hard_iron, self.notes)
        if self.gait is not None:
            self._consume_gait(self.gait.flush(), None, None)
        self.schedule.flush_all()
        eng = self.engine
        eng.drain(math.inf)
        if eng.velocity_mode:
            eng.track.add(eng.state, eng.last_activity)
        trajectory = eng.output_rows().trajectory()
        shown = self.history.steps[self.history.hidden:]
        steps = StepEvents.empty()
        if shown:
            steps = StepEvents.concatenate(shown)
            steps = replace(steps, heading_rad=wrap_angle(steps.heading_rad))
        floors: dict[str, Any] = {"source": "step model (barometer off)",
                                  "floor_height_m": self.meta.floor_height_m}
        if self.baro is not None:
            self.baro.finish()
            trajectory, rows_flat = self.baro.trajectory(trajectory)
            steps, steps_flat = self.baro.steps(steps)
            floors = self.baro.report(rows_relabelled=rows_flat, steps_relabelled=steps_flat)
        attitude = None if self.attitude is None else self.attitude.attitude()
        rep.final_notes(self.notes, self._pose, t0=self.sensors.t0, has_imu=self.has_imu,
                        seen_obs=self.schedule.seen_obs)
        report = rep.build_report(
            self.config, eng, self._base, trajectory=trajectory, steps=steps, notes=self.notes,
            attitude_method=self.attitude_method, two_pass=self._two_pass,
            compass=None if self.attitude is None else self.attitude.compass)
        report["floors"] = floors
        return TrackResult(trajectory, steps, attitude, eng.diagnostics, report)

    # ------------------------------------------------------------------ live reading
    def estimates_since(self, t_after_s: float = -math.inf) -> Estimates:
        """The trajectory rows produced so far with time > ``t_after_s`` (no :meth:`finish`).

        Rows are final except the last one: a later event at the same time replaces it (read
        again from the previous row's time to see it). After :meth:`restore`, rows from before
        the snapshot are not repeated.
        """
        if not self._started:
            raise InputError("estimates_since() before start()", where="Tracker",
                             expected="start() first")
        acc = self.engine.diagnostics.accepted_times()
        base = np.asarray(self._base["accepted_t"], dtype=np.float64)
        if len(base):
            acc = np.concatenate([base, acc])
        est = self.engine.output_rows().since(t_after_s, acc, self.meta.floor_height_m)
        if self.baro is None or not self.baro.active or not len(est):
            return est
        xyz, activity = self.baro.rows(est.t, est.xyz, est.activity)
        return replace(est, xyz=xyz, activity=activity,
                       floor=np.rint(xyz[:, 2] / self.meta.floor_height_m).astype(np.int64))

    # ------------------------------------------------------------------ snapshot / restore
    def snapshot(self) -> bytes:
        """The state as bytes (versioned, zlib + msgpack of plain values, no code).

        Holds what the tracker needs to continue (filters, gait and attitude states, held
        samples and events, learned scales, hard iron, mounting, report counters), not the
        rows already produced: read those with :meth:`estimates_since` first. A tracker from
        :meth:`restore` fed the rest of the data produces the same rows as this one would.
        """
        if not self._started:
            raise InputError("snapshot() before start()", where="Tracker",
                             expected="start() first")
        eng = self.engine
        s = self.sensors
        out: dict[str, Any] = {
            "config": self.config.model_dump(mode="json"),
            "start": {"meta": self._start_meta.model_dump(mode="json"),
                      "landmarks": {k: lm.model_dump(mode="json")
                                    for k, lm in self._start_landmarks.items()},
                      "has_imu": s.has_imu, "has_gyro": s.has_gyro, "has_mag": s.has_mag,
                      "has_orientation": s.has_orientation, "rate_hz": s.rate_hz, "t0": s.t0},
            "meta": self.meta.model_dump(mode="json"),
            "gait_built": self.gait is not None,
            "tracker": {"mounting_pending": self._mounting_pending,
                        "t_last_sample": self._t_last_sample, "two_pass": self._two_pass,
                        "t_consumed": self._t_consumed,
                        "hard_iron_fixed_ut": self.hard_iron_fixed_ut,
                        "notes": self.notes.items, "ignored": self._pose.ignored},
            "schedule": self.schedule.state(),
            "engine": eng.state_dict(),
            "scale": {k: getattr(eng.scale, k) for k in StepScaleLearner.STATE},
            "history": self.history.state(eng.state.t),
            "gait": None if self.gait is None else self.gait.state(strict_json=False),
            "attitude": None if self.attitude is None else self.attitude.state(),
            "held": {k: getattr(self._held, k) for k in HeldImu.STATE},
            "baro": None if self.baro is None else self.baro.state(),
            "diag": rep.carried(eng, self._base),
        }
        from hrtls.pipeline import snapshot as snap  # imported by the runs that snapshot
        return snap.pack(out)

    @classmethod
    def restore(cls, data: bytes) -> Tracker:
        """A tracker continuing from :meth:`snapshot` bytes (its configuration inside)."""
        from hrtls.pipeline import snapshot as snap
        d = snap.unpack(data)
        try:
            tr = cls(TrackerConfig.model_validate(d["config"]))
            a = d["start"]
            tr._begin(SessionMeta.model_validate(a["meta"]),
                      {k: Landmark.model_validate(v) for k, v in a["landmarks"].items()},
                      Sensors(has_imu=a["has_imu"], has_gyro=a["has_gyro"],
                              has_mag=a["has_mag"], has_orientation=a["has_orientation"],
                              rate_hz=a["rate_hz"], t0=a["t0"]),
                      fixed_hard_iron_ut=d["tracker"]["hard_iron_fixed_ut"])
            tr.meta = SessionMeta.model_validate(d["meta"])
            if d["gait_built"] and tr.gait is None:
                tr._build_gait()
            p = d["tracker"]
            tr._mounting_pending = p["mounting_pending"]
            tr._t_last_sample = p["t_last_sample"]
            tr._t_consumed = p.get("t_consumed", tr._t_last_sample)   # older snapshots
            tr._two_pass = p["two_pass"]
            tr.notes = Notes(p["notes"])
            tr._pose.ignored = p["ignored"]
            tr.schedule.restore(d["schedule"])
            tr.engine.restore(d["engine"])
            for k, v in d["scale"].items():
                setattr(tr.engine.scale, k, v)
            tr.history.restore(d["history"])
            if tr.gait is not None:
                tr.gait.restore(d["gait"])
            if tr.attitude is not None:
                tr.attitude.restore(d["attitude"])
            for k, v in d["held"].items():
                setattr(tr._held, k, v)
            if tr.baro is not None:
                tr.baro.restore(d["baro"])
            tr._base = d["diag"]
        except (KeyError, TypeError, ValueError) as exc:
            raise FormatError(f"incomplete or foreign snapshot ({exc!r})", where="snapshot",
                              expected="bytes from Tracker.snapshot()") from None
        return tr

    # ------------------------------------------------------------------ stages
    def _process_imu(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
                     mag: np.ndarray | None, orientation: OrientationSeries | None) -> None:
        """Attitude and gait over one chunk of aligned samples; advances the horizon."""
        assert self.gait is not None
        q_nd = None if self.attitude is None else self.attitude.update(
            t, acc, gyr, mag, orientation, mounting_q_bd=self.meta.mounting_q_bd,
            state_t=self.engine.state.t)
        result = self.gait.update(t, acc, q_nd)
        self._consume_gait(result, t, q_nd)
        self._t_last_sample = float(t[-1])
        # events before the last classified sample are final, except steps the detector
        # may still report (it needs up to LIVE_LATENCY_S of later samples)
        if len(result.activity_t):
            sched = self.schedule
            sched.horizon = max(sched.horizon, min(float(result.activity_t[-1]),
                                                   float(t[-1]) - LIVE_LATENCY_S))

    def _release_held(self) -> None:
        """The mounting window has elapsed (or the recording ended): mounting, gait, samples."""
        held, cfg = self._held, self.config.attitude
        self._mounting_pending = False
        if not len(held.t):
            self.meta = resolve_mounting(self.meta, np.zeros((0, 3)), self.notes, cfg)
            self._build_gait()
            return
        t_from = max(float(held.t[0]), self._pose.t_pose)
        sel = (held.t >= t_from) & (held.t < t_from + cfg.mounting_window_s)
        self.meta = resolve_mounting(self.meta, held.acc[sel], self.notes, cfg)
        self._build_gait()
        self._held = HeldImu()
        self._process_imu(held.t, held.acc, held.gyr, held.mag, held.orientation())

    def _consume_gait(self, result: GaitResult, t: np.ndarray | None,
                      q_nd: np.ndarray | None) -> None:
        hist = self.history
        if self.baro is not None:
            self.baro.add_steps(result.steps.t_end, result.steps.t_start, result.steps.dz_m)
        if len(result.motion_sigma_m_s2) and t is not None:
            hist.motion_t.append(t)
            hist.motion_sigma.append(result.motion_sigma_m_s2)
        steps = result.steps
        if len(steps):
            hist.steps.append(steps)
            before = ~self._pose.keep("steps", steps.t_end)
            if before.any():
                steps = steps.select(~before)
        eng = self.engine
        if len(steps) and not eng.velocity_mode:
            rows = np.full((len(steps), 5), np.nan)
            rows[:, 0] = steps.length_m
            rows[:, 1] = steps.heading_rad
            rows[:, 2] = steps.dz_m
            rows[:, 3] = steps.activity
            self.schedule.steps(steps.t_end, rows)
        if eng.velocity_mode and len(result.velocity_t) and q_nd is not None \
                and t is not None:
            eng.buffer_velocity(result, t, q_nd, self.meta.mounting_q_bd)


def _resolved(landmarks: dict[str, Landmark], meta: SessionMeta) -> dict[str, Landmark]:
    """The landmarks with their local positions (where known); destroyed ones are left out."""
    geo = None if meta.georeference is None else meta.georeference.to_georeference()
    return {k: lm.resolved(geo) if (lm.position is not None or geo is not None) else lm
            for k, lm in landmarks.items() if lm.status != "destroyed"}
