"""The gait stage: motion, activity, steps, step length, heading and walking velocity.

:class:`GaitAnalyzer` composes the sub-algorithms it is given (each is one module of
:mod:`hrtls.gait`) and runs them over an accelerometer stream, optionally with an attitude
quaternion series. The same :meth:`GaitAnalyzer.update` serves offline processing (one chunk,
then :meth:`GaitAnalyzer.flush`) and the live service (many chunks).

Outputs of a call are what became final during it: the steps whose activity window is complete
(a step is held until the activity of the window containing its end is known; with the step gate
also until ``gate_lookahead_s`` after its end), per-sample activity of completed windows, and
per-sample walking velocity. Concatenating the outputs of all chunks (plus the flush) gives the
same result as one offline call: everything a step needs from before its chunk (the vertical
acceleration for its excursion, the yaw at its start, the motion history of the gate, headings
waiting to take effect on the held walking direction) is kept in the state for a few seconds.

:meth:`GaitAnalyzer.state` returns the whole state as strict JSON values (the sub-estimators'
``to_dict`` states, filter memories, held samples and steps) and :meth:`GaitAnalyzer.restore`
continues from it, for the live service.

The motion state (Basso's spread test) is combined with the periodicity test of
:mod:`hrtls.gait.cadence` unless ``cadence=None``: it enables the PLL, selects its walking or
running oscillator, gates steps and gives the activity when no classifier is set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity, Session, StepEvents
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import GRAVITY_M_S2, quat_conjugate, quat_rotate, quat_to_matrix, wrap_angle
from hrtls.gait._state import FloatArray, as_matrix, as_time, check_positive
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds, classify_tree
from hrtls.gait.cadence import CadenceDetector, CadenceParams
from hrtls.gait.features import (
    DFT_ZERO_PAD,
    StreamingButterworth,
    WindowFeatures,
    window_features,
)
from hrtls.gait.fourier_heading import FourierHeading, FourierHeadingState
from hrtls.gait.missed_steps import MissedStepFiller, MissedStepParams, MissedStepState
from hrtls.gait.motion_detector import (
    STILL,
    MotionDetector,
    MotionParams,
    MotionResult,
    RunningStdState,
)
from hrtls.gait.peak_steps import PeakStepDetector, PeakStepState
from hrtls.gait.pll import PllState, PllStepDetector, StepDetection
from hrtls.gait.step_length import StairsModel, StepModel, WeinbergModel, displacements
from hrtls.gait.step_length_pendulum import vertical_excursion
from hrtls.gait.velocity_automaton import AutomatonState, VelocityAutomaton
from hrtls.gait.vertical import (
    GravityLevelling,
    LevelledAcceleration,
    LevellingState,
    from_orientation,
    heading_of,
    rotate,
)
from hrtls.gait.walking_bouts import WalkingBoutDetector, WalkingBoutParams

IntArray = NDArray[np.int64]
HEADING_HOLD_DELAY_S = 0.5
EXCURSION_BUFFER_S = 5.0
DEFAULT_CADENCE = CadenceParams()
HeadingSource = Literal["fourier", "yaw", "none"]
StepYaw = Literal["endpoints", "mean", "turns"]
TURNING_STEP_RAD = math.radians(20.0)
"""step_yaw="turns": a step turning more than this uses the time-averaged yaw"""


@dataclass(frozen=True, slots=True, eq=False)
class GaitResult:
    """What one call of the analyzer produced.

    Attributes
    ----------
    steps: step table (t_start, t_end, length, heading, dz, activity, frequency, extremes).
    activity_t, activity: per-sample activity codes of the samples classified in this call.
    velocity_t, velocity_m_s: per-sample walking velocity (Colombo automaton; empty when off).
    motion_sigma_m_s2: per-sample 2 s std of vertical acceleration (Basso II-B) of this chunk.
    heading_frame: ``"enu"`` (orientation given) or ``"levelled"`` (relative to the device,
        accelerometer-only).
    features: activity features of the windows completed in this call (Inderst Sec. 4.1).
    step_excursion_m: vertical excursion of the pelvis during each step of ``steps``, m
        (:mod:`hrtls.gait.step_length_pendulum`).
    """

    steps: StepEvents
    activity_t: FloatArray
    activity: IntArray
    velocity_t: FloatArray
    velocity_m_s: FloatArray
    motion_sigma_m_s2: FloatArray
    heading_frame: str
    features: WindowFeatures = field(default_factory=lambda: WindowFeatures(
        np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 7))))
    step_excursion_m: FloatArray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def concat(cls, parts: list[GaitResult]) -> GaitResult:
        """Join the results of consecutive calls."""
        if not parts:
            return cls(StepEvents.empty(), np.zeros(0), np.zeros(0, dtype=np.int64),
                       np.zeros(0), np.zeros(0), np.zeros(0), "levelled")
        cols = ("t_start", "t_end", "length_m", "heading_rad", "dz_m", "activity",
                "frequency_hz", "acc_max", "acc_min")
        steps = StepEvents(*(np.concatenate([getattr(p.steps, c) for p in parts]) for c in cols))
        feats = WindowFeatures(*(np.concatenate([getattr(p.features, c) for p in parts])
                                 for c in ("t_start", "t_end", "tree", "lda")))
        return cls(steps,
                   np.concatenate([p.activity_t for p in parts]),
                   np.concatenate([p.activity for p in parts]),
                   np.concatenate([p.velocity_t for p in parts]),
                   np.concatenate([p.velocity_m_s for p in parts]),
                   np.concatenate([p.motion_sigma_m_s2 for p in parts]),
                   parts[-1].heading_frame, feats,
                   np.concatenate([p.step_excursion_m for p in parts]))


@dataclass
class _Pending:
    """Samples waiting for their activity window and steps waiting for their activity."""

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    acc: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    # combined motion state and Basso spread of the held samples
    ms: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    sg: FloatArray = field(default_factory=lambda: np.zeros(0))
    steps: list[StepDetection] = field(default_factory=list)
    headings: list[FloatArray] = field(default_factory=list)
    excursions: list[FloatArray] = field(default_factory=list)
    # recent vertical acceleration for the step excursions: times and values
    vb_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    vb_a: FloatArray = field(default_factory=lambda: np.zeros(0))
    # recent unwrapped yaw of the body forward axis (heading="yaw"): times and values
    yb_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    yb_y: FloatArray = field(default_factory=lambda: np.zeros(0))
    win_end: list[float] = field(default_factory=list)
    win_label: list[int] = field(default_factory=list)
    last_label: int = int(Activity.UNKNOWN)
    yaw_last: float = float("nan")
    heading_last: float = float("nan")
    # motion history for the step gate: sample times and moving flags (0/1)
    mt: FloatArray = field(default_factory=lambda: np.zeros(0))
    mv: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    # step headings waiting to take effect on the held walking direction: times and values
    hq_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    hq_h: FloatArray = field(default_factory=lambda: np.zeros(0))


class GaitAnalyzer:
    """Compose motion, activity, step, length, heading and velocity estimators.

    Parameters
    ----------
    rate_hz:
        Nominal sampling rate of the accelerometer, Hz (sizes filters and windows).
    step_detector:
        :class:`PeakStepDetector` (default) or :class:`PllStepDetector`.
    step_model:
        :class:`WeinbergModel` (default) or :class:`FrequencyLawModel`.
    stairs:
        :class:`StairsModel` for steps classified up/downstairs.
    activity:
        :class:`LdaModel`, :class:`TreeThresholds`, or None to use the motion detector
        (still / walking / running).
    heading:
        ``"fourier"`` (Basso Sec. III), ``"yaw"`` (body x axis of the attitude) or ``"none"``.
    velocity:
        :class:`VelocityAutomaton` or None.
    motion:
        Parameters of the Basso motion detector (also gates the PLL).
    mounting_q_bd:
        Device -> body rotation [w, x, y, z] (body x forward, y left, z up). Needed for the
        activity features' AP/ML axes, the yaw heading and the velocity; identity if unknown.
    step_cutoff_hz:
        Corner of the 4th-order Butterworth low-pass before the peak detector, Hz.
    gate_steps_with_motion:
        Drop steps not confirmed by motion: a step is kept when the motion state (Basso's
        spread test, or the periodicity test of :mod:`hrtls.gait.cadence` when ``cadence`` is
        set) reports motion at some sample of ``[t_end, t_end + gate_lookahead_s]`` (both
        tests judge a window that ends after the step; looking ahead lets the first steps
        of a walk pass). Gated steps are released ``gate_lookahead_s`` later.
    cadence:
        Parameters of the periodicity walking detector combined with the Basso spread test
        (moving when either reports motion, running only at a running step frequency); it
        sets the motion state used by the PLL, the step gate and the motion-based activity.
        None: Basso's spread test alone.
    gate_lookahead_s:
        Look-ahead of the step gate, s.
    pll_enable_m_s2:
        With the PLL and ``cadence``: the loop also runs where the combined state says still
        but the 2 s spread exceeds this (m/s^2), so that it is locked when walking is
        confirmed (the periodicity test reports a walk about a second late); its steps then
        always pass the step gate. None (default): the loop runs only while the combined
        state says moving (Basso's gating). On mobgap daily life 0.2-0.5 raised the PLL's
        F1 from 0.69 to about 0.77 but over-counted by 17-25 % (the free-running loop keeps
        stepping after a stop), and worsened the Oxford pocket counts.
    activity_window_s, activity_cutoff_hz:
        Window and low-pass corner of the activity features when ``activity`` is not an
        :class:`LdaModel` (a model carries its own), s and Hz.
    walking_bouts:
        Step-sequence walking bouts (:mod:`hrtls.gait.walking_bouts`): steps outside a bout
        (fewer than ``min_steps`` steps with gaps of at most ``max_gap_s``) are dropped, and
        with ``activity=None`` a window is walking when more than half of it lies in a bout
        (running when the combined motion state at its end says running). Steps and windows
        are then released once the bout decision is final (at most
        ``WalkingBoutParams.max_delay_s`` plus the detection delay later). None (default):
        off.
    missed_steps:
        Insert one step into a gap of about two step periods within a walk
        (:mod:`hrtls.gait.missed_steps`); None (default): off.
    step_yaw:
        With ``heading="yaw"``: a step's heading is the circular mean of the yaw at its start
        and end (``"endpoints"``) or the time average of the yaw over the step (``"mean"``,
        which follows a turn made during the step), or the time average only for steps that
        turn by more than ``TURNING_STEP_RAD`` (``"turns"``).
    window_features:
        Compute the activity features of every window even when ``activity`` is None (they
        are returned in :attr:`GaitResult.features`, e.g. for training); False skips them
        when nothing uses them (the features are then NaN).
    """

    def __init__(self, *, rate_hz: float, step_detector: PeakStepDetector | PllStepDetector
                 | None = None, step_model: StepModel | None = None,
                 stairs: StairsModel | None = None,
                 activity: LdaModel | TreeThresholds | None = None,
                 heading: HeadingSource = "fourier", fourier: FourierHeading | None = None,
                 velocity: VelocityAutomaton | None = None, motion: MotionParams | None = None,
                 mounting_q_bd: FloatArray | None = None, step_cutoff_hz: float = 3.0,
                 gate_steps_with_motion: bool = False, activity_window_s: float = 2.0,
                 activity_cutoff_hz: float = 6.0,
                 cadence: CadenceParams | None = DEFAULT_CADENCE,
                 gate_lookahead_s: float = 1.6,
                 pll_enable_m_s2: float | None = None,
                 walking_bouts: WalkingBoutParams | None = None,
                 missed_steps: MissedStepParams | None = None,
                 step_yaw: StepYaw = "endpoints", window_features: bool = True) -> None:
        check_positive(rate_hz, "rate_hz")
        self.window_features = bool(window_features)
        if step_yaw not in ("endpoints", "mean", "turns"):
            raise InputError(f"step_yaw {step_yaw!r}", where="step_yaw",
                             expected="'endpoints', 'mean' or 'turns'")
        self.step_yaw: StepYaw = step_yaw
        if heading not in ("fourier", "yaw", "none"):
            raise InputError(f"heading {heading!r}", where="heading",
                             expected="'fourier', 'yaw' or 'none'")
        self.rate_hz = float(rate_hz)
        self.step_detector = step_detector or PeakStepDetector()
        self.step_model: StepModel = step_model or WeinbergModel()
        self.stairs = stairs or StairsModel()
        self.activity = activity
        self.heading: HeadingSource = heading
        self.fourier = fourier or FourierHeading()
        self.velocity = velocity
        self.motion = MotionDetector(motion)
        q = np.array([1.0, 0.0, 0.0, 0.0]) if mounting_q_bd is None else np.asarray(
            mounting_q_bd, dtype=np.float64)
        if q.shape != (4,) or abs(np.linalg.norm(q) - 1.0) > 1e-6:
            raise InputError(f"mounting {q}", where="mounting_q_bd",
                             expected="a unit quaternion [w, x, y, z]")
        self.q_bd = q
        self.mounting_known = mounting_q_bd is not None
        window_s = activity.window_s if isinstance(activity, LdaModel) else activity_window_s
        cutoff = activity.cutoff_hz if isinstance(activity, LdaModel) else activity_cutoff_hz
        self.window_samples = max(4, round(window_s * rate_hz))
        self._act_filter = StreamingButterworth(order=5, cutoff_hz=min(cutoff, 0.45 * rate_hz),
                                                rate_hz=rate_hz)
        self._step_filter = StreamingButterworth(order=4, cutoff_hz=min(step_cutoff_hz,
                                                                        0.45 * rate_hz),
                                                 rate_hz=rate_hz)
        self.gate_steps_with_motion = gate_steps_with_motion
        if not (math.isfinite(gate_lookahead_s) and gate_lookahead_s >= 0):
            raise InputError(f"gate_lookahead_s = {gate_lookahead_s}", where="gate_lookahead_s",
                             expected="a finite value >= 0 (s)")
        self.gate_lookahead_s = float(gate_lookahead_s)
        self.cadence = None if cadence is None else CadenceDetector(cadence, rate_hz=rate_hz)
        if pll_enable_m_s2 is not None:
            check_positive(pll_enable_m_s2, "pll_enable_m_s2")
        uses_pll = isinstance(self.step_detector, PllStepDetector)
        self._pll_enable = (float(pll_enable_m_s2) if uses_pll and self.cadence is not None
                            and pll_enable_m_s2 is not None else None)
        self._gate = gate_steps_with_motion or self._pll_enable is not None
        self._step_delay_s = self._step_filter.group_delay_s(1.8)
        self._levelling = GravityLevelling()
        self.bouts = None if walking_bouts is None else WalkingBoutDetector(
            walking_bouts, history_s=window_s + 2.0 * walking_bouts.max_gap_s + 2.0)
        self.filler = None if missed_steps is None else MissedStepFiller(missed_steps)
        # windows wait for the bout decision when the bouts give the activity
        self._bout_labels = self.bouts is not None and activity is None
        self.reset()

    def reset(self) -> None:
        """Start over (all estimators reset)."""
        self.step_detector.reset()
        self.fourier.reset()
        if self.velocity is not None:
            self.velocity.reset()
        self.motion.reset()
        if self.cadence is not None:
            self.cadence.reset()
        if self.bouts is not None:
            self.bouts.reset()
        if self.filler is not None:
            self.filler.reset()
        self._levelling.reset()
        self._act_filter.reset()
        self._step_filter.reset()
        self._pending = _Pending()
        self._t_last = -np.inf
        self._forward_d: FloatArray | None = None
        self._frame = "levelled"

    # ------------------------------------------------------------------ helpers
    def _level(self, t: FloatArray, acc: FloatArray,
               q_nd: FloatArray | None) -> LevelledAcceleration:
        if q_nd is None:
            return self._levelling.update(t, acc)
        return from_orientation(t, acc, q_nd)

    def _steps_complete_s(self) -> float:
        """Time before which the step detector has reported all its steps (reported times)."""
        if isinstance(self.step_detector, PllStepDetector):
            return self._t_last  # the loop reports a step at its phase crossing
        v = self.step_detector.state.values
        # inside a positive lobe its peak (a step end not reported yet) is at or after v[4]
        c = v[4] if v[2] == 1.0 else v[0]
        return float(c) - self._step_delay_s if np.isfinite(c) else -math.inf

    def _window_labels(self, feats_tree: FloatArray, feats_lda: FloatArray,
                       sigma_end: FloatArray, state_end: IntArray,
                       walk_share: FloatArray | None = None) -> IntArray:
        if walk_share is not None:
            # walking bouts (module walking_bouts); running from the combined motion state
            run = state_end == int(Activity.RUNNING) if self.cadence is not None else (
                sigma_end > self.motion.params.run_threshold_m_s2)
            return np.where(walk_share > 0.5, np.where(run, int(Activity.RUNNING),
                                                       int(Activity.WALKING)),
                            int(Activity.STANDING)).astype(np.int64)
        if isinstance(self.activity, LdaModel):
            return self.activity.predict(feats_lda)
        if isinstance(self.activity, TreeThresholds):
            return classify_tree(feats_tree, self.activity)
        if self.cadence is not None:
            # combined motion state at the window end (0/1/2 are STANDING/WALKING/RUNNING)
            return np.where(state_end < 0, int(Activity.STANDING), state_end).astype(np.int64)
        return np.where(sigma_end > self.motion.params.run_threshold_m_s2, int(Activity.RUNNING),
                        np.where(sigma_end > self.motion.params.still_threshold_m_s2,
                                 int(Activity.WALKING), int(Activity.STANDING))).astype(np.int64)

    # ------------------------------------------------------------------ main entry
    def update(self, t: FloatArray, acc_d_m_s2: FloatArray,
               q_nd: FloatArray | None = None) -> GaitResult:
        """Process one chunk.

        Parameters
        ----------
        t: sample times, s (N,), strictly increasing and after the previous chunk.
        acc_d_m_s2: device-frame specific force, m/s^2 (N, 3).
        q_nd: optional device -> ENU attitude quaternions (N, 4) [w, x, y, z].
        """
        tt = as_time(t, where="imu time", after=self._t_last)
        acc = as_matrix(acc_d_m_s2, where="accelerometer", columns=3, length=tt.shape[0])
        if q_nd is not None:
            q_nd = as_matrix(q_nd, where="orientation q_nd", columns=4, length=tt.shape[0])
        if tt.shape[0] == 0:
            return GaitResult.concat([])
        self._t_last = float(tt[-1])
        lev = self._level(tt, acc, q_nd)
        self._frame = lev.frame
        basso = self.motion.update(tt, lev.vertical_m_s2)
        v_lp = self._step_filter.update(lev.vertical_m_s2)
        if self.cadence is not None:
            p = self.motion.params
            cad = self.cadence.update(v_lp, basso.sigma_m_s2,
                                      still_threshold_m_s2=p.still_threshold_m_s2,
                                      run_threshold_m_s2=p.run_threshold_m_s2)
            motion = MotionResult(basso.t, basso.mean_m_s2, basso.sigma_m_s2, cad.state)
        else:
            motion = basso

        # --- steps
        if isinstance(self.step_detector, PllStepDetector):
            pll_motion = motion
            if self._pll_enable is not None:
                # the loop runs (and locks) on any motion above the floor; its steps are
                # then confirmed by the gate on the combined motion state
                st = np.where((motion.state == STILL) & (motion.sigma_m_s2 > self._pll_enable),
                              1, motion.state).astype(np.int64)
                pll_motion = MotionResult(motion.t, motion.mean_m_s2, motion.sigma_m_s2, st)
            det = self.step_detector.update(lev.vertical_m_s2, pll_motion).steps
        else:
            det = self.step_detector.update(tt, v_lp)
            # report the steps at the peaks of the unfiltered signal: remove the filter delay
            det = StepDetection(det.t_start - self._step_delay_s, det.t_end - self._step_delay_s,
                                det.frequency_hz, det.acc_max, det.acc_min)
        if self.filler is not None:
            det = self.filler.update(det)
        if self.bouts is not None:
            self.bouts.add(det.t_end, self._steps_complete_s())
        # vertical excursion of each new step (inverted pendulum length model)
        pm = self._pending
        vb_t = np.concatenate([pm.vb_t, tt])
        vb_a = np.concatenate([pm.vb_a, lev.vertical_m_s2])
        exc = vertical_excursion(vb_t, vb_a, det.t_start, det.t_end)
        recent = vb_t >= tt[-1] - EXCURSION_BUFFER_S
        pm.vb_t = vb_t[recent]
        pm.vb_a = vb_a[recent]
        if self._gate:
            pm.mt = np.concatenate([pm.mt, tt])
            pm.mv = np.concatenate([pm.mv, (motion.state != STILL).astype(np.int64)])

        # --- heading per step
        # body forward axis in ENU: rotate the device-frame image of body x by q_nd
        fwd_n = None
        if self.mounting_known:
            fwd_d = quat_rotate(quat_conjugate(self.q_bd), np.array([1.0, 0.0, 0.0]))
        else:
            fwd_d = self._unknown_mounting_forward(q_nd)
        if q_nd is not None and self.velocity is not None and self.mounting_known:
            fwd_n = rotate(q_nd, fwd_d)
        if self.heading == "fourier":
            head = self.fourier.update(tt, lev.horizontal_m_s2, det.t_end).heading_rad
        elif self.heading == "yaw" and q_nd is not None:
            # mean direction of the body forward axis over the step: of its start and end
            # yaw ("endpoints") or the time average over the step ("mean")
            # (unwrapped continuously across chunks; the last seconds are kept so that a step
            # starting or ending before this chunk reads the same yaw as in a whole run)
            yaw = heading_of(q_nd, fwd_d)
            pm = self._pending
            if np.isfinite(pm.yaw_last):
                yaw += 2.0 * np.pi * np.round((pm.yaw_last - yaw[0]) / (2.0 * np.pi))
            yb_t = np.concatenate([pm.yb_t, tt])
            yb_y = np.concatenate([pm.yb_y, yaw])
            y_end = np.interp(det.t_end, yb_t, yb_y)
            y_start = np.interp(det.t_start, yb_t, yb_y)
            head = np.arctan2(np.sin(y_start) + np.sin(y_end), np.cos(y_start) + np.cos(y_end))
            if self.step_yaw != "endpoints" and yb_t.size > 1:
                # time average of the unwrapped yaw over [t_start, t_end] (trapezoid rule)
                area = np.concatenate([[0.0], np.cumsum(0.5 * (yb_y[1:] + yb_y[:-1])
                                                        * np.diff(yb_t))])
                span = det.t_end - det.t_start
                mean = (np.interp(det.t_end, yb_t, area)
                        - np.interp(det.t_start, yb_t, area)) / np.where(span > 0, span, 1.0)
                use = span > 0
                if self.step_yaw == "turns":
                    use &= np.abs(y_end - y_start) > TURNING_STEP_RAD
                head = np.where(use, wrap_angle(mean), head)
            pm.yaw_last = float(yaw[-1])
            recent = yb_t >= tt[-1] - EXCURSION_BUFFER_S
            pm.yb_t = yb_t[recent]
            pm.yb_y = yb_y[recent]
        else:
            head = np.full(len(det), np.nan)

        # walking direction held from the latest finite step heading (forward fill); a
        # heading takes effect HEADING_HOLD_DELAY_S after its step end, a time by which every
        # detector has reported the step, so that chunked and whole runs agree
        ok = np.isfinite(head)
        pm = self._pending
        q_t = np.concatenate([pm.hq_t, det.t_end[ok] + HEADING_HOLD_DELAY_S])
        q_h = np.concatenate([pm.hq_h, head[ok]])
        due = q_t <= tt[-1]
        at = np.searchsorted(tt, q_t[due])
        src = np.full(tt.shape[0], -1, dtype=np.int64)
        src[np.clip(at, 0, tt.shape[0] - 1)] = np.arange(at.shape[0])
        src = np.maximum.accumulate(src)
        psi_held = np.concatenate([[pm.heading_last], q_h[due]])[src + 1]
        if due.any():
            pm.heading_last = float(q_h[due][-1])
        pm.hq_t = q_t[~due]
        pm.hq_h = q_h[~due]

        # --- velocity (Colombo), forward axis from attitude+mounting or the held heading
        if self.velocity is not None:
            if fwd_n is not None and self.mounting_known:
                nrm = np.hypot(fwd_n[:, 0], fwd_n[:, 1])[:, None]
                fwd = np.where(nrm > 1e-6, fwd_n[:, :2] / np.maximum(nrm, 1e-12), 0.0)
            else:
                psi = np.where(np.isfinite(psi_held), psi_held, 0.0)
                fwd = np.column_stack([np.cos(psi), np.sin(psi)])
            a_fwd = np.einsum("ij,ij->i", lev.horizontal_m_s2, fwd)
            vel = self.velocity.update(tt, a_fwd)
            vel_t, vel_v = vel.t, vel.velocity_m_s
        else:
            vel_t, vel_v = np.zeros(0), np.zeros(0)

        # --- activity windows
        pend = self._pending
        pend.t = np.concatenate([pend.t, tt])
        if self.activity is not None or self.window_features:
            pend.acc = np.concatenate([pend.acc, self._activity_input(acc, lev, psi_held)])
        pend.ms = np.concatenate([pend.ms, motion.state])
        pend.sg = np.concatenate([pend.sg, motion.sigma_m_s2])
        act_t, act, feats = self._windows(final=False)
        pend.steps.append(det)
        pend.headings.append(np.asarray(head, dtype=np.float64))
        pend.excursions.append(exc)
        steps, h = self._release(final=False)
        if self.bouts is not None:
            # keep the decisions of the held steps
            held = pend.steps[0].t_end if pend.steps and len(pend.steps[0]) else np.zeros(0)
            self.bouts.trim(float(held.min()) if held.size else math.inf)
        return GaitResult(steps, act_t, act.astype(np.int64), vel_t, vel_v, motion.sigma_m_s2,
                          lev.frame, feats, h)

    def _activity_input(self, acc: FloatArray, lev: LevelledAcceleration,
                        psi_held: FloatArray) -> FloatArray:
        """Low-passed AP, ML and vertical acceleration of the samples (window features).

        AP/ML axes: the mounting when known, else the levelled horizontal acceleration turned
        into the held walking direction (raw levelled axes until a heading exists).
        """
        if self.mounting_known:
            body = acc @ quat_to_matrix(self.q_bd).T
            ap, ml = body[:, 0], body[:, 1]
        else:
            known = np.isfinite(psi_held)
            c = np.where(known, np.cos(psi_held), 1.0)
            sn = np.where(known, np.sin(psi_held), 0.0)
            hx, hy = lev.horizontal_m_s2[:, 0], lev.horizontal_m_s2[:, 1]
            ap, ml = c * hx + sn * hy, -sn * hx + c * hy
        feat_in = np.column_stack([ap, ml, lev.vertical_m_s2 + GRAVITY_M_S2])
        return self._act_filter.update(feat_in)

    def _features(self, act_t: FloatArray, acc: FloatArray, j: int) -> WindowFeatures:
        """Activity features of whole windows (Inderst Sec. 4.1) with the classifier's settings."""
        return window_features(act_t, acc, window_samples=j,
                               anthropometric_nr=(self.activity.anthropometric_nr
                                                  if isinstance(self.activity, TreeThresholds)
                                                  else 1.0),
                               dft_zero_pad=(self.activity.dft_zero_pad
                                             if isinstance(self.activity, LdaModel)
                                             else DFT_ZERO_PAD))

    def _windows(self, *, final: bool) -> tuple[FloatArray, IntArray, WindowFeatures]:
        """Label the complete activity windows that can be labelled (all when ``final``)."""
        pend = self._pending
        j = self.window_samples
        nw = pend.t.shape[0] // j
        if self._bout_labels and not final and nw and self.bouts is not None:
            # only windows whose walking state is final
            ends_t = pend.t[np.arange(1, nw + 1) * j - 1]
            nw = int(np.searchsorted(ends_t, self.bouts.final_until_s, side="left"))
        act_t = pend.t[: nw * j]
        if not nw:
            return act_t, np.zeros(0, dtype=np.int64), WindowFeatures(
                np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 7)))
        if self.activity is None and not self.window_features:
            # motion-based labels need no features: only the window times (NaN features)
            starts = act_t[np.arange(nw) * j]
            ends = act_t[np.arange(1, nw + 1) * j - 1]
            wf = WindowFeatures(starts, ends, np.full((nw, 3), np.nan), np.full((nw, 7), np.nan))
        else:
            wf = self._features(act_t, pend.acc[: nw * j], j)
        idx = np.arange(1, nw + 1) * j - 1
        sig_end = np.where(np.isfinite(pend.sg[idx]), pend.sg[idx], 0.0)
        state_end = pend.ms[idx]
        share = None
        if self._bout_labels and self.bouts is not None:
            share = self.bouts.walking(act_t).reshape(nw, j).mean(axis=1)
        labels = self._window_labels(wf.tree, wf.lda, sig_end, state_end, share)
        act = np.repeat(labels, j)
        pend.win_end.extend(wf.t_end.tolist())
        pend.win_label.extend(labels.tolist())
        pend.last_label = int(labels[-1])
        pend.t = pend.t[nw * j:]
        pend.acc = pend.acc[nw * j:]
        pend.ms = pend.ms[nw * j:]
        pend.sg = pend.sg[nw * j:]
        return act_t, act.astype(np.int64), wf

    def _release(self, *, final: bool) -> tuple[StepEvents, FloatArray]:
        """Steps whose activity window is known (all when ``final``) and their excursions."""
        pend = self._pending
        det = StepDetection.concat(pend.steps)
        head = np.concatenate(pend.headings) if pend.headings else np.zeros(0)
        exc = np.concatenate(pend.excursions) if pend.excursions else np.zeros(0)
        ends = np.asarray(pend.win_end)
        labels = np.asarray(pend.win_label, dtype=np.int64)
        if final:
            ready = np.ones(len(det), dtype=bool)
        else:
            ready = det.t_end <= (ends[-1] if ends.size else -np.inf)
            if self._gate:
                ready &= det.t_end + self.gate_lookahead_s <= self._t_last
        if self.bouts is not None and not final:
            ready &= self.bouts.decided(det.t_end)
        sel = np.flatnonzero(ready)
        rest = np.flatnonzero(~ready)
        if self._gate:
            # motion somewhere in [t_end, t_end + lookahead] (see the class notes)
            cs = np.concatenate([[0], np.cumsum(pend.mv)])
            i0 = np.searchsorted(pend.mt, det.t_end[sel], side="left")
            i1 = np.searchsorted(pend.mt, det.t_end[sel] + self.gate_lookahead_s, side="right")
            sel = sel[cs[i1] - cs[i0] > 0]
            # keep what pending steps and steps still to be reported (their ends may lie a
            # little before the current sample) may need
            first_needed = self._t_last - EXCURSION_BUFFER_S
            if rest.size:
                first_needed = min(first_needed, float(det.t_end[rest[0]]))
            keep_m = pend.mt >= first_needed - 1e-9
            pend.mt = pend.mt[keep_m]
            pend.mv = pend.mv[keep_m]
        if self.bouts is not None:
            sel = sel[self.bouts.in_bout(det.t_end[sel])]
        w = np.searchsorted(ends, det.t_end[sel], side="left")
        act = np.where(w < labels.size, labels[np.clip(w, 0, max(labels.size - 1, 0))]
                       if labels.size else int(Activity.UNKNOWN),
                       pend.last_label).astype(np.int64)
        if act.size and labels.size == 0:
            act[:] = int(Activity.WALKING)
        act = np.where(act == int(Activity.UNKNOWN), int(Activity.WALKING), act)
        released = StepDetection(det.t_start[sel], det.t_end[sel], det.frequency_hz[sel],
                                 det.acc_max[sel], det.acc_min[sel])
        length, dz = displacements(released, act, self.step_model, self.stairs, exc[sel])
        pend.steps = [StepDetection(det.t_start[rest], det.t_end[rest], det.frequency_hz[rest],
                                    det.acc_max[rest], det.acc_min[rest])]
        pend.headings = [head[rest]]
        pend.excursions = [exc[rest]]
        # keep only windows that pending steps may still need
        if ends.size > 1:
            keep_from = ends.size - 1
            if rest.size:
                keep_from = min(keep_from, int(np.searchsorted(ends, det.t_end[rest[0]])))
            pend.win_end = ends[keep_from:].tolist()
            pend.win_label = labels[keep_from:].tolist()
        return StepEvents.build(t_start=released.t_start, t_end=released.t_end,
                                length_m=length, heading_rad=head[sel], dz_m=dz, activity=act,
                                frequency_hz=released.frequency_hz, acc_max=released.acc_max,
                                acc_min=released.acc_min), exc[sel]

    def flush(self) -> GaitResult:
        """End of the recording: release held steps and label the last partial window."""
        pend = self._pending
        feats = WindowFeatures(np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 7)))
        win_t = np.zeros(0)
        win_act = np.zeros(0, dtype=np.int64)
        if self.bouts is not None:
            self.bouts.finish()
            if self._bout_labels:
                win_t, win_act, feats = self._windows(final=True)
        steps, h = self._release(final=True)
        act_t = pend.t.copy()
        label = pend.last_label if pend.last_label != int(Activity.UNKNOWN) else int(
            Activity.STANDING)
        act = np.full(act_t.shape[0], label, dtype=np.int64)
        if self._bout_labels and self.bouts is not None and act_t.size:
            walk = self.bouts.walking(act_t).mean() > 0.5
            act[:] = int(Activity.WALKING) if walk else int(Activity.STANDING)
        pend.t = np.zeros(0)
        pend.acc = np.zeros((0, 3))
        pend.ms = np.zeros(0, dtype=np.int64)
        pend.sg = np.zeros(0)
        return GaitResult(steps, np.concatenate([win_t, act_t]),
                          np.concatenate([win_act, act]).astype(np.int64), np.zeros(0),
                          np.zeros(0), np.zeros(0), self._frame, features=feats,
                          step_excursion_m=h)

    def _unknown_mounting_forward(self, q_nd: FloatArray | None) -> FloatArray:
        """The device axis whose yaw stands for the walking direction, mounting unknown.

        The axis most orthogonal to the vertical at the first sample with an attitude (device
        x only when it is that axis; one sample, so any split into chunks chooses alike), kept
        for the whole recording. Only its yaw
        *changes* are used (the heading offset is unknown either way), and those are well
        defined only for an axis far from the vertical: a lower-back sensor strapped with x up
        made the yaw of x noise (turns off by 30-120 deg).
        """
        if self._forward_d is None and q_nd is not None and len(q_nd):
            up_d = quat_to_matrix(q_nd[0])[2]   # row 2 of R (v_n = R v_d): ENU up, device axes
            axis = np.eye(3)[int(np.argmin(np.abs(up_d)))]
            level = axis - float(axis @ up_d) * up_d   # made horizontal at that sample
            self._forward_d = level / np.linalg.norm(level)
        return np.array([1.0, 0.0, 0.0]) if self._forward_d is None else self._forward_d

    # ------------------------------------------------------------------ save / restore
    def state(self, *, strict_json: bool = True) -> dict[str, Any]:
        """The whole analyzer state as plain values.

        Combines the sub-estimators' ``to_dict`` states, the filter memories and the held
        samples and steps. :meth:`restore` on an analyzer built with the same parameters
        continues exactly where this one stopped. ``strict_json``: non-finite floats become the
        strings ``"nan"``, ``"inf"``, ``"-inf"`` (no NaN literals in JSON); False keeps them
        as floats for a binary codec that carries them (the tracker's msgpack snapshot).
        """
        pend = self._pending
        det = StepDetection.concat(pend.steps)
        heads = np.concatenate(pend.headings) if pend.headings else np.zeros(0)
        out: dict[str, Any] = {
            "format": STATE_FORMAT,
            "version": 1,
            "t_last": self._t_last,
            "forward_d": None if self._forward_d is None else self._forward_d.tolist(),
            "frame": self._frame,
            "levelling": self._levelling.state.to_dict(),
            "motion": self.motion.state.to_dict(),
            "cadence": None if self.cadence is None else self.cadence.to_dict(),
            "bouts": None if self.bouts is None else self.bouts.to_dict(),
            "missed_steps": None if self.filler is None else self.filler.state.to_dict(),
            "step_detector": {
                "kind": "pll" if isinstance(self.step_detector, PllStepDetector) else "peak",
                "state": self.step_detector.state.to_dict()},
            "fourier": self.fourier.state.to_dict(),
            "velocity": None if self.velocity is None else self.velocity.state.to_dict(),
            "act_filter_zi": None if self._act_filter.zi is None else self._act_filter.zi.tolist(),
            "step_filter_zi": (None if self._step_filter.zi is None
                               else self._step_filter.zi.tolist()),
            "pending": {
                "t": pend.t.tolist(), "acc": pend.acc.tolist(),
                "ms": pend.ms.tolist(), "sg": pend.sg.tolist(),
                "steps": np.column_stack([det.t_start, det.t_end, det.frequency_hz,
                                          det.acc_max, det.acc_min]).tolist(),
                "headings": heads.tolist(),
                "excursions": (np.concatenate(pend.excursions) if pend.excursions
                               else np.zeros(0)).tolist(),
                "vb_t": pend.vb_t.tolist(), "vb_a": pend.vb_a.tolist(),
                "yb_t": pend.yb_t.tolist(), "yb_y": pend.yb_y.tolist(),
                "win_end": list(pend.win_end),
                "win_label": [int(v) for v in pend.win_label],
                "last_label": int(pend.last_label), "yaw_last": pend.yaw_last,
                "heading_last": pend.heading_last, "mt": pend.mt.tolist(),
                "mv": pend.mv.tolist(), "hq_t": pend.hq_t.tolist(),
                "hq_h": pend.hq_h.tolist()},
        }
        if not strict_json:
            out["nonfinite_as_strings"] = False
            return out
        encoded: dict[str, Any] = _encode_nonfinite(out)
        return encoded

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`state` dict (the analyzer must have the same parameters)."""
        if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
            raise InputError("not a GaitAnalyzer state", where="state",
                             expected=f"a dict with 'format': '{STATE_FORMAT}'")
        d = state if state.get("nonfinite_as_strings") is False else _decode_nonfinite(state)
        try:
            kind = d["step_detector"]["kind"]
            is_pll = isinstance(self.step_detector, PllStepDetector)
            if (kind == "pll") != is_pll:
                raise InputError(f"state of a {kind!r} step detector", where="state",
                                 expected="the step detector this analyzer was built with")
            if (d["cadence"] is None) != (self.cadence is None) or (
                    d["velocity"] is None) != (self.velocity is None) or (
                    d.get("bouts") is None) != (self.bouts is None) or (
                    d.get("missed_steps") is None) != (self.filler is None):
                raise InputError("cadence/velocity presence differs", where="state",
                                 expected="an analyzer built with the same parameters")
            self._levelling.state = LevellingState.from_dict(d["levelling"])
            self.motion.state = RunningStdState.from_dict(d["motion"])
            if self.cadence is not None:
                self.cadence.from_dict(d["cadence"])
            if self.bouts is not None:
                self.bouts.from_dict(d["bouts"])
            if self.filler is not None:
                self.filler.state = MissedStepState.from_dict(d["missed_steps"])
            if isinstance(self.step_detector, PllStepDetector):
                self.step_detector.state = PllState.from_dict(d["step_detector"]["state"])
            else:
                self.step_detector.state = PeakStepState.from_dict(d["step_detector"]["state"])
            self.fourier.state = FourierHeadingState.from_dict(d["fourier"])
            if self.velocity is not None:
                self.velocity.state = AutomatonState.from_dict(d["velocity"])
            self._act_filter.zi = (None if d["act_filter_zi"] is None
                                   else np.asarray(d["act_filter_zi"], dtype=np.float64))
            self._step_filter.zi = (None if d["step_filter_zi"] is None
                                    else np.asarray(d["step_filter_zi"], dtype=np.float64))
            pd = d["pending"]
            pend = _Pending()
            pend.t = np.asarray(pd["t"], dtype=np.float64).reshape(-1)
            pend.acc = np.asarray(pd["acc"], dtype=np.float64).reshape(-1, 3)
            # states written before the held motion state was kept: unknown (-1 / NaN)
            pend.ms = np.asarray(pd.get("ms", [-1] * pend.t.shape[0]),
                                 dtype=np.int64).reshape(-1)
            pend.sg = np.asarray(pd.get("sg", [math.nan] * pend.t.shape[0]),
                                 dtype=np.float64).reshape(-1)
            pend.steps = [StepDetection.from_rows(np.asarray(pd["steps"], dtype=np.float64))]
            pend.headings = [np.asarray(pd["headings"], dtype=np.float64).reshape(-1)]
            pend.excursions = [np.asarray(pd["excursions"], dtype=np.float64).reshape(-1)]
            pend.vb_t = np.asarray(pd["vb_t"], dtype=np.float64).reshape(-1)
            pend.vb_a = np.asarray(pd["vb_a"], dtype=np.float64).reshape(-1)
            pend.yb_t = np.asarray(pd["yb_t"], dtype=np.float64).reshape(-1)
            pend.yb_y = np.asarray(pd["yb_y"], dtype=np.float64).reshape(-1)
            pend.win_end = [float(v) for v in pd["win_end"]]
            pend.win_label = [int(v) for v in pd["win_label"]]
            pend.last_label = int(pd["last_label"])
            pend.yaw_last = float(pd["yaw_last"])
            pend.heading_last = float(pd["heading_last"])
            pend.mt = np.asarray(pd["mt"], dtype=np.float64).reshape(-1)
            pend.mv = np.asarray(pd["mv"], dtype=np.int64).reshape(-1)
            pend.hq_t = np.asarray(pd["hq_t"], dtype=np.float64).reshape(-1)
            pend.hq_h = np.asarray(pd["hq_h"], dtype=np.float64).reshape(-1)
            self._pending = pend
            self._t_last = float(d["t_last"])
            fwd = d.get("forward_d")   # absent in states before the axis was chosen: device x
            self._forward_d = (np.array([1.0, 0.0, 0.0]) if "forward_d" not in d else
                               None if fwd is None else np.asarray(fwd, dtype=np.float64))
            self._frame = str(d["frame"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed state ({exc!r})", where="state",
                             expected="a dict written by GaitAnalyzer.state()") from None

    def process(self, t: FloatArray, acc_d_m_s2: FloatArray,
                q_nd: FloatArray | None = None) -> GaitResult:
        """Whole recording: reset, one update, flush; returns the joined result."""
        self.reset()
        if q_nd is None:
            import warnings

            warnings.warn("no orientation: accelerometer-only levelling, headings are "
                          "relative to the device", DegradedInputWarning, stacklevel=2)
        first = self.update(t, acc_d_m_s2, q_nd)
        last = self.flush()
        out = GaitResult.concat([first, last])
        return GaitResult(out.steps, out.activity_t, out.activity, out.velocity_t,
                          out.velocity_m_s, out.motion_sigma_m_s2, first.heading_frame,
                          out.features, out.step_excursion_m)


STATE_FORMAT = "hrtls-gait-analyzer-state"
_NONFINITE = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def _encode_nonfinite(obj: Any) -> Any:
    """Replace non-finite floats by the strings ``"nan"``, ``"inf"``, ``"-inf"`` (recursive)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, dict):
        return {k: _encode_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_encode_nonfinite(v) for v in obj]
    return obj


def _decode_nonfinite(obj: Any) -> Any:
    """Inverse of :func:`_encode_nonfinite`."""
    if isinstance(obj, str) and obj in _NONFINITE:
        return _NONFINITE[obj]
    if isinstance(obj, dict):
        return {k: _decode_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_decode_nonfinite(v) for v in obj]
    return obj


def activity_windows(t: FloatArray, acc_d_m_s2: FloatArray, *, rate_hz: float,
                     q_nd: FloatArray | None = None, mounting_q_bd: FloatArray | None = None,
                     window_s: float = 2.0, cutoff_hz: float = 6.0,
                     anthropometric_nr: float = 1.0) -> WindowFeatures:
    """Activity features of a whole recording, computed by :class:`GaitAnalyzer` itself.

    Vertical from the levelled acceleration (plus g); AP and ML from the mounting rotation, or
    (mounting unknown) from the levelled horizontal acceleration turned into the Fourier walking
    direction; 5th-order Butterworth at ``cutoff_hz`` (Inderst Sec. 4.1); windows of
    ``window_s``. Training and classification therefore see the same features.
    """
    import warnings

    tree = TreeThresholds(anthropometric_nr=anthropometric_nr)
    ga = GaitAnalyzer(rate_hz=rate_hz, activity=tree, mounting_q_bd=mounting_q_bd,
                      activity_window_s=window_s, activity_cutoff_hz=cutoff_hz)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        return ga.process(t, acc_d_m_s2, q_nd).features


def session_inputs(session: Session) -> tuple[FloatArray, FloatArray, FloatArray | None,
                                               FloatArray | None, float]:
    """Accelerometer times and samples, orientation on those times (or None), mounting, rate.

    The orientation stream, when present, is interpolated (slerp) onto the accelerometer times;
    samples outside its span use its first/last value.
    """
    if session.imu is None:
        raise InputError("session has no IMU", where="session",
                         expected="imu.csv with an accelerometer")
    t = session.imu.accel.t
    acc = session.imu.accel.values
    if t.shape[0] < 8:
        raise InputError(f"{t.shape[0]} accelerometer samples", where="imu.csv",
                         expected="at least 8 samples")
    rate = float(1.0 / np.median(np.diff(t)))
    q_nd = None
    if session.orientation is not None and len(session.orientation.t) >= 2:
        from scipy.spatial.transform import Slerp

        from hrtls.frames import quat_from_rotation, quat_to_rotation

        ot = session.orientation.t
        slerp = Slerp(ot, quat_to_rotation(session.orientation.q))
        q_nd = quat_from_rotation(slerp(np.clip(t, ot[0], ot[-1])))
    mount = session.meta.mounting_q_bd
    return t, acc, q_nd, None if mount is None else np.asarray(mount, dtype=np.float64), rate


def analyze_session(session: Session, **analyzer_kwargs: object) -> GaitResult:
    """Run a :class:`GaitAnalyzer` over a whole session.

    The mounting rotation and the user's step model (``meta.user.step_model``) come from the
    session unless given in ``analyzer_kwargs`` (keyword arguments of :class:`GaitAnalyzer`).
    """
    from hrtls.gait.step_length import step_model_from_dict

    t, acc, q_nd, mount, rate = session_inputs(session)
    kwargs: dict[str, object] = {"rate_hz": rate, "mounting_q_bd": mount}
    if session.meta.user.step_model:
        kwargs["step_model"] = step_model_from_dict(session.meta.user.step_model)
    kwargs.update(analyzer_kwargs)
    analyzer = GaitAnalyzer(**kwargs)  # type: ignore[arg-type]
    return analyzer.process(t, acc, q_nd)
