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

import dataclasses
import math
import warnings
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity, StepEvents
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import quat_conjugate, quat_rotate, wrap_angle
from hrtls.gait._state import FloatArray, as_matrix, as_time, check_positive
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds
from hrtls.gait.analyzer_state import STATE_FORMAT, PendingGait, decode_nonfinite, encode_nonfinite
from hrtls.gait.cadence import CadenceDetector, CadenceParams
from hrtls.gait.features import StreamingButterworth, WindowFeatures
from hrtls.gait.fourier_heading import FourierHeading, FourierHeadingState
from hrtls.gait.gait_result import GaitResult
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
from hrtls.gait.stairs_climb import ClimbParams, climb_heights
from hrtls.gait.step_heading import (
    TURNING_STEP_RAD,
    StepYaw,
    check_heading_choice,
    held_heading,
    level_forward_axis,
    yaw_step_headings,
)
from hrtls.gait.step_length import StairsModel, StepModel, WeinbergModel
from hrtls.gait.step_length_pendulum import vertical_excursion
from hrtls.gait.step_release import release_steps
from hrtls.gait.velocity_automaton import AutomatonState, VelocityAutomaton
from hrtls.gait.vertical import (
    GravityLevelling,
    LevelledAcceleration,
    LevellingState,
    heading_of,
    levelled,
    rotate,
)
from hrtls.gait.walk_steps import WalkStepParams
from hrtls.gait.walking_bouts import WalkingBoutDetector, WalkingBoutParams
from hrtls.gait.walking_direction import WalkingDirection, WalkingDirectionParams
from hrtls.gait.window_activity import classify_windows, feature_axes, windows_features

__all__ = ["TURNING_STEP_RAD", "GaitAnalyzer", "GaitResult", "HeadingSource", "StepYaw"]

IntArray = NDArray[np.int64]
EXCURSION_BUFFER_S = 5.0
DEFAULT_CADENCE = CadenceParams()
HeadingSource = Literal["fourier", "yaw", "none"]


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
        state says moving (Basso's gating); a free-running loop keeps stepping after a stop.
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
    walk_steps:
        Hold steps until their walk is confirmed (:mod:`hrtls.gait.walk_steps`); None: off.
    step_yaw:
        With ``heading="yaw"``: a step's heading is the circular mean of the yaw at its start
        and end (``"endpoints"``) or the time average of the yaw over the step (``"mean"``,
        which follows a turn made during the step), or the time average only for steps that
        turn by more than ``TURNING_STEP_RAD`` (``"turns"``).
    window_features:
        Compute the activity features of every window even when ``activity`` is None (they
        are returned in :attr:`GaitResult.features`, e.g. for training); False skips them
        when nothing uses them (the features are then NaN).
    walking_direction:
        Mounting unknown: walking direction from the motion (:mod:`hrtls.gait.walking_direction`).
    climb:
        With ``activity`` None: label walking steps that climb up/downstairs
        (:mod:`hrtls.gait.stairs_climb`); None: off.
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
                 walk_steps: WalkStepParams | None = None,
                 step_yaw: StepYaw = "endpoints", window_features: bool = True,
                 walking_direction: WalkingDirectionParams | None = None,
                 climb: ClimbParams | None = None) -> None:
        check_positive(rate_hz, "rate_hz")
        self.window_features = bool(window_features)
        check_heading_choice(heading=heading, step_yaw=step_yaw)
        self.step_yaw: StepYaw = step_yaw
        self.rate_hz = float(rate_hz)
        self.step_detector = step_detector or PeakStepDetector()
        self.step_model: StepModel = step_model or WeinbergModel()
        self.stairs = stairs or StairsModel()
        self.activity = activity
        self.climb = climb if activity is None else None
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
        self._step_filter = StreamingButterworth(
            order=4, cutoff_hz=min(step_cutoff_hz, 0.45 * rate_hz), rate_hz=rate_hz)
        self.gate_steps_with_motion = gate_steps_with_motion
        check_positive(gate_lookahead_s, "gate_lookahead_s", zero_ok=True)
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
        self.walk_steps = walk_steps
        self.direction = WalkingDirection(walking_direction)
        self._offset_yaw = not self.mounting_known and heading == "yaw"
        # windows wait for the bout decision when the bouts give the activity
        self._bout_labels = self.bouts is not None and activity is None
        self.reset()

    def reset(self) -> None:
        """Start over (all estimators reset)."""
        self.step_detector.reset()
        self.fourier.reset()
        self.direction.reset()
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
        self._pending = PendingGait()
        self._t_last = -np.inf
        self._forward_d: FloatArray | None = None
        self._frame = "levelled"

    # ------------------------------------------------------------------ helpers
    def _level(self, t: FloatArray, acc: FloatArray,
               q_nd: FloatArray | None) -> LevelledAcceleration:
        return self._levelling.update(t, acc) if q_nd is None else levelled(t, acc, q_nd)

    def _steps_complete_s(self) -> float:
        """Time before which the step detector has reported all its steps (reported times)."""
        if isinstance(self.step_detector, PllStepDetector):
            return self._t_last  # the loop reports a step at its phase crossing
        v = self.step_detector.state.values
        # inside a positive lobe its peak (a step end not reported yet) is at or after v[4]
        c = v[4] if v[2] == 1.0 else v[0]
        return float(c) - self._step_delay_s if np.isfinite(c) else -math.inf

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
        motion, v_lp = self._motion_state(tt, lev)
        det = self._detect_steps(tt, lev, v_lp, motion)
        exc = self._step_excursions(tt, lev, det, motion)
        fwd_d = (quat_rotate(quat_conjugate(self.q_bd), np.array([1.0, 0.0, 0.0]))
                 if self.mounting_known else self._unknown_mounting_forward(q_nd))
        head = self._step_headings(tt, lev, q_nd, det, fwd_d)
        held = head   # mounting unknown: the yaw of fwd_d plus the walking direction from it
        if self._offset_yaw:
            psi_r = np.zeros(len(tt)) if q_nd is None else heading_of(q_nd, fwd_d)
            held = wrap_angle(head + self.direction.update(
                tt, lev.horizontal_m_s2, psi_r, lev.vertical_m_s2, det.t_start, det.t_end))
        psi_held = held_heading(self._pending, tt, det.t_end, held)
        vel_t, vel_v = self._walking_velocity(tt, lev, q_nd, fwd_d, psi_held)

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

    def _motion_state(self, tt: FloatArray,
                      lev: LevelledAcceleration) -> tuple[MotionResult, FloatArray]:
        """Motion state and the step detector's low-passed vertical acceleration.

        Basso's spread test, combined with the periodicity test when ``cadence`` is set.
        """
        basso = self.motion.update(tt, lev.vertical_m_s2)
        v_lp = self._step_filter.update(lev.vertical_m_s2)
        if self.cadence is None:
            return basso, v_lp
        p = self.motion.params
        cad = self.cadence.update(v_lp, basso.sigma_m_s2,
                                  still_threshold_m_s2=p.still_threshold_m_s2,
                                  run_threshold_m_s2=p.run_threshold_m_s2)
        return MotionResult(basso.t, basso.mean_m_s2, basso.sigma_m_s2, cad.state), v_lp

    def _detect_steps(self, tt: FloatArray, lev: LevelledAcceleration, v_lp: FloatArray,
                      motion: MotionResult) -> StepDetection:
        """The steps the detector reports in this chunk (filled in, registered with the bouts)."""
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
        return det

    def _step_excursions(self, tt: FloatArray, lev: LevelledAcceleration, det: StepDetection,
                         motion: MotionResult) -> FloatArray:
        """Vertical excursion of each new step (inverted pendulum length model).

        Also keeps the recent vertical acceleration and, with the step gate, the motion
        history in the pending state.
        """
        pm = self._pending
        vb_t = np.concatenate([pm.vb_t, tt])
        vb_a = np.concatenate([pm.vb_a, lev.vertical_m_s2])
        exc = vertical_excursion(vb_t, vb_a, det.t_start, det.t_end)
        pm.climbs.append(climb_heights(pm, vb_t, tt, lev.vertical_m_s2, det, self.climb))
        recent = vb_t >= tt[-1] - EXCURSION_BUFFER_S
        pm.vb_t, pm.vb_a, pm.vb_h = vb_t[recent], vb_a[recent], pm.vb_h[recent]
        if self._gate:
            pm.mt = np.concatenate([pm.mt, tt])
            pm.mv = np.concatenate([pm.mv, (motion.state != STILL).astype(np.int64)])
        return exc

    def _step_headings(self, tt: FloatArray, lev: LevelledAcceleration,
                       q_nd: FloatArray | None, det: StepDetection,
                       fwd_d: FloatArray) -> FloatArray:
        """Heading of each new step by the configured source (NaN when there is none)."""
        if self.heading == "fourier":
            heading: FloatArray = self.fourier.update(tt, lev.horizontal_m_s2,
                                                      det.t_end).heading_rad
            return heading
        if self.heading == "yaw" and q_nd is not None:
            # direction of the body forward axis fwd_d (device frame) rotated by q_nd
            return yaw_step_headings(self._pending, tt, heading_of(q_nd, fwd_d), det.t_start,
                                     det.t_end, step_yaw=self.step_yaw,
                                     keep_s=EXCURSION_BUFFER_S)
        return np.full(len(det), np.nan)

    def _walking_velocity(self, tt: FloatArray, lev: LevelledAcceleration,
                          q_nd: FloatArray | None, fwd_d: FloatArray,
                          psi_held: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Walking velocity (Colombo's automaton; empty when it is off).

        Along the body forward axis when attitude and mounting are known, else along the held
        walking direction.
        """
        if self.velocity is None:
            return np.zeros(0), np.zeros(0)
        if q_nd is not None and self.mounting_known:
            fwd_n = rotate(q_nd, fwd_d)
            nrm = np.hypot(fwd_n[:, 0], fwd_n[:, 1])[:, None]
            fwd = np.where(nrm > 1e-6, fwd_n[:, :2] / np.maximum(nrm, 1e-12), 0.0)
        else:
            psi = np.where(np.isfinite(psi_held), psi_held, 0.0)
            fwd = np.column_stack([np.cos(psi), np.sin(psi)])
        a_fwd = np.einsum("ij,ij->i", lev.horizontal_m_s2, fwd)
        vel = self.velocity.update(tt, a_fwd)
        return vel.t, vel.velocity_m_s

    def _activity_input(self, acc: FloatArray, lev: LevelledAcceleration,
                        psi_held: FloatArray) -> FloatArray:
        """Low-passed AP, ML and vertical acceleration of the samples (window features)."""
        axes = feature_axes(acc, lev, psi_held, q_bd=self.q_bd if self.mounting_known else None)
        return self._act_filter.update(axes)

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
        wf = windows_features(act_t, pend.acc[: nw * j], window_samples=j, activity=self.activity,
                              compute=self.activity is not None or self.window_features)
        idx = np.arange(1, nw + 1) * j - 1
        sig_end = np.where(np.isfinite(pend.sg[idx]), pend.sg[idx], 0.0)
        state_end = pend.ms[idx]
        share = None
        if self._bout_labels and self.bouts is not None:
            share = self.bouts.walking(act_t).reshape(nw, j).mean(axis=1)
        labels = classify_windows(wf.tree, wf.lda, sig_end, state_end, share,
                                  activity=self.activity, motion=self.motion.params,
                                  combined_state=self.cadence is not None)
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
        return release_steps(self._pending, final=final, t_last=self._t_last,
                             gate_lookahead_s=self.gate_lookahead_s if self._gate else None,
                             bouts=self.bouts, step_model=self.step_model, stairs=self.stairs,
                             keep_s=EXCURSION_BUFFER_S, climb=self.climb, walk=self.walk_steps,
                             offset=self.direction.heading_offset() if self._offset_yaw else None,
                             complete_s=self._steps_complete_s())

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
        """The reference axis, mounting unknown (its yaw plus the offset is the walking direction).

        :func:`~hrtls.gait.step_heading.level_forward_axis` at the first sample with an
        attitude (one sample: any split into chunks chooses alike), kept for the recording.
        """
        if self._forward_d is None and q_nd is not None and len(q_nd):
            self._forward_d = level_forward_axis(q_nd[0])
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
            "walking_direction": self.direction.to_dict(),
            "velocity": None if self.velocity is None else self.velocity.state.to_dict(),
            "act_filter_zi": None if self._act_filter.zi is None else self._act_filter.zi.tolist(),
            "step_filter_zi": (None if self._step_filter.zi is None
                               else self._step_filter.zi.tolist()),
            "pending": self._pending.to_dict(),
        }
        if not strict_json:
            out["nonfinite_as_strings"] = False
            return out
        encoded: dict[str, Any] = encode_nonfinite(out)
        return encoded

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`state` dict (the analyzer must have the same parameters)."""
        if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
            raise InputError("not a GaitAnalyzer state", where="state",
                             expected=f"a dict with 'format': '{STATE_FORMAT}'")
        d = state if state.get("nonfinite_as_strings") is False else decode_nonfinite(state)
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
            self.direction.from_dict(d.get("walking_direction"))
            if self.velocity is not None:
                self.velocity.state = AutomatonState.from_dict(d["velocity"])
            for filt, key in ((self._act_filter, "act_filter_zi"),
                              (self._step_filter, "step_filter_zi")):
                filt.zi = None if d[key] is None else np.asarray(d[key], dtype=np.float64)
            self._pending = PendingGait.from_dict(d["pending"])
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
            warnings.warn("no orientation: accelerometer-only levelling, headings are "
                          "relative to the device", DegradedInputWarning, stacklevel=2)
        first = self.update(t, acc_d_m_s2, q_nd)
        last = self.flush()
        return dataclasses.replace(GaitResult.concat([first, last]),
                                   heading_frame=first.heading_frame)
