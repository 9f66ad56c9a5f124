"""The tracker: attitude -> gait -> position filter with every correction, offline and live.

:class:`Tracker` wires the parts named by a :class:`~hrtls.pipeline.config.TrackerConfig`.
``run(session)`` is ``start`` + one ``update`` with the whole session + ``finish``; the live
service calls ``update`` with successive chunks (a :class:`~hrtls.data.Session` holding the new
samples and observations, see :mod:`hrtls.pipeline.chunks`) and gets the same result.

Per-sample work (attitude, gait, velocity prediction) runs in the compiled kernels of those
stages. The position filter then handles *events* in time order -- steps, position fixes, RSS
readings or scans, tag reads, ranges. Runs of consecutive steps, RSS readings or scans and
ranges go through one compiled loop (:mod:`hrtls.pipeline._events`, the same maths as the
Python fusion parts, tested equal); fixes, tags, bearings and velocity segments (and, with the
velocity-driven prediction, every observation) are handled one at a time in Python (a few per
second at most). Observations are held back until
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
of eq. 19 anchored at the first fix, and the random-walk prediction without an IMU.

Start pose time (``StartPose.t``): attitude and gait run from the first sample so the filters
have converged, the position starts at the pose's time; steps, velocity samples and
observations before it are ignored for position (counted in ``report["notes"]``).
"""

from __future__ import annotations

import heapq
import math
import warnings
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hrtls.attitude.base import AttitudeFilter, AttitudeResult
from hrtls.attitude.device import DeviceOrientation
from hrtls.attitude.registry import make_filter
from hrtls.calibration.hard_iron import fit_hard_iron
from hrtls.calibration.hard_iron_running import RunningHardIron, RunningHardIronParams
from hrtls.data import (
    Activity,
    ImuStream,
    Landmark,
    OrientationSeries,
    Session,
    SessionMeta,
    StartPose,
    StepEvents,
    Trajectory,
)
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.errors import DegradedInputWarning, FormatError, InputError
from hrtls.frames import quat_conjugate, quat_multiply, wrap_angle
from hrtls.fusion.channel import ChannelEstimator, ChannelState
from hrtls.fusion.fixes import (
    DRIFT_MIN_PATH_M,
    FixCorrector,
    FixParams,
    FixSchedule,
    StretchMemory,
    YawPseudoMeasurement,
    partial_step,
    step_in_progress,
)
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    kalman_update,
    skipped,
)
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.random_walk import RandomWalkParams, predict_random_walk
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.rss import rss_update
from hrtls.fusion.rss_scans import scan_position, scan_table
from hrtls.fusion.state import IH, FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import (
    TagCorrector,
    TagMemory,
    TagParams,
    bearing_heading_correction,
    group_detections,
)
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor
from hrtls.fusion.yaw_stretch import YawStretchParams, stretch_yaw
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds
from hrtls.gait.analyzer import GaitAnalyzer, GaitResult
from hrtls.gait.missed_steps import MissedStepParams
from hrtls.gait.peak_steps import PeakStepDetector
from hrtls.gait.pll import PllStepDetector
from hrtls.gait.step_length import FrequencyLawModel, StepModel, WeinbergModel, step_model_from_dict
from hrtls.gait.step_length_pendulum import PendulumModel
from hrtls.gait.velocity_automaton import VelocityAutomaton
from hrtls.gait.walking_bouts import WalkingBoutParams
from hrtls.pipeline import _events as ev
from hrtls.pipeline import snapshot as snap
from hrtls.pipeline.compass import CompassParams, CompassYaw
from hrtls.pipeline.config import TrackerConfig, preset
from hrtls.pipeline.diagnostics import DiagnosticsBlock, DiagnosticsLog
from hrtls.pipeline.mounting import handheld_mounting_q_bd
from hrtls.pipeline.output import Estimates, TrackRows

FloatArray = np.ndarray

# event kinds in the order they are applied when they share a time
_STEP, _FIX, _RSS, _TAGS, _RANGE, _BEARING = 0, 1, 2, 3, 4, 5
MOVING_SIGMA_M_S2 = 0.2
"""Colombo's sigma_min: the user moves when the 2 s std of vertical acceleration exceeds it."""
LIVE_LATENCY_S = 4.0
"""Events are held until the IMU stream is this far past them (late step detections), s."""
FLOOR_SIGMA_M = 0.1
"""1-sigma of the floor-level pseudo-measurement after a flat step (m)."""
RSS_MIN_DISTANCE_M = 0.5
"""Tight RSS readings are not used when the estimate is nearer than this to the anchor (m)."""
BEARING_TURN_WINDOW_S = 3.0
"""Steps from this long before a tag read to its confirmation must agree within
``tags.bearing_max_turn_deg`` for the read's bearing to be used, s."""
SCALE_MIN_BASELINE_M = 8.0
"""Shortest straight stretch between two absolute corrections that teaches the step scale, m."""
SCALE_GAIN = 0.25
"""Fraction (as a power) of each measured step-length ratio applied to the scale."""
SCALE_BOUNDS = (0.8, 1.25)
"""Admissible step-length scale."""
VELOCITY_ROW_PERIOD_S = 0.04
"""Output period of the trajectory rows of the velocity-driven prediction (s)."""
DEFAULT_VAR_YAW_RAD2 = 0.01
"""Yaw variance when the attitude filter gives none (rad^2)."""
RATE_SAMPLES = 512
"""Leading accelerometer samples whose median spacing gives the nominal rate (start_session)."""
SCAN_ROWS_TRIM = 4096
"""Stored anchors of queued RSS scans are trimmed once there are this many (rows)."""


def hard_iron_samples(imu: ImuStream, window_s: float = 0.0
                      ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Magnetometer samples and mean up direction for the hard-iron fit of :meth:`Tracker.start`.

    The first ``window_s`` of the magnetometer (0: all of it) and the mean accelerometer
    reading over the same time; ``(None, None)`` without a magnetometer.
    """
    if imu.mag is None or not len(imu.mag.t):
        return None, None
    tm = imu.mag.t
    n_mag = int(np.searchsorted(tm, tm[0] + window_s)) if window_s > 0 else len(tm)
    n_mag = max(n_mag, 1)
    ta = imu.accel.t
    a0, a1 = np.searchsorted(ta, [tm[0], tm[n_mag - 1]], side="left")
    acc = imu.accel.values[a0:a1 + 1] if a1 >= a0 else imu.accel.values
    up = acc.mean(axis=0)
    if not np.all(np.isfinite(up)):
        up = np.nanmean(acc, axis=0)
    return imu.mag.values[:n_mag], up


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


class _HeldImu:
    """IMU samples held until the hand-held mounting window has elapsed (aligned arrays)."""

    def __init__(self) -> None:
        self.t = np.zeros(0)
        self.acc = np.zeros((0, 3))
        self.gyr: np.ndarray | None = None
        self.mag: np.ndarray | None = None
        self.ot = np.zeros(0)
        self.oq = np.zeros((0, 4))
        self.has_orientation = False

    def add(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
            mag: np.ndarray | None, orientation: OrientationSeries | None) -> None:
        first = not len(self.t)
        self.t = np.concatenate([self.t, t])
        self.acc = np.concatenate([self.acc, acc])
        if gyr is not None:
            self.gyr = gyr.copy() if first or self.gyr is None else np.concatenate([self.gyr, gyr])
        if mag is not None:
            self.mag = mag.copy() if first or self.mag is None else np.concatenate([self.mag, mag])
        if orientation is not None:
            self.has_orientation = True
            self.ot = np.concatenate([self.ot, orientation.t])
            self.oq = np.concatenate([self.oq, orientation.q])

    def orientation(self) -> OrientationSeries | None:
        return OrientationSeries(self.ot, self.oq) if self.has_orientation else None


class Tracker:
    """Track one agent from a session (offline) or from chunks of it (live).

    Parameters
    ----------
    config:
        What to run; the ``default`` preset when None.
    keep_attitude:
        Keep the per-sample attitude for :attr:`TrackResult.attitude` (None without it): about
        64 bytes per IMU sample, which long recordings streamed in chunks may not want to hold.
    """

    def __init__(self, config: TrackerConfig | None = None, *, keep_attitude: bool = True
                 ) -> None:
        self.config = config if config is not None else preset("default")
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
        self._begin(meta, landmarks, has_imu=has_imu, has_gyro=has_gyro, has_mag=has_mag,
                    has_orientation=has_orientation, rate_hz=rate_hz, t0=t0)

    def _begin(self, meta: SessionMeta, landmarks: dict[str, Landmark], *,
               has_imu: bool, has_gyro: bool, has_mag: bool, has_orientation: bool,
               rate_hz: float, t0: float, fixed_mounting_acc: np.ndarray | None = None,
               fixed_hard_iron_ut: np.ndarray | None = None) -> None:
        """:meth:`start`; ``fixed_*``: the whole-recording estimates of ``[offline] two_pass``."""
        cfg = self.config
        self._start_args: dict[str, Any] = {
            "meta": meta.model_dump(mode="json"),
            "landmarks": {k: lm.model_dump(mode="json") for k, lm in landmarks.items()},
            "has_imu": has_imu, "has_gyro": has_gyro, "has_mag": has_mag,
            "has_orientation": has_orientation, "rate_hz": rate_hz, "t0": t0}
        self.notes: list[str] = []
        self._steps_hidden = 0
        self._diag_base: dict[str, Any] = {"counts": {}, "rejected": [], "accepted_t": [],
                                           "yaw_pseudo": 0}
        self._two_pass = False
        self._mounting_pending = cfg.attitude.mounting == "handheld" and has_imu
        if self._mounting_pending and fixed_mounting_acc is not None:
            meta = self._resolve_mounting(meta, fixed_mounting_acc)
            self._mounting_pending = False
        elif not self._mounting_pending:
            self._note_session_mounting(meta)
        self.hard_iron_fixed_ut = fixed_hard_iron_ut
        self.hard_iron: RunningHardIron | None = None
        if cfg.attitude.mag_hard_iron == "fit" and has_imu and has_mag and \
                fixed_hard_iron_ut is None:
            self.hard_iron = RunningHardIron(RunningHardIronParams(
                block_samples=max(1, round(rate_hz))))
        self._rate_hz = rate_hz
        self._held = _HeldImu()
        self.meta = meta
        geo = None if meta.georeference is None else meta.georeference.to_georeference()
        self.landmarks = {k: lm.resolved(geo) if (lm.position is not None or geo is not None)
                          else lm for k, lm in landmarks.items()}
        self.diagnostics = DiagnosticsLog()
        self._track = TrackRows()
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
        self._var_t = np.zeros(0)
        self._var_v = np.zeros(0)
        self._vel_t = np.zeros(0)
        self._vel_v = np.zeros(0)
        self._vel_yaw = np.zeros(0)
        self._vel_var = np.zeros(0)
        self._yaw_offset = 0.0
        self._vel_bin = -math.inf
        self._stretch: StretchMemory | None = None
        self._corrected_since_fix = False
        self._last_speed = 0.0
        self.fix_jumps: list[tuple[float, float, float]] = []
        """Accepted fixes: time of the output row holding the corrected state, position change
        (east, north) made by the fix, m."""
        self.step_scale = 1.0
        self.run_scale = 1.0
        self._anchor_xy: np.ndarray | None = None
        self._path_since_anchor = 0.0
        self._run_since_anchor = 0.0
        self._soft_since_anchor = False
        self._recent_heading: deque[tuple[float, float]] = deque(maxlen=16)
        self.yaw_pseudo: list[YawPseudoMeasurement] = []
        self._rss_note = False
        self._seen_obs = False
        self._bulk_t = np.zeros(0)
        self._bulk_k = np.zeros(0, dtype=np.int64)
        self._bulk_seq = np.zeros(0, dtype=np.int64)
        self._bulk_ev = np.zeros(0, dtype=np.int64)
        self._bulk_data = np.zeros((0, 5))
        self._bulk_src = np.zeros(0, dtype=str)
        # diagnostics (kind, reason) of each buffer row, as codes into _label_kind/_reason
        self._bulk_label = np.zeros(0, dtype=np.int64)
        self._labels: dict[tuple[str, str], int] = {}
        self._label_kind = np.zeros(0, dtype=object)
        self._label_reason = np.zeros(0, dtype=object)
        self._bulk_i = 0
        self._bulk_count = 0
        self._t0 = t0
        self._tag_buf_t = np.zeros(0)
        self._tag_buf_id = np.zeros(0, dtype=str)
        self._scan_buf_t = np.zeros(0)
        self._scan_buf_a = np.zeros(0, dtype=str)
        self._scan_buf_v = np.zeros(0)
        self._scan_rows = np.zeros((0, 4))     # anchors of queued scans (kernel SC_* columns)
        self._scan_base = 0                    # absolute index of _scan_rows[0]
        self._avg_buf_t = np.zeros(0)
        self._avg_buf_a = np.zeros(0, dtype=str)
        self._avg_buf_v = np.zeros(0)
        if not has_imu:
            self.notes.append("no IMU: positions from the infrastructure alone, predicted by a "
                              "random walk between observations")
        pose = meta.start_pose or StartPose()
        self.heading_known = pose.heading is not None
        # the agent is placed at the start pose's time; attitude and gait run from t0 so the
        # filters have converged by then, and earlier steps/observations are ignored for
        # position (counted in the notes at the end)
        self._t_pose = t0 if pose.t is None else max(float(pose.t), t0)
        self._ignored_before_pose: dict[str, int] = {}
        self.state = FilterState.from_start_pose(pose, t=self._t_pose)
        self._track.add(self.state, int(Activity.UNKNOWN))
        # --- attitude
        self.attitude_filter: AttitudeFilter | DeviceOrientation | None = None
        method = cfg.attitude.method
        if method == "auto":
            method = "device" if has_orientation else "quat-ekf"
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
        # only on the device's own orientation (a black-box AHRS whose yaw wanders): our
        # filters already fuse the magnetometer with their own disturbance gates
        # with the hard iron already removed, the compass needs no warm-up of its own
        self._compass = (CompassYaw(self._t_pose, CompassParams(
                             field_corrected=self.hard_iron is not None
                             or self.hard_iron_fixed_ut is not None))
                         if cfg.attitude.compass_yaw and has_mag
                         and isinstance(self.attitude_filter, DeviceOrientation) else None)
        # --- gait (with the hand-held mounting: once it is known)
        self.gait: GaitAnalyzer | None = None
        self.running_factor = 1.0
        self._step_model_obj = self._step_model(meta) if has_imu else None
        if has_imu and not self._mounting_pending:
            self._build_gait()
        # --- position filter parts
        heading_mode = cfg.prediction.heading_mode
        self.step_predictor = StepPredictor(StepPredictionParams(
            q_along=cfg.prediction.q_along, q_across=cfg.prediction.q_across,
            heading_mode=heading_mode, stairs_from_model=cfg.prediction.stairs_from_model,
            sigma_heading_increment_rad=cfg.prediction.sigma_heading_increment_rad))
        self.fix_corrector = FixCorrector(FixParams(
            period_s=cfg.fixes.period_s, require_motion=cfg.fixes.require_motion,
            gate_probability=cfg.gate_probability if cfg.fixes.gate else None,
            max_consecutive_rejections=cfg.fixes.max_consecutive_rejections))
        self.fix_schedule = FixSchedule()
        self._fix_phase_set = False
        self.tag_corrector = TagCorrector(TagParams(
            strategy=cfg.tags.strategy, gate_probability=cfg.gate_probability,
            sigma_per_accuracy=cfg.tags.sigma_per_accuracy,
            repeat_interval_s=cfg.tags.repeat_interval_s))
        self.tag_fallback = (TagCorrector(replace(self.tag_corrector.params, strategy="paper"))
                             if cfg.tags.strategy == "kalman" else None)
        self.tag_memory = TagMemory()
        self.range_params = RangeParams(gate_probability=cfg.gate_probability)
        channel = meta.channel
        self.path_loss = (PathLossModel.from_channel(channel) if channel is not None
                          else PathLossModel(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
        # without an IMU the position comes from the RSS itself: estimating A and eta from the
        # same readings is circular (they drift together with the position), so keep the prior
        self.channel_estimator = (ChannelEstimator()
                                  if cfg.rss.estimate_channel and has_imu else None)
        if cfg.rss.estimate_channel and not has_imu:
            self.notes.append("no IMU: the RSS channel (A, eta) is not re-estimated online "
                              "(positions and channel would come from the same readings)")
        self.channel_state: ChannelState | None = (
            None if self.channel_estimator is None
            else self.channel_estimator.start(self.path_loss))
        self._velocity_mode = cfg.prediction.model == "velocity" and has_imu
        self.velocity_predictor = VelocityPredictor(VelocityPredictionParams(
            heading_mode=cfg.prediction.heading_mode))
        self._params = self._kernel_params()
        self._t_last_sample = t0
        self._started = True

    def _build_gait(self) -> None:
        """The gait stage, for the mounting now known (``self.meta``)."""
        cfg = self.config
        assert self._step_model_obj is not None
        self.gait = GaitAnalyzer(
            rate_hz=self._rate_hz,
            step_detector=PllStepDetector() if cfg.gait.step_detector == "pll"
            else PeakStepDetector(),
            step_model=self._step_model_obj,
            activity=self._activity_model(),
            heading=cfg.gait.heading if self.attitude_method != "none" else "fourier",
            velocity=VelocityAutomaton() if (cfg.gait.velocity_automaton
                                             or cfg.prediction.model == "velocity")
            else None,
            mounting_q_bd=None if self.meta.mounting_q_bd is None
            else np.asarray(self.meta.mounting_q_bd, dtype=np.float64),
            gate_steps_with_motion=cfg.gait.gate_steps_with_motion,
            walking_bouts=WalkingBoutParams() if cfg.gait.walking_bouts else None,
            missed_steps=MissedStepParams() if cfg.gait.fill_missed_steps else None,
            step_yaw=cfg.gait.step_yaw,
            window_features=cfg.gait.activity != "motion",
        )
        if self.meta.mounting_q_bd is None and cfg.gait.heading == "yaw":
            self.notes.append("device mounting unknown: step headings follow the device x "
                              "axis; only their changes are used (heading in the state)")

    def _fit_hard_iron_offline(self, imu: ImuStream) -> np.ndarray | None:
        """``[offline] two_pass``: the hard iron fitted on the whole recording (or None, noted).

        Blocks of ``rate_hz`` magnetometer samples are averaged before the fit: one second when
        the magnetometer runs at the accelerometer rate, longer when it is slower.
        """
        mag, up_d = hard_iron_samples(imu)
        if mag is None:
            return None
        try:
            fit = fit_hard_iron(mag, up_d=up_d, block_samples=max(1, round(imu.accel.rate_hz)))
        except InputError as exc:
            self._offline_notes.append((True, f"magnetometer hard iron not fitted ({exc}); "
                                        "field used raw"))
            return None
        self._offline_notes.append((False,
            "magnetometer hard iron fitted on the whole recording's turns ([offline] two_pass):"
            f" c = [{', '.join(f'{v:.2f}' for v in fit.hard_iron_ut)}] uT, horizontal field "
            f"{fit.field_ut:.1f} uT, residual {fit.residual_ut:.2f} uT, {fit.arc_deg:.0f} deg "
            f"of turning, {fit.n_used} samples"))
        return fit.hard_iron_ut

    def _note_hard_iron(self) -> None:
        """Report line of the running hard-iron fit (at the end of the recording)."""
        hi = self.hard_iron
        if hi is None:
            return
        st = hi.state
        if not hi.accepted:
            self._degrade("magnetometer hard iron not fitted (no fit accepted: the walk turned "
                          "too little or the field was disturbed); field used raw")
            return
        self.notes.append(
            "magnetometer hard iron fitted on the turns so far (running fit, first accepted at "
            f"t = {st.t_accepted:.1f} s, {st.n_fits} fits): c = ["
            f"{', '.join(f'{v:.2f}' for v in st.c_ut)}] uT, horizontal field "
            f"{st.field_ut:.1f} uT, residual {st.residual_ut:.2f} uT, {st.arc_deg:.0f} deg "
            f"of turning, {st.n_used} block means; the field was used raw before")

    def _resolve_mounting(self, meta: SessionMeta, acc_d: np.ndarray) -> SessionMeta:
        """The session metadata with the hand-held mounting from these samples (noted)."""
        if len(acc_d):
            try:
                q_bd = handheld_mounting_q_bd(acc_d)
            except InputError as exc:  # e.g. a phone held upright: top edge vertical
                self._degrade(f"hand-held mounting not estimable ({exc}); using the "
                              "session's mounting")
                self._note_session_mounting(meta)
                return meta
            self.notes.append(
                "mounting: hand-held in front (device +y forward), tilt from the mean "
                f"specific force of {len(acc_d)} samples: q_bd = "
                f"[{', '.join(f'{v:.4f}' for v in q_bd)}]")
            return meta.model_copy(update={"mounting_q_bd": tuple(float(v) for v in q_bd)})
        self.notes.append("mounting 'handheld' asked but no accelerometer samples from the start "
                          "pose on; using the session's mounting")
        self._note_session_mounting(meta)
        return meta

    def _note_session_mounting(self, meta: SessionMeta) -> None:
        if meta.mounting_q_bd is not None:
            self.notes.append("mounting: from the session (meta.mounting_q_bd = "
                              f"[{', '.join(f'{v:.4f}' for v in meta.mounting_q_bd)}])")

    def _degrade(self, message: str) -> None:
        self.notes.append(message)
        warnings.warn(message, DegradedInputWarning, stacklevel=3)

    def _step_model(self, meta: SessionMeta) -> StepModel:
        cfg = self.config.gait
        profile = dict(meta.user.step_model)
        # our addition: a profile may carry the running steps' own factor (calibration walks
        # at walking and running pace); "k_running" with a Weinberg K, "running_factor" else
        k_run = profile.pop("k_running", None)
        run_factor = profile.pop("running_factor", None)
        self.running_factor = 1.0
        if profile.get("kind") == cfg.step_length:
            if k_run is not None and profile.get("k"):
                self.running_factor = float(k_run) / float(profile["k"])
            elif run_factor is not None:
                self.running_factor = float(run_factor)
            if not (0.5 <= self.running_factor <= 2.0):
                raise InputError(f"running step factor {self.running_factor:.3g}",
                                 where="user.step_model", expected="between 0.5 and 2")
        if cfg.step_length == "weinberg":
            if cfg.weinberg_k is not None:
                return WeinbergModel(k=cfg.weinberg_k)
            if profile and profile.get("kind") == "weinberg":
                return step_model_from_dict(profile)
            return WeinbergModel()
        if cfg.step_length == "pendulum":
            if profile and profile.get("kind") == "pendulum":
                return step_model_from_dict(profile)
            return PendulumModel()
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
        """Track a whole session (the same code path as the live chunks).

        With ``[offline] two_pass = true`` the hard iron and the hand-held mounting are first
        fitted on the whole recording and kept fixed (offline only, named in the report).
        """
        if self.config.offline.two_pass:
            self._start_two_pass(session)
        else:
            self.start_session(session)
        self.update(session)
        return self.finish()

    def start_session(self, session: Session) -> None:
        """:meth:`start` with the sensors this session has.

        Of its samples only the first ``RATE_SAMPLES`` accelerometer times are read (the
        nominal rate: median spacing), so a session cut later starts the same tracker.
        """
        self._begin(**self._session_sensors(session))

    @staticmethod
    def _session_sensors(session: Session) -> dict[str, Any]:
        imu = session.imu
        return {"meta": session.meta, "landmarks": session.landmarks, "has_imu": imu is not None,
                "has_gyro": imu is not None and imu.gyro is not None,
                "has_mag": imu is not None and imu.mag is not None,
                "has_orientation": session.orientation is not None,
                "rate_hz": _leading_rate_hz(imu.accel.t) if imu is not None else 0.0,
                "t0": session.time_span()[0]}

    def _start_two_pass(self, session: Session) -> None:
        """``[offline] two_pass``: start with the whole recording's hard iron and mounting."""
        imu = session.imu
        self._offline_notes: list[tuple[bool, str]] = []
        acc_mount = hard_iron = None
        if imu is not None and self.config.attitude.mounting == "handheld":
            # the walk starts at the start pose: samples before it (phone lying or being
            # picked up) would bias the mean tilt
            pose_t = session.meta.start_pose.t if session.meta.start_pose is not None else None
            ta = imu.accel.t
            sel = ta >= (float(ta[0]) if pose_t is None else max(float(ta[0]), float(pose_t)))
            acc_mount = imu.accel.values[sel] if sel.any() else imu.accel.values
        if imu is not None and imu.mag is not None and \
                self.config.attitude.mag_hard_iron == "fit":
            hard_iron = self._fit_hard_iron_offline(imu)
        notes = self._offline_notes
        self._begin(**self._session_sensors(session), fixed_mounting_acc=acc_mount,
                    fixed_hard_iron_ut=hard_iron)
        self._two_pass = True
        for degraded, text in notes:
            (self._degrade if degraded else self.notes.append)(text)

    def update(self, chunk: Session) -> None:
        """Consume the samples and observations of one chunk (in time order across chunks)."""
        if not self._started:
            raise InputError("update() before start()", where="Tracker",
                             expected="start() (or run()) first")
        self._queue_observations(chunk)
        if chunk.imu is not None and self.has_imu:
            t, acc, gyr, mag = chunk.imu.aligned()
            if self._mounting_pending:
                self._held.add(t, acc, gyr, mag, chunk.orientation)
                t_from = max(float(self._held.t[0]), self._t_pose)
                if float(t[-1]) >= t_from + self.config.attitude.mounting_window_s:
                    self._release_held()
            else:
                self._process_imu(t, acc, gyr, mag, chunk.orientation)
        elif not self.has_imu:
            self._horizon = max(self._horizon, _chunk_end(chunk))
        # tag reads / RSS readings still being grouped hold back everything after them
        limit = self._horizon
        for buf in (self._tag_buf_t, self._scan_buf_t, self._avg_buf_t):
            if len(buf):
                limit = min(limit, float(np.nextafter(buf[0], -np.inf)))
        self._drain(limit)

    def finish(self) -> TrackResult:
        """End of the recording: release held steps and observations, build the result."""
        if self._mounting_pending:   # shorter than the mounting window: what there is
            self._release_held()
        self._note_hard_iron()
        if self.gait is not None:
            self._consume_gait(self.gait.flush(), None, None)
        self._flush_tag_groups(math.inf)
        self._flush_scans(math.inf)
        self._flush_averages(math.inf)
        self._drain(math.inf)
        if self._velocity_mode:
            self._track.add(self.state, self._last_activity)
        trajectory = self._track.trajectory()
        shown = self._steps[self._steps_hidden:]
        steps = StepEvents.empty() if not shown else _concat_steps(shown)
        # one chunk (offline run): its result as is, no copy of the per-sample arrays
        attitude = (None if not self._attitude else self._attitude[0]
                    if len(self._attitude) == 1 else AttitudeResult.concatenate(self._attitude))
        return TrackResult(trajectory, steps, attitude, self.diagnostics,
                           self._report(trajectory, steps))


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
        acc = self.diagnostics.accepted_times()
        base = np.asarray(self._diag_base["accepted_t"], dtype=np.float64)
        if len(base):
            acc = np.concatenate([base, acc])
        return self._track.since(t_after_s, acc, self.meta.floor_height_m)

    # ------------------------------------------------------------------ snapshot / restore
    _PLAIN = ("_anchor_xy", "_avg_buf_a", "_avg_buf_t", "_avg_buf_v", "_bulk_count",
              "_corrected_since_fix", "_fix_phase_set", "_horizon", "_ignored_before_pose",
              "_labels", "_last_activity", "_last_speed", "_last_step_end",
              "_mounting_pending", "_path_since_anchor", "_pending", "_recent_heading",
              "_rss_note", "_run_since_anchor", "_scan_base", "_scan_buf_a", "_scan_buf_t",
              "_scan_buf_v", "_scan_rows", "_seen_obs", "_seq", "_soft_since_anchor",
              "_stretch", "_t_last_sample", "_tag_buf_id", "_tag_buf_t", "_var_t", "_var_v",
              "_vel_bin", "_vel_t", "_vel_v", "_vel_var", "_vel_yaw", "_yaw_offset",
              "channel_state", "fix_schedule", "notes", "run_scale", "step_scale", "state",
              "tag_memory", "_two_pass", "hard_iron_fixed_ut")
    _BULK = ("_bulk_t", "_bulk_k", "_bulk_seq", "_bulk_ev", "_bulk_data", "_bulk_src",
             "_bulk_label")
    _COMPASS = ("n_tot", "y_tot", "n_cur", "y_cur", "cur_block", "c", "radius", "history",
                "s1", "s2", "n_ref", "t_first", "smooth", "last_error")
    _HELD = ("t", "acc", "gyr", "mag", "ot", "oq", "has_orientation")

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
        st = self.state
        plain = {name: getattr(self, name) for name in self._PLAIN}
        i0 = self._bulk_i
        plain.update({name: getattr(self, name)[i0:] for name in self._BULK})
        plain["_label_kind"] = self._label_kind
        plain["_label_reason"] = self._label_reason
        # history the future still needs: the step block in progress, the motion blocks from
        # the latest one before the state's time, the last output row
        j = max([k for k, b in enumerate(self._steps) if len(b) and b.t_start[0] <= st.t],
                default=0)
        steps = self._steps[j:]
        m = max([k for k, b in enumerate(self._motion_t) if len(b) and b[0] <= st.t], default=0)
        rows = self._track
        last_row = None
        if rows.last_time() is not None:
            last_row = (float(rows.t[-1][-1]), rows.x[-1][-1], rows.cov[-1][-1],
                        float(rows.var_h[-1][-1]), int(rows.activity[-1][-1]))
        rejected = list(self._diag_base["rejected"])
        rejected += [d.to_dict() for d in self.diagnostics.first_rejected(200 - len(rejected))]
        acc_t = self.diagnostics.accepted_times()
        counts = self._report_counts()
        out: dict[str, Any] = {
            "config": self.config.model_dump(mode="json"),
            "start": self._start_args,
            "meta": self.meta.model_dump(mode="json"),
            "gait_built": self.gait is not None,
            "plain": plain,
            "steps": steps,
            "motion_t": self._motion_t[m:],
            "motion_sigma": self._motion_sigma[m:],
            "last_row": last_row,
            "fix_phase_s": self.fix_corrector.params.phase_s,
            "gait": None if self.gait is None else self.gait.state(),
            "attitude": (self.attitude_filter.state
                         if isinstance(self.attitude_filter, AttitudeFilter) else None),
            "compass": None if self._compass is None else {
                k: getattr(self._compass, k) for k in self._COMPASS},
            "hard_iron": None if self.hard_iron is None else self.hard_iron.state,
            "held": {k: getattr(self._held, k) for k in self._HELD},
            "diag": {"counts": counts, "rejected": rejected[:200],
                     "accepted_t": ([float(acc_t[-1])] if len(acc_t)
                                    else list(self._diag_base["accepted_t"])[-1:]),
                     "yaw_pseudo": self._diag_base["yaw_pseudo"] + len(self.yaw_pseudo)},
        }
        return snap.pack(out)

    def _report_counts(self) -> dict[str, dict[str, int]]:
        counts = self.diagnostics.counts()
        for kind, by_status in self._diag_base["counts"].items():
            d = counts.setdefault(kind, {})
            for status, n in by_status.items():
                d[status] = d.get(status, 0) + n
        return counts

    @classmethod
    def restore(cls, data: bytes) -> Tracker:
        """A tracker continuing from :meth:`snapshot` bytes (its configuration inside)."""
        d = snap.unpack(data)
        try:
            tr = cls(TrackerConfig.model_validate(d["config"]))
            a = d["start"]
            tr._begin(SessionMeta.model_validate(a["meta"]),
                      {k: Landmark.model_validate(v) for k, v in a["landmarks"].items()},
                      has_imu=a["has_imu"], has_gyro=a["has_gyro"], has_mag=a["has_mag"],
                      has_orientation=a["has_orientation"], rate_hz=a["rate_hz"], t0=a["t0"],
                      fixed_hard_iron_ut=d["plain"]["hard_iron_fixed_ut"])
            tr.meta = SessionMeta.model_validate(d["meta"])
            if d["gait_built"] and tr.gait is None:
                tr._build_gait()
            for name, value in d["plain"].items():
                setattr(tr, name, value)
            tr._bulk_i = 0
            tr._label_kind = np.asarray(d["plain"]["_label_kind"], dtype=object)
            tr._label_reason = np.asarray(d["plain"]["_label_reason"], dtype=object)
            tr._params = tr._kernel_params()
            tr._steps = list(d["steps"])
            tr._steps_hidden = len(tr._steps)
            tr._motion_t = list(d["motion_t"])
            tr._motion_sigma = list(d["motion_sigma"])
            tr._track = TrackRows()
            if d["last_row"] is not None:
                t_r, x_r, cov_r, var_r, act_r = d["last_row"]
                tr._track.add_block(np.array([t_r]), x_r[None, :], cov_r[None], np.array([var_r]),
                                    np.array([act_r]))
                tr._track.hidden = 1
            if tr._fix_phase_set:
                tr.fix_corrector = FixCorrector(replace(tr.fix_corrector.params,
                                                        phase_s=d["fix_phase_s"]))
            if tr.gait is not None:
                tr.gait.restore(d["gait"])
            if isinstance(tr.attitude_filter, AttitudeFilter):
                tr.attitude_filter.restore(d["attitude"])
            if tr._compass is not None:
                for k, v in d["compass"].items():
                    setattr(tr._compass, k, v)
            if tr.hard_iron is not None:
                tr.hard_iron.state = d["hard_iron"]
            for k, v in d["held"].items():
                setattr(tr._held, k, v)
            tr._diag_base = d["diag"]
        except (KeyError, TypeError, ValueError) as exc:
            raise FormatError(f"incomplete or foreign snapshot ({exc!r})", where="snapshot",
                              expected="bytes from Tracker.snapshot()") from None
        return tr

    # ------------------------------------------------------------------ stages
    def _kernel_params(self) -> np.ndarray:
        """Parameter record of the compiled event loop (see :mod:`hrtls.pipeline._events`)."""
        cfg = self.config
        return ev.loop_params(
            step=self.step_predictor.params, path_loss=self.path_loss,
            range_params=self.range_params,
            channel=None if self.channel_estimator is None else self.channel_estimator.params,
            random_walk=RandomWalkParams(), floor_snap=cfg.floor_snap,
            floor_height_m=self.meta.floor_height_m, floor_sigma_m=FLOOR_SIGMA_M,
            gate_probability=cfg.gate_probability, heading_known=self.heading_known,
            has_imu=self.has_imu, rss_min_distance_m=RSS_MIN_DISTANCE_M,
            scan_jump=cfg.rss.mode == "wls", scan_wls_covariance=cfg.rss.use_wls_covariance,
            scan_sigma_position_m=cfg.rss.sigma_position_m)

    def _process_imu(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
                     mag: np.ndarray | None, orientation: OrientationSeries | None) -> None:
        """Attitude and gait over one chunk of aligned samples; advances the horizon."""
        assert self.gait is not None
        q_nd = self._attitude_update(t, acc, gyr, mag, orientation)
        result = self.gait.update(t, acc, q_nd)
        self._consume_gait(result, t, q_nd)
        self._t_last_sample = float(t[-1])
        # events before the last classified sample are final, except steps the detector
        # may still report (it needs up to LIVE_LATENCY_S of later samples)
        if len(result.activity_t):
            self._horizon = max(self._horizon, min(float(result.activity_t[-1]),
                                                   float(t[-1]) - LIVE_LATENCY_S))

    def _release_held(self) -> None:
        """The mounting window has elapsed (or the recording ended): mounting, gait, samples."""
        held = self._held
        self._mounting_pending = False
        if not len(held.t):
            self.meta = self._resolve_mounting(self.meta, np.zeros((0, 3)))
            self._build_gait()
            return
        t_from = max(float(held.t[0]), self._t_pose)
        sel = (held.t >= t_from) & (held.t < t_from + self.config.attitude.mounting_window_s)
        self.meta = self._resolve_mounting(self.meta, held.acc[sel])
        self._build_gait()
        self._held = _HeldImu()
        self._process_imu(held.t, held.acc, held.gyr, held.mag, held.orientation())

    def _hard_iron_at(self, t: np.ndarray, acc: np.ndarray, mag: np.ndarray
                      ) -> np.ndarray | None:
        """Hard iron in force at each sample (N, 3; NaN rows: not known yet), or None."""
        if self.hard_iron_fixed_ut is not None:
            return np.broadcast_to(self.hard_iron_fixed_ut, mag.shape)
        if self.hard_iron is None:
            return None
        return self.hard_iron.update(t, mag, acc)

    def _attitude_update(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
                         mag: np.ndarray | None, orientation: OrientationSeries | None
                         ) -> np.ndarray | None:
        filt = self.attitude_filter
        if filt is None:
            return None
        c_of = None if mag is None else self._hard_iron_at(t, acc, mag)
        if mag is not None and c_of is not None:
            mag = mag - np.nan_to_num(c_of, nan=0.0)
        if isinstance(filt, DeviceOrientation):
            assert orientation is not None
            res = filt.run(orientation, t)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DegradedInputWarning)
                res = filt.update(t, acc, gyr, mag if self._use_mag else None)
        if self.keep_attitude:
            self._attitude.append(res)
        q = res.q
        if res.frame == "nb" and self.meta.mounting_q_bd is not None:
            q = quat_multiply(q, np.asarray(self.meta.mounting_q_bd, dtype=np.float64))
        if self._compass is not None and mag is not None and len(mag) == len(res.t):
            q = self._compass.correct(res.t, np.asarray(q), mag, c_of)
        var = (res.var_rpy[:, 2] if res.var_rpy is not None
               else np.full(len(res.t), DEFAULT_VAR_YAW_RAD2))
        # keep the yaw variance of the samples later events may still need
        keep = self._var_t >= self.state.t - 5.0
        self._var_t = np.concatenate([self._var_t[keep], res.t])
        self._var_v = np.concatenate([self._var_v[keep], var])
        return np.asarray(q)

    def _var_yaw_at(self, t: np.ndarray) -> np.ndarray:
        if len(self._var_t) == 0:
            return np.full(np.shape(t), np.nan)
        return np.interp(t, self._var_t, self._var_v)

    def _consume_gait(self, result: GaitResult, t: np.ndarray | None,
                      q_nd: np.ndarray | None) -> None:
        if len(result.motion_sigma_m_s2) and t is not None:
            self._motion_t.append(t)
            self._motion_sigma.append(result.motion_sigma_m_s2)
        steps = result.steps
        if len(steps):
            self._steps.append(steps)
            before = ~self._ignore_before_pose("steps", steps.t_end)
            if before.any():
                steps = _select_steps(steps, ~before)
        if len(steps) and not self._velocity_mode:
            rows = np.full((len(steps), 5), np.nan)
            rows[:, 0] = steps.length_m
            rows[:, 1] = steps.heading_rad
            rows[:, 2] = steps.dz_m
            rows[:, 3] = steps.activity
            self._add_rows(_STEP, np.asarray(steps.t_end, dtype=np.float64),
                           np.full(len(steps), ev.EV_STEP, dtype=np.int64), rows,
                           np.full(len(steps), "", dtype=str))
        if self._velocity_mode and len(result.velocity_t) and q_nd is not None \
                and t is not None:
            self._buffer_velocity(result, t, q_nd)

    def _buffer_velocity(self, result: GaitResult, t: np.ndarray, q_nd: np.ndarray) -> None:
        """Keep the velocity samples (Colombo eq. 16-17 inputs) until events reach them."""
        vt = result.velocity_t
        q_bd = (np.array([1.0, 0, 0, 0]) if self.meta.mounting_q_bd is None
                else np.asarray(self.meta.mounting_q_bd, dtype=np.float64))
        idx = np.clip(np.searchsorted(t, vt), 0, len(t) - 1)
        # yaw of the body x axis (first column of the rotation matrix of q_nb)
        w, x, y, z = quat_multiply(q_nd[idx], quat_conjugate(q_bd)).T
        yaw = np.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))
        var = self._var_yaw_at(vt)
        var = np.where(np.isfinite(var), var, DEFAULT_VAR_YAW_RAD2)
        self._vel_t = np.concatenate([self._vel_t, vt])
        self._vel_v = np.concatenate([self._vel_v, np.maximum(result.velocity_m_s, 0.0)])
        self._vel_yaw = np.concatenate([self._vel_yaw, yaw])
        self._vel_var = np.concatenate([self._vel_var, var])

    def _velocity_to(self, t_end: float) -> None:
        """Colombo eq. 16-17 through the buffered samples up to ``t_end`` (rows at <= 25 Hz)."""
        n = int(np.searchsorted(self._vel_t, t_end, side="right"))
        if n == 0:
            return
        vt, vv = self._vel_t[:n], self._vel_v[:n]
        yaw = np.asarray(wrap_angle(self._vel_yaw[:n] + self._yaw_offset))
        var = self._vel_var[:n]
        self._vel_t, self._vel_v = self._vel_t[n:], self._vel_v[n:]
        self._vel_yaw, self._vel_var = self._vel_yaw[n:], self._vel_var[n:]
        keep = vt > self.state.t
        if self._t_pose > self._t0:
            self._ignore_before_pose("velocity samples", vt)
        if not np.any(keep):
            return
        vt, vv, yaw, var = vt[keep], vv[keep], yaw[keep], var[keep]
        self._path_since_anchor += float(np.sum(np.diff(vt, prepend=self.state.t) * vv))
        self._last_speed = float(vv[-1])
        res = self.velocity_predictor.run(self.state, vt, vv, yaw, var)
        self.state = res.state
        if self._stretch is not None:
            self._stretch = self._stretch.extended(vt, vv, yaw)
        # output rows: the first sample of every 40 ms bin (the same in chunked runs)
        bins = np.floor(vt / VELOCITY_ROW_PERIOD_S)
        sel = np.flatnonzero(np.diff(np.concatenate([[self._vel_bin], bins])) != 0)
        self._vel_bin = float(bins[-1])
        if len(sel) == 0:
            return
        x = np.column_stack([res.xyz[sel], res.heading_rad[sel]])
        act = np.where(vv[sel] > 0.05, int(Activity.WALKING), int(Activity.STANDING))
        self._last_activity = int(act[-1])
        self._track.add_block(vt[sel], x, res.cov_xy[sel], res.var_heading[sel], act)

    def _push(self, t: float, kind: int, *, i_payload: Any) -> None:
        self._seq += 1
        heapq.heappush(self._pending, (t, kind, self._seq, i_payload))

    def _ignore_before_pose(self, what: str, t: np.ndarray) -> np.ndarray:
        """Mask of the times at or after the start pose's time; counts the others."""
        keep = np.asarray(t, dtype=np.float64) >= self._t_pose
        n = int(len(keep) - np.count_nonzero(keep))
        if n:
            self._ignored_before_pose[what] = self._ignored_before_pose.get(what, 0) + n
        return keep

    def _from_pose(self, chunk: Session) -> Session:
        """The chunk's observations at or after the start pose's time (position starts there)."""
        parts: dict[str, Any] = {}
        f = chunk.fixes
        if f is not None and not (m := self._ignore_before_pose("fixes", f.t)).all():
            parts["fixes"] = PositionFixes(f.t[m], f.xyz[m], f.sigma_m[m], f.has_z) \
                if m.any() else None
        r = chunk.rss
        if r is not None and not (m := self._ignore_before_pose("rss", r.t)).all():
            parts["rss"] = RssReadings(r.t[m], r.anchor[m], r.rss_dbm[m]) if m.any() else None
        g = chunk.tags
        if g is not None and not (m := self._ignore_before_pose("tags", g.t)).all():
            parts["tags"] = TagDetections(g.t[m], g.tag[m]) if m.any() else None
        n = chunk.ranges
        if n is not None and not (m := self._ignore_before_pose("ranges", n.t)).all():
            parts["ranges"] = RangeMeasurements(n.t[m], n.node[m], n.range_m[m],
                                                n.sigma_m[m]) if m.any() else None
        return chunk.with_parts(**parts) if parts else chunk

    def _queue_observations(self, chunk: Session) -> None:
        cfg = self.config
        chunk = self._from_pose(chunk)
        self._seen_obs = self._seen_obs or any(
            part is not None for part in (chunk.fixes, chunk.rss, chunk.tags, chunk.ranges))
        if chunk.fixes is not None and cfg.fixes.enabled:
            f = chunk.fixes
            for i in range(len(f)):
                self._push(float(f.t[i]), _FIX, i_payload=(f.xyz[i], float(f.sigma_m[i]),
                                                           f.has_z))
        if chunk.rss is not None and cfg.rss.mode != "off":
            if self.meta.channel is None and not self._rss_note:
                self._rss_note = True
                self.notes.append("no channel model in session.json: RSS starts from A = -59 "
                                  "dBm, eta = 2" + (" and re-estimates them online"
                                                    if self.channel_estimator is not None
                                                    else ""))
            if cfg.rss.mode == "tight":
                r = chunk.rss
                keep = r.rss_dbm >= cfg.rss.sensitivity_dbm
                if cfg.rss.average_s > 0:
                    self._avg_buf_t = np.concatenate([self._avg_buf_t, r.t[keep]])
                    self._avg_buf_a = np.concatenate([self._avg_buf_a,
                                                      r.anchor[keep].astype(str)])
                    self._avg_buf_v = np.concatenate([self._avg_buf_v, r.rss_dbm[keep]])
                else:
                    self._queue_tight(r.t[keep], r.anchor[keep].astype(str), r.rss_dbm[keep])
            else:
                r = chunk.rss
                self._scan_buf_t = np.concatenate([self._scan_buf_t, r.t])
                self._scan_buf_a = np.concatenate([self._scan_buf_a, r.anchor.astype(str)])
                self._scan_buf_v = np.concatenate([self._scan_buf_v, r.rss_dbm])
        if cfg.rss.mode in ("wls", "kalman"):
            self._flush_scans(_chunk_end(chunk))
        self._flush_averages(_chunk_end(chunk))
        if chunk.tags is not None and cfg.tags.enabled:
            g = chunk.tags
            self._tag_buf_t = np.concatenate([self._tag_buf_t, g.t])
            self._tag_buf_id = np.concatenate([self._tag_buf_id, g.tag.astype(str)])
        self._flush_tag_groups(_chunk_end(chunk))
        if chunk.ranges is not None and cfg.ranges.enabled:
            rm = chunk.ranges
            if self._velocity_mode:
                for i in range(len(rm)):
                    self._push(float(rm.t[i]), _RANGE, i_payload=(
                        str(rm.node[i]), float(rm.range_m[i]), float(rm.sigma_m[i])))
            else:
                self._add_bulk(_RANGE, rm.t, rm.node.astype(str), rm.range_m, rm.sigma_m)

    def _queue_tight(self, t: np.ndarray, anchor: np.ndarray, rss_dbm: np.ndarray) -> None:
        """Queue RSS readings for tight (per-reading) range updates."""
        if self._velocity_mode:
            for k in range(len(t)):
                self._push(float(t[k]), _RSS, i_payload=("reading", str(anchor[k]),
                                                         float(rss_dbm[k])))
        else:
            self._add_bulk(_RSS, t, anchor, rss_dbm, np.full(len(t), np.nan))

    def _flush_averages(self, t_seen: float) -> None:
        """Queue the per-beacon RSS means of the ``average_s`` windows that have closed.

        Windows run from the session start (``t0`` of :meth:`start`), so a chunked run closes
        the same windows as the offline run.
        """
        if len(self._avg_buf_t) == 0:
            return
        w = self.config.rss.average_s
        if math.isfinite(t_seen):
            end_bin = math.floor((t_seen - self._t0) / w)
            done = np.floor((self._avg_buf_t - self._t0) / w) < end_bin
        else:
            done = np.ones(len(self._avg_buf_t), dtype=bool)
        if not done.any():
            return
        avg = average_rss_per_anchor(
            RssReadings(self._avg_buf_t[done], self._avg_buf_a[done], self._avg_buf_v[done]),
            w, t_origin=self._t0)
        self._queue_tight(avg.t, avg.anchor.astype(str), avg.rss_dbm)
        self._avg_buf_t = self._avg_buf_t[~done]
        self._avg_buf_a = self._avg_buf_a[~done]
        self._avg_buf_v = self._avg_buf_v[~done]

    def _add_bulk(self, heap_kind: int, t: np.ndarray, src: np.ndarray, value: np.ndarray,
                  sigma: np.ndarray) -> None:
        """Queue tight RSS readings or ranges as sorted columns (no per-reading Python)."""
        n = len(t)
        if n == 0:
            return
        ev_kind = np.full(n, ev.EV_RSS if heap_kind == _RSS else ev.EV_RANGE, dtype=np.int64)
        data = np.full((n, 5), np.nan)
        data[:, 3] = value
        data[:, 4] = sigma
        names, inv = np.unique(src, return_inverse=True)
        for j, name in enumerate(names.tolist()):
            lm = self.landmarks.get(name)
            rows = inv == j
            if lm is None or lm.position is None:
                ev_kind[rows] = ev.EV_SKIP
            else:
                data[rows, :3] = lm.xyz()
        self._add_rows(heap_kind, np.asarray(t, dtype=np.float64), ev_kind, data, src)

    def _add_rows(self, heap_kind: int, t: np.ndarray, ev_kind: np.ndarray, data: np.ndarray,
                  src: np.ndarray, reason: np.ndarray | None = None) -> None:
        """Merge rows of the compiled loop into the sorted buffer (order: t, kind, arrival).

        ``reason``: text of the rows' diagnostics when skipped (default: the unknown
        anchor/node text on ``EV_SKIP`` rows).
        """
        n = len(t)
        i0 = self._bulk_i
        name = "rss" if heap_kind == _RSS else ("range" if heap_kind == _RANGE else "")
        label = np.full(n, self._label(name, ""), dtype=np.int64)
        if reason is None:
            skip = ev_kind == ev.EV_SKIP
            if skip.any():
                label[skip] = self._label(name, "anchor without a known position"
                                          if heap_kind == _RSS else "node without a known position")
        else:
            reason = np.asarray(reason, dtype=object)
            for text in set(reason.tolist()) - {""}:
                label[reason == text] = self._label(name, str(text))
        seq = self._bulk_count + np.arange(n)
        self._bulk_count += n
        bt = np.concatenate([self._bulk_t[i0:], t])
        bk = np.concatenate([self._bulk_k[i0:], np.full(n, heap_kind, dtype=np.int64)])
        bs = np.concatenate([self._bulk_seq[i0:], seq])
        order = np.lexsort((bs, bk, bt))
        self._bulk_t = bt[order]
        self._bulk_k = bk[order]
        self._bulk_seq = bs[order]
        self._bulk_ev = np.concatenate([self._bulk_ev[i0:], ev_kind])[order]
        self._bulk_data = np.concatenate([self._bulk_data[i0:], data])[order]
        self._bulk_src = np.concatenate([self._bulk_src[i0:], src])[order]
        self._bulk_label = np.concatenate([self._bulk_label[i0:], label])[order]
        self._bulk_i = 0

    def _label(self, kind: str, reason: str) -> int:
        """Code of a (diagnostics kind, reason) pair of buffer rows."""
        code = self._labels.get((kind, reason))
        if code is None:
            code = len(self._labels)
            self._labels[(kind, reason)] = code
            self._label_kind = np.array([*self._label_kind.tolist(), kind], dtype=object)
            self._label_reason = np.array([*self._label_reason.tolist(), reason], dtype=object)
        return code

    def _flush_tag_groups(self, t_seen: float) -> None:
        """Group tag reads whose grouping window has closed (the same in chunked runs)."""
        if len(self._tag_buf_t) == 0:
            return
        w = self.tag_corrector.params.group_window_s
        groups = group_detections(TagDetections(self._tag_buf_t, self._tag_buf_id), w)
        used = 0
        for t, ids in groups:
            first = float(self._tag_buf_t[used])
            if first + w >= t_seen:
                break
            self._push(t, _TAGS, i_payload=ids)
            used = int(np.searchsorted(self._tag_buf_t, first + w, side="right"))
        self._tag_buf_t = self._tag_buf_t[used:]
        self._tag_buf_id = self._tag_buf_id[used:]

    def _take_closed_scans(self, t_seen: float) -> RssReadings | None:
        """Remove and return the buffered RSS readings whose window closed before ``t_seen``.

        Windows are ``window_s`` long from the session start; None when no reading is due.
        """
        if len(self._scan_buf_t) == 0:
            return None
        n = len(self._scan_buf_t)
        if math.isfinite(t_seen):
            w = self.config.rss.window_s
            end_bin = math.floor((t_seen - self._t0) / w)
            n = int(np.count_nonzero(np.floor((self._scan_buf_t - self._t0) / w) < end_bin))
        if n == 0:
            return None
        readings = RssReadings(self._scan_buf_t[:n], self._scan_buf_a[:n], self._scan_buf_v[:n])
        self._scan_buf_t = self._scan_buf_t[n:]
        self._scan_buf_a = self._scan_buf_a[n:]
        self._scan_buf_v = self._scan_buf_v[n:]
        return readings

    def _flush_scans(self, t_seen: float) -> None:
        """Average RSS over windows of ``window_s`` from the session start once they closed."""
        readings = self._take_closed_scans(t_seen)
        if readings is None:
            return
        w = self.config.rss.window_s
        table = scan_table(readings, self.landmarks, window_s=w,
                           sensitivity_dbm=self.config.rss.sensitivity_dbm, t_origin=self._t0)
        if self._velocity_mode:
            for scan in table.scans():
                self._push(scan.t, _RSS, i_payload=("scan", scan))
        elif len(table):
            # compiled loop: rows [first anchor row (absolute), number of anchors]
            start = self._scan_base + len(self._scan_rows)
            self._scan_rows = np.concatenate([self._scan_rows, np.column_stack(
                [table.anchor_xyz[:, :2], table.rss_dbm, table.n_readings])])
            data = np.full((len(table), 5), np.nan)
            data[:, 0] = start + table.first
            data[:, 1] = table.count
            src = np.array([",".join(table.anchor[a:a + c].tolist())
                            for a, c in zip(table.first.tolist(), table.count.tolist(),
                                            strict=True)], dtype=str)
            reason = np.full(len(table), "", dtype=object)
            few = np.flatnonzero(table.count < 3)
            reason[few] = [f"{c} anchors heard (WLS needs 3)" for c in table.count[few].tolist()]
            self._add_rows(_RSS, table.t, np.full(len(table), ev.EV_SCAN, dtype=np.int64),
                           data, src, reason)

    # ------------------------------------------------------------------ event loop
    def _drain(self, horizon: float) -> None:
        pending = self._pending
        while True:
            head = pending[0] if pending and pending[0][0] <= horizon else None
            bi = self._bulk_i
            bulk_next = bi < len(self._bulk_t) and self._bulk_t[bi] <= horizon
            if head is None and not bulk_next:
                break
            if head is not None and (not bulk_next or (head[0], head[1]) < (
                    float(self._bulk_t[bi]), int(self._bulk_k[bi]))):
                heapq.heappop(pending)
                t, kind, _, payload = head
                self._advance_without_steps(t)
                self._apply_observation(t, kind, payload)
                self._track.add(self.state, self._last_activity)
                continue
            # a fast run: buffer rows up to the next slow event (or the horizon)
            if head is not None:
                lim_t, lim_k = head[0], head[1]
                j = int(np.searchsorted(self._bulk_t, lim_t, side="left"))
                j2 = int(np.searchsorted(self._bulk_t, lim_t, side="right"))
                j += int(np.count_nonzero(self._bulk_k[j:j2] < lim_k))
            else:
                j = int(np.searchsorted(self._bulk_t, horizon, side="right"))
            j = max(j, bi + 1)
            self._run_kernel(bi, j)
            self._bulk_i = j
        if self._velocity_mode and math.isfinite(horizon):
            self._velocity_to(horizon)
        elif self._velocity_mode:
            self._velocity_to(math.inf)

    def _run_kernel(self, b0: int, b1: int) -> None:
        """Buffer rows ``b0:b1`` (steps, RSS readings or scans, ranges) in the compiled loop.

        The step scale, running factor, yaw offset and the yaw variance at each step are
        applied inside the kernel (``step_scale``, ``running_multiplier``, ``yaw_offset_rad`` of
        the loop state).
        """
        n = b1 - b0
        tt = self._bulk_t[b0:b1]
        kind = self._bulk_ev[b0:b1]
        data = self._bulk_data[b0:b1]
        st = self.state
        x = st.x.copy()
        p = st.P.copy()
        cstate = self.channel_state if self.channel_estimator is not None else None
        rec, chan_cov = ev.loop_state(
            st, path_loss=self.path_loss, channel=cstate, last_activity=self._last_activity,
            last_step_end_s=self._last_step_end, step_scale=self.step_scale,
            running_multiplier=self.running_factor * self.run_scale / self.step_scale,
            yaw_offset_rad=self._yaw_offset, scan_base=self._scan_base)
        t_out = np.empty(n)
        x_out = np.empty((n, 4))
        p_out = np.empty((n, 4, 4))
        act = np.empty(n, dtype=np.int64)
        status = np.empty(n, dtype=np.int64)
        nis = np.empty(n)
        s_out = np.empty(n)
        nu = np.empty(n)
        aux = np.empty((n, 5))
        recent = np.empty((ev.N_RECENT, 2))
        ev.event_kernel(kind, tt, data, self._params, rec, chan_cov, x, p, t_out, x_out, p_out,
                        act, status, nis, s_out, nu, self._scan_rows, aux, self._var_t,
                        self._var_v, recent)
        sc = rec[0]
        self.state = FilterState.from_kernel(float(sc["t"]), x, p, float(sc["input_heading_rad"]),
                                             bool(sc["has_input_heading"]),
                                             bool(sc["reference_pending"]))
        self._last_activity = int(sc["last_activity"])
        self._last_step_end = float(sc["last_step_end_s"])
        self._path_since_anchor += float(sc["path_m"])
        self._run_since_anchor += float(sc["running_path_m"])
        if cstate is not None:
            self.channel_state = ChannelState.from_record(sc["channel"], chan_cov)
        self._track.add_block(t_out, x_out, p_out[:, :2, :2], p_out[:, IH, IH], act)
        n_steps = int(sc["n_steps"])
        n_head = int(sc["n_headings"])
        if n_head:
            # the last raw step headings (before the yaw offset), for the turn test of bearings
            last = recent.tolist()
            if n_head > ev.N_RECENT:      # ring: oldest first
                cut = n_head % ev.N_RECENT
                last = last[cut:] + last[:cut]
            self._recent_heading.extend(
                (float(ts), float(hd)) for ts, hd in last[:min(n_head, ev.N_RECENT)])
        if n_steps < n:
            n_soft, n_scan_ok = int(sc["n_soft"]), int(sc["n_scan_accepted"])
            # an accepted scan (Kalman mode) counts as a correction since the last fix; the
            # WLS jump does not, and scans do not stop the step-scale learning
            self._corrected_since_fix = self._corrected_since_fix or n_soft + n_scan_ok > 0
            self._soft_since_anchor = self._soft_since_anchor or n_soft > 0
            obs = np.flatnonzero(kind != ev.EV_STEP) if n_steps else np.arange(n)
            self._kernel_diagnostics(b0, obs, status[obs], nis, s_out, nu, aux,
                                     sc["n_scans"] > 0)
            if len(self._scan_rows) >= SCAN_ROWS_TRIM:
                self._trim_scan_rows(b1)

    def _trim_scan_rows(self, b1: int) -> None:
        """Drop the stored scan anchors that no queued scan (buffer rows from ``b1``) needs."""
        pending = np.flatnonzero(self._bulk_ev[b1:] == ev.EV_SCAN)
        keep_from = (int(self._bulk_data[b1:][pending, 0].min()) if len(pending)
                     else self._scan_base + len(self._scan_rows))
        drop = keep_from - self._scan_base
        if drop > 0:
            self._scan_rows = self._scan_rows[drop:]
            self._scan_base = keep_from

    def _kernel_diagnostics(self, b0: int, obs: np.ndarray, code: np.ndarray, nis: np.ndarray,
                            s: np.ndarray, nu: np.ndarray, aux: np.ndarray,
                            has_scans: bool) -> None:
        """One diagnostics block for the observation rows ``obs`` (relative to ``b0``)."""
        rows = obs + b0
        labels = self._bulk_label[rows]
        reasons = self._label_reason[labels]
        dof = nu2 = s2 = None
        if has_scans:
            is_scan = self._bulk_ev[rows] == ev.EV_SCAN
            dof = np.where(is_scan, 2, 1)
            # a scan with < 3 anchors is "skipped" (its reason was set when it was queued)
            code = np.where(code == ev.ST_FEW, ev.ST_SKIPPED, code)
            reasons = np.where(code == ev.ST_COLLINEAR, "anchors are collinear",
                               np.where(code == ev.ST_WLS, "WLS position (RSS alone)",
                                        reasons))
            nu2 = aux[obs, :2]
            s2 = aux[obs, 2:5]
        self.diagnostics.add_block(DiagnosticsBlock(
            self._label_kind[labels], self._bulk_t[rows], code, nis[obs], s[obs], nu[obs],
            self._bulk_src[rows], reasons, float(self._params["gate_1d"][0]),
            dof=dof, nu2=nu2, s2=s2, threshold2=float(self._params["gate_2d"][0])))

    def _advance_without_steps(self, t: float) -> None:
        """Bring the state to ``t`` before a correction when no step or velocity drives it."""
        if self._velocity_mode:
            self._velocity_to(t)
        if t <= self.state.t:
            return
        st = self.state
        if not self.has_imu:
            self.state = predict_random_walk(st, t, RandomWalkParams())
        else:   # only the time changes: no need to validate the state again
            self.state = FilterState.from_kernel(t, st.x, st.P, st.input_heading_rad,
                                                 st.has_input_heading, st.reference_pending)

    def _moving(self, t: float) -> bool:
        if self._velocity_mode:
            # eq. 19 literally: sigma(a_xu) > sigma_min, i.e. the automaton is in a motion
            # state (non-zero speed) at the last sample up to t
            return self._last_speed > 0.0
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
            self._apply_fix(t, payload)
        elif kind == _RSS:
            self._apply_rss(t, payload)
        elif kind == _TAGS:
            ids: list[str] = payload
            prior_xy = self.state.x[:2].copy()
            upd = self.tag_corrector.update_ids(self.state, t=t, ids=ids,
                                                landmarks=self.landmarks, memory=self.tag_memory)
            if (self.tag_fallback is not None and upd.strategy == 0
                    and not any(d.accepted for d in upd.diagnostics)):
                # every lobe failed the gate: the dead reckoning, not the tag, is off --
                # re-initialize by the thesis' strategies (eq. 4.26-4.33)
                upd = self.tag_fallback.update_ids(self.state, t=t, ids=ids,
                                                   landmarks=self.landmarks,
                                                   memory=self.tag_memory)
            self.state, self.tag_memory = upd.state, upd.memory
            self.diagnostics.extend(upd.diagnostics)
            if upd.strategy != -1 and any(d.accepted for d in upd.diagnostics):
                self._corrected_since_fix = True
                self._learn_scale(prior_xy, self.state.x[:2].copy())
            if cfg.tags.bearing_correction and upd.strategy != -1:
                for tag_id in ids:
                    lm = self.landmarks.get(tag_id)
                    if lm is None or not lm.bearings_rad:
                        continue
                    if cfg.tags.bearing_confirm_s > 0.0:
                        # decide once the next steps show whether the user was turning
                        self._push(t + cfg.tags.bearing_confirm_s, _BEARING, i_payload=(
                            tag_id, tuple(lm.bearings_rad), self.state.heading, t))
                    else:
                        self._apply_bearing(t, tag_id, np.asarray(lm.bearings_rad))
        elif kind == _BEARING:
            tag_id, bearings, heading_at_read, t_read = payload
            turn = self._recent_turn(t_read - BEARING_TURN_WINDOW_S, t)
            if turn > math.radians(cfg.tags.bearing_max_turn_deg):
                self.diagnostics.append(skipped(
                    "bearing", t, f"turning ({math.degrees(turn):.0f} deg around the read)",
                    tag_id))
                return
            # the bearing judged against the heading at the read, applied to the heading now
            shift = float(wrap_angle(self.state.heading - heading_at_read))
            self._apply_bearing(t, tag_id, np.asarray(bearings) + shift)
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
            self._corrected_since_fix = self._corrected_since_fix or upd_r.diagnostics.accepted

    def _apply_bearing(self, t: float, tag_id: str, bearings: np.ndarray) -> None:
        """Inderst eq. 4.21-4.22 with the configured deadband, gate and mode."""
        cfg = self.config.tags
        hc = bearing_heading_correction(
            self.state, bearings, t=t, source=tag_id, gate_rad=math.radians(cfg.bearing_gate_deg),
            deadband_rad=math.radians(cfg.bearing_deadband_deg), mode=cfg.bearing_mode,
            sigma_rad=math.radians(cfg.bearing_sigma_deg),
            gate_probability=self.config.gate_probability)
        self.state = hc.state
        self.diagnostics.append(hc.diagnostics)

    def _recent_turn(self, t_from: float, t_to: float) -> float:
        """Largest heading change between the steps ending in ``[t_from, t_to]`` (rad)."""
        hs = [h for (ts, h) in self._recent_heading if t_from <= ts <= t_to]
        if len(hs) < 2:
            return 0.0 if hs else math.inf
        d = np.asarray(wrap_angle(np.asarray(hs) - hs[-1]))
        return float(np.max(np.abs(d)))

    def _learn_scale(self, prior_xy: np.ndarray, post_xy: np.ndarray) -> None:
        """Step-length scale from two absolute corrections on a straight stretch (our addition).

        Between the last absolute correction (tag or fix) and this one, the dead-reckoned
        displacement is ``prior - anchor``; the corrected one projected on it gives the ratio
        of the true to the modelled step length. It is used only when no other correction
        happened in between, the stretch is at least ``SCALE_MIN_BASELINE_M`` long and nearly
        straight; the scale moves by the power ``SCALE_GAIN`` of the ratio, within
        ``SCALE_BOUNDS``.
        """
        anchor = self._anchor_xy
        if (self.config.prediction.learn_step_scale and anchor is not None
                and not self._soft_since_anchor and not self._velocity_mode):
            d = prior_xy - anchor
            base = float(np.hypot(d[0], d[1]))
            if base >= SCALE_MIN_BASELINE_M and base >= 0.95 * self._path_since_anchor:
                ratio = float((post_xy - anchor) @ d) / (base * base)
                if 0.7 < ratio < 1.4:
                    # per activity: the ratio teaches the scale of the steps that made the
                    # stretch (walking, running, or both when mixed)
                    share_run = self._run_since_anchor / max(self._path_since_anchor, 1e-9)
                    if share_run < 0.8:
                        self.step_scale = float(np.clip(self.step_scale * ratio**SCALE_GAIN,
                                                        *SCALE_BOUNDS))
                    if share_run > 0.2:
                        self.run_scale = float(np.clip(self.run_scale * ratio**SCALE_GAIN,
                                                       *SCALE_BOUNDS))
        self._anchor_xy = post_xy
        self._path_since_anchor = 0.0
        self._run_since_anchor = 0.0
        self._soft_since_anchor = False

    def _apply_fix(self, t: float, payload: Any) -> None:
        """Colombo eq. 18-23, then the yaw from trajectory stretching (eq. 24-28) fed back."""
        cfg = self.config
        xyz, sigma, has_z = payload
        if not self._fix_phase_set:
            # eq. 19 slots i Tp: anchored at the first fix (the query clock is unknown)
            self._fix_phase_set = True
            prm = self.fix_corrector.params
            self.fix_corrector = FixCorrector(replace(prm, phase_s=t - prm.slot_tolerance_s / 2))
        prior_xy = self.state.x[:2].copy()
        # step model: the state stands at the last finished step; the fix is compared with the
        # state plus the part of the step in progress at t (fixes.partial_step, our addition)
        lead = np.zeros(2)
        if cfg.fixes.partial_step and not self._velocity_mode:
            for st in reversed(self._steps):
                if len(st) == 0 or st.t_start[0] > t:
                    continue
                k = step_in_progress(t, st.t_start, st.t_end)
                if k >= 0 and st.t_end[k] > self.state.t and math.isfinite(st.heading_rad[k]):
                    h_k = float(st.heading_rad[k])
                    h_last = self._recent_heading[-1][1] if self._recent_heading else h_k
                    scale = (self.running_factor * self.run_scale
                             if st.activity[k] == int(Activity.RUNNING) else self.step_scale)
                    lead = partial_step(t, t_start=float(st.t_start[k]),
                                        t_end=float(st.t_end[k]),
                                        length_m=float(st.length_m[k]) * scale,
                                        heading_rad=float(self.state.x[IH]
                                                          + wrap_angle(h_k - h_last)))
                break
        xyz_cmp = np.asarray(xyz, dtype=np.float64).copy()
        xyz_cmp[:2] -= lead
        walked = self._path_since_anchor
        drift = cfg.fixes.drift_fraction * max(walked, DRIFT_MIN_PATH_M)
        upd = self.fix_corrector.update(self.state, self.fix_schedule, t=t, xyz=xyz_cmp,
                                        sigma_m=sigma, moving=self._moving(t), has_z=has_z,
                                        drift_var_m2=drift * drift)
        self.state, self.fix_schedule = upd.state, upd.schedule
        self.diagnostics.append(upd.diagnostics)
        if not upd.diagnostics.accepted:
            return
        jump = self.state.x[:2] - prior_xy
        rows = self._track.t
        if (np.any(lead != 0.0) and rows and len(rows[-1])
                and float(rows[-1][-1]) == self._last_step_end):
            # the corrected state is the position at the last step end: its output row
            # replaces that step's row (a row at t would show it one partial step late)
            st_ = self.state
            self.state = FilterState.from_kernel(self._last_step_end, st_.x, st_.P,
                                                 st_.input_heading_rad, st_.has_input_heading,
                                                 st_.reference_pending)
        # at the time of the output row that shows it
        self.fix_jumps.append((self.state.t, float(jump[0]), float(jump[1])))
        self._learn_scale(prior_xy, self.state.x[:2].copy())
        # positions at t: the state plus the step in progress
        prior_xy = prior_xy + lead
        fix_xy = np.asarray(xyz[:2], dtype=np.float64)
        mem = self._stretch
        if cfg.fixes.yaw_stretch and mem is not None and not self._corrected_since_fix:
            if self._velocity_mode:
                t_in, v_in, yaw_in = mem.t, mem.speed_m_s, mem.yaw_rad
            else:
                # steps since the last fix: one straight sample from the start to the prior,
                # at a nominal 1 m/s (its time only scales eq. 26's spreading; a loop's chord
                # over Tp would otherwise look slower than min_speed_m_s and be dropped)
                chord = prior_xy - mem.post_xy
                length = max(float(np.hypot(*chord)), 1e-3)
                t_in = np.array([mem.t_fix + length])
                v_in = np.array([1.0])
                yaw_in = np.array([math.atan2(chord[1], chord[0])])
            res = stretch_yaw(t_start=mem.t_fix, t=t_in, speed_m_s=v_in, yaw_rad=yaw_in,
                              start_xy=mem.post_xy, offset_start=mem.fix_xy - mem.post_xy,
                              offset_end=fix_xy - prior_xy, sigma_start_m=mem.sigma_m,
                              sigma_end_m=sigma, path_m=walked,
                              params=YawStretchParams(
                                  drift_fraction=cfg.fixes.drift_fraction))   # eq. 24-28
            if res.valid:
                self.yaw_pseudo.append(YawPseudoMeasurement(t, res.yaw_rad, res.var_yaw_rad2,
                                                            res.correction_rad))
                gain = cfg.fixes.yaw_feedback_gain
                p_new = self.state.P
                if cfg.fixes.yaw_feedback == "kalman":
                    # scalar update of the heading by the pseudo-measurement (Joseph form)
                    var_h = float(self.state.P[IH, IH])
                    gain *= var_h / (var_h + res.var_yaw_rad2)
                    a = np.eye(self.state.P.shape[0])
                    a[IH, IH] = 1.0 - gain
                    p_new = a @ self.state.P @ a.T
                    p_new[IH, IH] += gain * gain * res.var_yaw_rad2
                delta = gain * res.correction_rad
                self._yaw_offset = float(wrap_angle(self._yaw_offset + delta))
                x = self.state.x.copy()
                x[IH] = float(wrap_angle(x[IH] + delta))
                self.state = self.state.evolve(
                    x=x, P=p_new, input_heading_rad=float(wrap_angle(
                        self.state.input_heading_rad + delta)))
        empty = np.zeros(0)
        self._stretch = StretchMemory(t, self.state.x[:2] + lead, fix_xy, sigma, empty, empty,
                                      empty)
        self._corrected_since_fix = False

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
                             min_distance_m=RSS_MIN_DISTANCE_M,
                             gate_probability=cfg.gate_probability, t=t, source=anchor)
            self.state = upd.state
            self.diagnostics.append(upd.diagnostics)
            self._corrected_since_fix = self._corrected_since_fix or upd.diagnostics.accepted
            return
        scan = payload[1]
        if len(scan.anchor) < 3:
            self.diagnostics.append(skipped("rss", t, f"{len(scan.anchor)} anchors heard "
                                            "(WLS needs 3)", ",".join(scan.anchor)))
            return
        try:
            fix = scan_position(scan, self.path_loss)
        except InputError as exc:   # e.g. the heard anchors are collinear
            self.diagnostics.append(UpdateDiagnostics("rss", t, "rejected",
                                                      source=",".join(scan.anchor),
                                                      reason=exc.problem))
            return
        if cfg.rss.mode == "wls":
            # RSS alone: the estimate jumps to each WLS position (Tarrio's baseline)
            x = self.state.x.copy()
            x[:2] = fix.xy
            p = self.state.P.copy()
            p[:2, :] = 0.0
            p[:, :2] = 0.0
            p[:2, :2] = fix.cov
            self.state = self.state.evolve(t=t, x=x, P=p)
            self.diagnostics.append(UpdateDiagnostics("rss", t, "accepted", dof=2,
                                                      source=",".join(scan.anchor),
                                                      reason="WLS position (RSS alone)"))
            return
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        r = fix.cov if cfg.rss.use_wls_covariance else np.eye(2) * cfg.rss.sigma_position_m**2
        res = kalman_update(self.state.x, self.state.P, h, r, fix.xy - self.state.x[:2],
                            gate_probability=cfg.gate_probability, kind="rss", t=t,
                            source=",".join(scan.anchor), angle_index=IH)
        self.state = self.state.evolve(x=res.x, P=res.P)
        self.diagnostics.append(res.diagnostics)
        self._corrected_since_fix = self._corrected_since_fix or res.diagnostics.accepted

    # ------------------------------------------------------------------ report
    def _report(self, trajectory: Trajectory, steps: StepEvents) -> dict[str, Any]:
        counts = self._report_counts()
        if self._t_pose > self._t0:
            ignored = ", ".join(f"{n} {k}" for k, n in self._ignored_before_pose.items())
            self.notes.append(f"start pose holds at t = {self._t_pose:.3f} s: attitude and gait "
                              f"ran from t = {self._t0:.3f} s, position starts at the pose"
                              + (f"; ignored before it: {ignored}" if ignored else ""))
        if self.has_imu and not self._seen_obs:
            self.notes.append("no infrastructure observations: pure dead reckoning (the error "
                              "grows with the distance walked)")
        rejected = list(self._diag_base["rejected"])
        rejected += [d.to_dict() for d in self.diagnostics.first_rejected(200 - len(rejected))]
        final = self.state
        report: dict[str, Any] = {
            "config": self.config.model_dump(),
            "attitude_method": self.attitude_method,
            "notes": self.notes,
            "corrections": counts,
            "rejected": rejected,
            "step_length_scale": self.step_scale,
            "running_step_length_scale": self.run_scale,
            "running_step_factor": self.running_factor,
            "yaw_pseudo_measurements": self._diag_base["yaw_pseudo"] + len(self.yaw_pseudo),
            "offline": {"two_pass": self._two_pass},
            "summary": {
                "duration_s": float(trajectory.t[-1] - trajectory.t[0]) if len(trajectory) else 0,
                "steps": len(steps),
                "distance_walked_m": steps.distance_m,
                "path_length_m": trajectory.path_length_m,
                "final_position_m": final.x[:3].tolist(),
                "final_sigma_xy_m": float(math.sqrt(max(np.trace(final.P[:2, :2]), 0.0) / 2)),
            },
        }
        if self._compass is not None:
            report["compass"] = {"hard_iron_ut": self._compass.c.tolist(),
                                 "field_ut": self._compass.radius
                                 if math.isfinite(self._compass.radius) else None,
                                 "last_yaw_correction_deg": math.degrees(
                                     -self._compass.last_error)}
        if self.channel_state is not None and self.config.rss.mode != "off":
            report["channel"] = {"a_dbm": float(self.channel_state.theta[0]),
                                 "eta": float(self.channel_state.theta[1]),
                                 "sigma_db": math.sqrt(self.channel_state.residual_var_db2)}
        return report


def average_rss_per_anchor(rss: RssReadings, window_s: float, *,
                           t_origin: float | None = None) -> RssReadings:
    """One reading per anchor and window: the mean (dBm) of its readings in that window.

    Windows are ``[t_origin + i w, t_origin + (i + 1) w)`` (``t_origin``: the first reading
    when None); each mean is stamped with the time of the last reading it contains (it is
    known by then). Consecutive readings of one beacon share their shadowing error; averaging
    keeps them from entering the filter as independent measurements. Output in time order
    (ties: anchor name).
    """
    if not (math.isfinite(window_s) and window_s > 0):
        raise InputError(f"{window_s}", where="window_s", expected="a positive window (s)")
    if len(rss) == 0:
        return rss
    origin = float(rss.t[0]) if t_origin is None else float(t_origin)
    if not math.isfinite(origin) or origin > float(rss.t.min()):
        raise InputError(f"{t_origin}", where="t_origin",
                         expected="a finite time at or before the first reading")
    anchors, a_idx = np.unique(rss.anchor, return_inverse=True)
    bins = np.floor((rss.t - origin) / window_s).astype(np.int64)
    n_bins = int(bins.max()) + 1
    keys = a_idx.astype(np.int64) * n_bins + bins
    uniq, inv = np.unique(keys, return_inverse=True)
    mean = np.bincount(inv, weights=rss.rss_dbm) / np.bincount(inv)
    t_last = np.full(uniq.shape[0], -np.inf)
    np.maximum.at(t_last, inv, rss.t)
    anchor = anchors[uniq // n_bins]
    order = np.lexsort((anchor, t_last))
    return RssReadings(t_last[order], anchor[order], mean[order], rss.name)


def _leading_rate_hz(t: np.ndarray) -> float:
    """Nominal rate from the median spacing of the first ``RATE_SAMPLES`` times, Hz."""
    head = t[:RATE_SAMPLES]
    return float(1.0 / np.median(np.diff(head))) if len(head) >= 2 else 0.0


def _chunk_end(chunk: Session) -> float:
    """Latest time of the chunk's sensor streams and observations (not its ground truth)."""
    ends = [float(part.t[-1]) for part in (chunk.fixes, chunk.rss, chunk.tags, chunk.ranges)
            if part is not None and len(part.t)]
    if chunk.imu is not None and len(chunk.imu.accel.t):
        ends.append(float(chunk.imu.accel.t[-1]))
    return max(ends) if ends else -math.inf


def _select_steps(steps: StepEvents, keep: np.ndarray) -> StepEvents:
    """The steps where ``keep`` is true."""
    return StepEvents(steps.t_start[keep], steps.t_end[keep], steps.length_m[keep],
                      steps.heading_rad[keep], steps.dz_m[keep], steps.activity[keep],
                      steps.frequency_hz[keep], steps.acc_max[keep], steps.acc_min[keep])


def _concat_steps(parts: list[StepEvents]) -> StepEvents:
    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in parts])

    return StepEvents(cat("t_start"), cat("t_end"), cat("length_m"),
                      wrap_angle(cat("heading_rad")), cat("dz_m"), cat("activity"),
                      cat("frequency_hz"), cat("acc_max"), cat("acc_min"))
