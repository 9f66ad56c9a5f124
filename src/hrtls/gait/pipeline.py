"""The gait stage: motion, activity, steps, step length, heading and walking velocity.

:class:`GaitAnalyzer` composes the sub-algorithms it is given (each is one module of
:mod:`hrtls.gait`) and runs them over an accelerometer stream, optionally with an attitude
quaternion series. The same :meth:`GaitAnalyzer.update` serves offline processing (one chunk,
then :meth:`GaitAnalyzer.flush`) and the live service (many chunks).

Outputs of a call are what became final during it: the steps whose activity window is complete
(a step is held until the activity of the window containing its end is known), per-sample
activity of completed windows, and per-sample walking velocity. Concatenating the outputs of all
chunks (plus the flush) gives the same result as one offline call.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity, Session, StepEvents
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import GRAVITY_M_S2, quat_conjugate, quat_rotate, quat_to_matrix
from hrtls.gait._state import FloatArray, as_matrix, as_time, check_positive
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds, classify_tree
from hrtls.gait.features import StreamingButterworth, WindowFeatures, window_features
from hrtls.gait.fourier_heading import FourierHeading
from hrtls.gait.motion import STILL, MotionDetector, MotionParams
from hrtls.gait.peak_steps import PeakStepDetector
from hrtls.gait.pll import PllStepDetector, StepDetection
from hrtls.gait.step_length import StairsModel, StepModel, WeinbergModel, displacements
from hrtls.gait.velocity_automaton import VelocityAutomaton
from hrtls.gait.vertical import (
    GravityLevelling,
    LevelledAcceleration,
    from_orientation,
    rotate,
)

IntArray = NDArray[np.int64]
HeadingSource = Literal["fourier", "yaw", "none"]


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
                   parts[-1].heading_frame, feats)


@dataclass
class _Pending:
    """Samples waiting for their activity window and steps waiting for their activity."""

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    acc: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    steps: list[StepDetection] = field(default_factory=list)
    headings: list[FloatArray] = field(default_factory=list)
    win_end: list[float] = field(default_factory=list)
    win_label: list[int] = field(default_factory=list)
    last_label: int = int(Activity.UNKNOWN)
    yaw_last: float = float("nan")
    heading_last: float = float("nan")


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
        Drop steps that end while the motion detector reports standing still.
    activity_window_s, activity_cutoff_hz:
        Window and low-pass corner of the activity features when ``activity`` is not an
        :class:`LdaModel` (a model carries its own), s and Hz.
    """

    def __init__(self, *, rate_hz: float, step_detector: PeakStepDetector | PllStepDetector
                 | None = None, step_model: StepModel | None = None,
                 stairs: StairsModel | None = None,
                 activity: LdaModel | TreeThresholds | None = None,
                 heading: HeadingSource = "fourier", fourier: FourierHeading | None = None,
                 velocity: VelocityAutomaton | None = None, motion: MotionParams | None = None,
                 mounting_q_bd: FloatArray | None = None, step_cutoff_hz: float = 3.0,
                 gate_steps_with_motion: bool = False, activity_window_s: float = 2.0,
                 activity_cutoff_hz: float = 6.0) -> None:
        check_positive(rate_hz, "rate_hz")
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
        self._step_delay_s = self._step_filter.group_delay_s(1.8)
        self._levelling = GravityLevelling()
        self.reset()

    def reset(self) -> None:
        """Start over (all estimators reset)."""
        self.step_detector.reset()
        self.fourier.reset()
        if self.velocity is not None:
            self.velocity.reset()
        self.motion.reset()
        self._levelling.reset()
        self._act_filter.reset()
        self._step_filter.reset()
        self._pending = _Pending()
        self._t_last = -np.inf
        self._frame = "levelled"

    # ------------------------------------------------------------------ helpers
    def _level(self, t: FloatArray, acc: FloatArray,
               q_nd: FloatArray | None) -> LevelledAcceleration:
        if q_nd is None:
            return self._levelling.update(t, acc)
        return from_orientation(t, acc, q_nd)

    def _window_labels(self, feats_tree: FloatArray, feats_lda: FloatArray,
                       sigma_end: FloatArray) -> IntArray:
        if isinstance(self.activity, LdaModel):
            return self.activity.predict(feats_lda)
        if isinstance(self.activity, TreeThresholds):
            return classify_tree(feats_tree, self.activity)
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
        motion = self.motion.update(tt, lev.vertical_m_s2)

        # --- steps
        if isinstance(self.step_detector, PllStepDetector):
            det = self.step_detector.update(lev.vertical_m_s2, motion).steps
        else:
            det = self.step_detector.update(tt, self._step_filter.update(lev.vertical_m_s2))
            # report the steps at the peaks of the unfiltered signal: remove the filter delay
            det = StepDetection(det.t_start - self._step_delay_s, det.t_end - self._step_delay_s,
                                det.frequency_hz, det.acc_max, det.acc_min)
        if self.gate_steps_with_motion and len(det):
            idx = np.clip(np.searchsorted(tt, det.t_end), 0, tt.shape[0] - 1)
            keep = motion.state[idx] != STILL
            det = StepDetection(det.t_start[keep], det.t_end[keep], det.frequency_hz[keep],
                                det.acc_max[keep], det.acc_min[keep])

        # --- heading per step
        # body forward axis in ENU: rotate the device-frame image of body x by q_nd
        fwd_n = None
        if q_nd is not None:
            fwd_d = quat_rotate(quat_conjugate(self.q_bd), np.array([1.0, 0.0, 0.0]))
            fwd_n = rotate(q_nd, fwd_d)
        if self.heading == "fourier":
            head = self.fourier.update(tt, lev.horizontal_m_s2, det.t_end).heading_rad
        elif self.heading == "yaw" and fwd_n is not None:
            # mean direction of the body forward axis over the step (its start and end)
            yaw = np.unwrap(np.arctan2(fwd_n[:, 1], fwd_n[:, 0]))
            prev = self._pending.yaw_last
            y_end = np.interp(det.t_end, tt, yaw)
            y_start = np.interp(det.t_start, tt, yaw)
            if np.isfinite(prev):
                y_start = np.where(det.t_start < tt[0], prev, y_start)
            head = np.arctan2(np.sin(y_start) + np.sin(y_end), np.cos(y_start) + np.cos(y_end))
            self._pending.yaw_last = float(yaw[-1])
        else:
            head = np.full(len(det), np.nan)

        # walking direction held from the latest finite step heading (forward fill)
        ok = np.isfinite(head)
        at = np.searchsorted(tt, det.t_end[ok])
        src = np.full(tt.shape[0], -1, dtype=np.int64)
        src[np.clip(at, 0, tt.shape[0] - 1)] = np.arange(at.shape[0])
        src = np.maximum.accumulate(src)
        psi_held = np.concatenate([[self._pending.heading_last], head[ok]])[src + 1]
        if ok.any():
            self._pending.heading_last = float(head[ok][-1])

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
        # AP/ML axes: the mounting when known, else the levelled horizontal acceleration turned
        # into the held walking direction (raw levelled axes until a heading exists)
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
        lp = self._act_filter.update(feat_in)
        pend = self._pending
        pend.t = np.concatenate([pend.t, tt])
        pend.acc = np.concatenate([pend.acc, lp])
        sigma_all = np.concatenate([np.full(pend.t.shape[0] - tt.shape[0], np.nan),
                                    motion.sigma_m_s2])
        j = self.window_samples
        nw = pend.t.shape[0] // j
        act_t = pend.t[: nw * j]
        if nw:
            wf = window_features(act_t, pend.acc[: nw * j], window_samples=j,
                                 anthropometric_nr=(self.activity.anthropometric_nr
                                                    if isinstance(self.activity, TreeThresholds)
                                                    else 1.0))
            sig_end = sigma_all[np.arange(1, nw + 1) * j - 1]
            sig_end = np.where(np.isfinite(sig_end), sig_end, 0.0)
            labels = self._window_labels(wf.tree, wf.lda, sig_end)
            act = np.repeat(labels, j)
            pend.win_end.extend(wf.t_end.tolist())
            pend.win_label.extend(labels.tolist())
            pend.last_label = int(labels[-1])
            pend.t = pend.t[nw * j:]
            pend.acc = pend.acc[nw * j:]
            feats = wf
        else:
            act = np.zeros(0, dtype=np.int64)
            feats = WindowFeatures(np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 7)))
        pend.steps.append(det)
        pend.headings.append(np.asarray(head, dtype=np.float64))
        steps = self._release(final=False)
        return GaitResult(steps, act_t, act.astype(np.int64), vel_t, vel_v, motion.sigma_m_s2,
                          lev.frame, feats)

    def _release(self, *, final: bool) -> StepEvents:
        """Steps whose activity window is known (all of them when ``final``)."""
        pend = self._pending
        det = StepDetection.concat(pend.steps)
        head = np.concatenate(pend.headings) if pend.headings else np.zeros(0)
        ends = np.asarray(pend.win_end)
        labels = np.asarray(pend.win_label, dtype=np.int64)
        if final:
            ready = np.ones(len(det), dtype=bool)
        else:
            ready = det.t_end <= (ends[-1] if ends.size else -np.inf)
        sel = np.flatnonzero(ready)
        rest = np.flatnonzero(~ready)
        w = np.searchsorted(ends, det.t_end[sel], side="left")
        act = np.where(w < labels.size, labels[np.clip(w, 0, max(labels.size - 1, 0))]
                       if labels.size else int(Activity.UNKNOWN),
                       pend.last_label).astype(np.int64)
        if act.size and labels.size == 0:
            act[:] = int(Activity.WALKING)
        act = np.where(act == int(Activity.UNKNOWN), int(Activity.WALKING), act)
        released = StepDetection(det.t_start[sel], det.t_end[sel], det.frequency_hz[sel],
                                 det.acc_max[sel], det.acc_min[sel])
        length, dz = displacements(released, act, self.step_model, self.stairs)
        pend.steps = [StepDetection(det.t_start[rest], det.t_end[rest], det.frequency_hz[rest],
                                    det.acc_max[rest], det.acc_min[rest])]
        pend.headings = [head[rest]]
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
                                acc_min=released.acc_min)

    def flush(self) -> GaitResult:
        """End of the recording: release held steps and label the last partial window."""
        pend = self._pending
        steps = self._release(final=True)
        act_t = pend.t.copy()
        label = pend.last_label if pend.last_label != int(Activity.UNKNOWN) else int(
            Activity.STANDING)
        act = np.full(act_t.shape[0], label, dtype=np.int64)
        pend.t = np.zeros(0)
        pend.acc = np.zeros((0, 3))
        return GaitResult(steps, act_t, act, np.zeros(0), np.zeros(0), np.zeros(0), self._frame)

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
                          out.features)


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
