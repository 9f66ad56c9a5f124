"""The tracker's fusion engine: the position filter state driven by the scheduled events.

Runs of fast rows (steps, tight RSS readings or scans, ranges, fixes) go through the compiled
loop of :mod:`hrtls.pipeline._events`; slow events (tag groups, bearings, the fixes the loop
hands back, and with the velocity-driven prediction every observation) are applied one at a
time by :mod:`hrtls.pipeline.observations`. With ``prediction.model = "velocity"`` the
buffered speed and yaw samples (Colombo eq. 16-17) are integrated up to each event.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from hrtls.data import Activity, Landmark, StepEvents
from hrtls.frames import quat_conjugate, quat_multiply, wrap_angle
from hrtls.fusion.channel import ChannelState
from hrtls.fusion.fixes import FixCorrector, FixSchedule, StretchMemory, YawPseudoMeasurement
from hrtls.fusion.random_walk import predict_random_walk
from hrtls.fusion.state import FilterState
from hrtls.fusion.tags import TagMemory
from hrtls.gait.analyzer import GaitResult
from hrtls.pipeline import _events as ev
from hrtls.pipeline import _fix_events as fx
from hrtls.pipeline import build
from hrtls.pipeline.build import Corrections, Notes
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.corrections import SMOOTHED, CorrectionLog, source_of
from hrtls.pipeline.diagnostics import DiagnosticsBlock, DiagnosticsLog
from hrtls.pipeline.grid_stage import GridStage
from hrtls.pipeline.imu_stage import DEFAULT_VAR_YAW_RAD2, AttitudeStage
from hrtls.pipeline.landmark_updates import LandmarkVersions
from hrtls.pipeline.observations import apply_fix, apply_observation, step_at
from hrtls.pipeline.output import TrackRows
from hrtls.pipeline.schedule import FIX, MAGNETIC, EventSchedule, PoseGate
from hrtls.pipeline.step_scale import StepScaleLearner

MOVING_SIGMA_M_S2 = 0.2
"""Colombo's sigma_min: the user moves when the 2 s std of vertical acceleration exceeds it."""
VELOCITY_ROW_PERIOD_S = 0.04
"""Output period of the trajectory rows of the velocity-driven prediction (s)."""


def _last_starting_by(blocks: Sequence[Any], t: float,
                      times: Callable[[Any], np.ndarray] = lambda b: b) -> int:
    """Index of the last non-empty block whose first time is at or before ``t`` (0: none).

    ``times`` gives a block's times. Searched from the end and lazily (blocks are in time
    order; a long mission has many, and the answer is near the end).
    """
    for k in range(len(blocks) - 1, -1, -1):
        b = times(blocks[k])
        if len(b) and b[0] <= t:
            return k
    return 0


class GaitHistory:
    """Steps and motion levels released by the gait stage (what later events look back on)."""

    def __init__(self) -> None:
        self.steps: list[StepEvents] = []
        self.motion_t: list[np.ndarray] = []
        self.motion_sigma: list[np.ndarray] = []
        self.hidden = 0
        """Leading step blocks restored from a snapshot (not in the result)."""

    def moving(self, t: float) -> bool | None:
        """The motion level at ``t`` exceeds ``MOVING_SIGMA_M_S2`` (None: no motion yet)."""
        if not self.motion_t:
            return None
        mt = self.motion_t[-1]
        ms = self.motion_sigma[-1]
        for tt, ss in zip(reversed(self.motion_t), reversed(self.motion_sigma), strict=True):
            if len(tt) and tt[0] <= t:
                mt, ms = tt, ss
                break
        # np.interp on the two samples around t (the same value, without a pass over the block)
        j = int(np.searchsorted(mt, t, side="right"))
        lo, hi = max(j - 1, 0), min(j + 1, len(mt))
        return bool(np.interp(t, mt[lo:hi], ms[lo:hi]) > MOVING_SIGMA_M_S2)

    def state(self, t: float) -> dict[str, Any]:
        """What the future still needs from ``t`` on (snapshot).

        The step block in progress at ``t`` and the motion blocks from the latest one before.
        """
        j = _last_starting_by(self.steps, t, lambda b: b.t_start)
        m = self._first_motion(t)
        return {"steps": self.steps[j:], "motion_t": self.motion_t[m:],
                "motion_sigma": self.motion_sigma[m:]}

    def forget_motion_before(self, t: float) -> None:
        """Drop the motion blocks no event from ``t`` on looks at (as :meth:`state` does)."""
        m = self._first_motion(t)
        del self.motion_t[:m], self.motion_sigma[:m]

    def _first_motion(self, t: float) -> int:
        """The latest motion block starting at or before ``t`` (0 when none does)."""
        return _last_starting_by(self.motion_t, t)

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state` (the restored steps are not reported again)."""
        self.steps = list(state["steps"])
        self.hidden = len(self.steps)
        self.motion_t = list(state["motion_t"])
        self.motion_sigma = list(state["motion_sigma"])


class FusionEngine:
    """Filter state, output rows and diagnostics of one tracker, advanced event by event."""

    STATE = ("state", "last_activity", "last_step_end", "yaw_offset", "vel_t", "vel_v",
             "vel_yaw", "vel_var", "vel_bin", "stretch", "corrected_since_fix", "last_speed",
             "recent_heading", "fix_schedule", "fix_phase_set", "tag_memory", "channel_state",
             "flight")
    """Plain attributes of the engine's state (snapshot)."""

    def __init__(self, config: TrackerConfig, parts: Corrections, *, state: FilterState,
                 landmarks: dict[str, Landmark], schedule: EventSchedule, pose: PoseGate,
                 scale: StepScaleLearner, gait: GaitHistory, params: np.ndarray,
                 has_imu: bool, velocity_mode: bool, running_factor: float, t0: float,
                 notes: Notes) -> None:
        self.config = config
        self.parts = parts
        self.landmarks = landmarks
        self.versions = LandmarkVersions()
        self.schedule = schedule
        self.pose = pose
        self.scale = scale
        self.gait = gait
        self.params = params
        self.has_imu = has_imu
        self.velocity_mode = velocity_mode
        self.running_factor = running_factor
        self.t0 = t0
        self.attitude: AttitudeStage | None = None
        self.state = state
        self.diagnostics = DiagnosticsLog()
        self.track = TrackRows()
        self.track.add(state, int(Activity.UNKNOWN))
        self.last_activity = int(Activity.UNKNOWN)
        self.last_step_end = -math.inf
        self.flight: tuple[float, ...] = ev.NO_FLIGHT
        self.yaw_offset = 0.0
        self.vel_t = np.zeros(0)
        self.vel_v = np.zeros(0)
        self.vel_yaw = np.zeros(0)
        self.vel_var = np.zeros(0)
        self.vel_bin = -math.inf
        self.stretch: StretchMemory | None = None
        self.corrected_since_fix = False
        self.last_speed = 0.0
        self.recent_heading: deque[tuple[float, float]] = deque(maxlen=16)
        self.fix_schedule = FixSchedule()
        self.fix_phase_set = False
        self.tag_memory = TagMemory()
        self.grid = GridStage.build(config, landmarks, parts.path_loss, has_imu=has_imu, t0=t0,
                                    z_m=float(state.x[2]), notes=notes)
        """RSS without an IMU (:mod:`hrtls.pipeline.grid_stage`)."""
        self.channel_state: ChannelState | None = (
            None if parts.channel_estimator is None
            else parts.channel_estimator.start(parts.path_loss))
        self.fix_jumps: list[tuple[float, float, float]] = []
        """Accepted fixes: time of the output row holding the corrected state, position change
        (east, north) made by the fix, m."""
        self.corrections = CorrectionLog()
        """Every update that moved the position (:mod:`hrtls.pipeline.corrections`)."""
        self.yaw_pseudo: list[YawPseudoMeasurement] = []
        self.mag_heading = build.mag_heading(config)
        """The magnetic heading measurement (``heading_source = "gyro+compass"``), or None."""
        self.fix_params = fx.fix_params(config, parts.fix_corrector.params, scale.params,
                                        running_factor=running_factor)

    # ------------------------------------------------------------------ event loop
    def drain(self, horizon: float) -> None:
        """Apply every queued event up to ``horizon`` in order (time, kind, arrival)."""
        sched = self.schedule
        att = self.attitude
        if att is not None and len(att.mag_rows):
            # field blocks of the magnetic heading measurement, from the start pose on
            for row in att.mag_rows[att.mag_rows[:, 0] >= self.pose.t_pose]:
                sched.push(float(row[0]), MAGNETIC, row)
            att.mag_rows = att.mag_rows[:0]
        while True:
            slow = sched.next_slow(horizon)
            if slow is not None:
                t, kind, _, payload = slow
                self.advance_without_steps(t)
                pre = self.state
                apply_observation(self, t, kind, payload)
                self.corrections.add(self.state.t, kind, source_of(kind, payload), pre.x, pre.P,
                                     self.state.x, self.state.P)
                self.track.add(self.state, self.last_activity)
                continue
            if not sched.has_fast(horizon):
                break
            self._run_kernel(*sched.fast_run(horizon))
        if self.velocity_mode:
            self.velocity_to(horizon)
        if horizon == math.inf:
            self.grid.finish()

    def set_smoothed(self, x: np.ndarray, p: np.ndarray) -> bool:
        """The state and covariance now set from outside (the mission smoother's feedback).

        Recorded as a ``SMOOTHED`` correction; its row replaces the latest (same time). Not with
        the velocity-driven prediction or the grid filter (False).
        """
        if self.velocity_mode or self.grid.filter is not None:
            return False
        pre = self.state
        self.state = replace(pre, x=np.asarray(x, np.float64), P=np.asarray(p, np.float64))
        self.corrections.add(pre.t, SMOOTHED, "smoother", pre.x, pre.P, x, p)
        self.track.add(self.state, self.last_activity)
        return True

    def output_rows(self) -> TrackRows:
        """The rows of the track: the grid filter's when it runs, else the Kalman filter's."""
        return self.grid.rows if self.grid.filter is not None else self.track

    def _run_kernel(self, b0: int, b1: int) -> None:
        """Buffer rows ``b0:b1`` (steps, RSS readings or scans, ranges, fixes) in the loop.

        The loop hands back the fixes it does not apply (:mod:`hrtls.pipeline._fix_events`):
        each goes through :func:`~hrtls.pipeline.observations.apply_fix`, then the loop
        continues after it.
        """
        while b0 < b1:
            stop = self._kernel_part(b0, b1)
            if stop < 0:
                return
            sched = self.schedule
            t = float(sched.bulk_t[stop])
            row = sched.bulk_data[stop]
            self.advance_without_steps(t)
            pre = self.state
            apply_fix(self, t, (row[:3].copy(), float(row[3]), False))
            self.corrections.add(self.state.t, FIX, str(sched.bulk_src[stop]), pre.x, pre.P,
                                 self.state.x, self.state.P)
            self.track.add(self.state, self.last_activity)
            b0 = stop + 1

    def _kernel_part(self, b0: int, b1: int) -> int:
        """The loop on rows ``b0:b1``; the row it stopped before (a fix for Python) or -1.

        The step scale, running factor, yaw offset and the yaw variance at each step are
        applied inside the kernel (``step_scale``, ``running_multiplier``, ``yaw_offset_rad`` of
        the loop state).
        """
        sched = self.schedule
        n = b1 - b0
        tt = sched.bulk_t[b0:b1]
        kind = sched.bulk_ev[b0:b1]
        data = sched.bulk_data[b0:b1]
        st = self.state
        x = st.x.copy()
        p = st.P.copy()
        cstate = self.channel_state if self.parts.channel_estimator is not None else None
        sc_ = self.scale
        rec, chan_cov = ev.loop_state(
            st, path_loss=self.parts.path_loss, channel=cstate, last_activity=self.last_activity,
            last_step_end_s=self.last_step_end, step_scale=sc_.step_scale,
            running_multiplier=self.running_factor * sc_.run_scale / sc_.step_scale,
            yaw_offset_rad=self.yaw_offset, scan_base=sched.scan_base, flight=self.flight)
        fixes = np.flatnonzero(kind == ev.EV_FIX)
        lead = _leads(self.gait.steps, tt, data, fixes)
        fst = self._fix_state()
        out = _KernelOut(n)
        recent = np.empty((ev.N_RECENT, 2))
        att = self.attitude
        var_t = att.var_t if att is not None else np.zeros(0)
        var_v = att.var_v if att is not None else np.zeros(0)
        ev.event_kernel(kind, tt, data, self.params, rec, chan_cov, x, p, out.t, out.x, out.cov,
                        out.var_h, out.act, out.status, out.nis, out.s, out.nu, sched.scan_rows,
                        out.aux, var_t, var_v, recent, self.fix_params, fst, lead, out.jump,
                        out.pre)
        sc = rec[0]
        f = fst[0]
        stop = int(f["stop"])
        m = n if stop < 0 else stop
        self.state = FilterState.from_kernel(float(sc["t"]), x, p, float(sc["input_heading_rad"]),
                                             bool(sc["has_input_heading"]),
                                             bool(sc["reference_pending"]))
        self.last_activity = int(sc["last_activity"])
        self.last_step_end = float(sc["last_step_end_s"])
        self.yaw_offset = float(sc["yaw_offset_rad"])
        self.flight = tuple(sc["flight"].tolist())
        # corrections since the last fix and soft corrections since the learner's anchor:
        # an accepted scan (Kalman mode) counts for the first only, the WLS jump for neither
        self.corrected_since_fix = bool(f["corrected_since_fix"])
        sc_.soft_since_anchor = bool(f["soft_since_anchor"])
        if len(fixes):
            self._fixes_back(f, float(sc["step_scale"]), out, m)
        sc_.walked(float(sc["path_m"]), float(sc["running_path_m"]))
        if cstate is not None:
            self.channel_state = ChannelState.from_record(sc["channel"], chan_cov)
        self.track.add_block(out.t[:m], out.x[:m], out.cov[:m], out.var_h[:m], out.act[:m])
        pre = out.pre[:m]
        moved = np.flatnonzero((pre[:, 0] != out.x[:m, 0]) | (pre[:, 1] != out.x[:m, 1]))
        moved = moved[np.isfinite(pre[moved, 0])]
        if len(moved):
            after = np.column_stack([out.x[moved, :2], out.cov[moved, 0, 0],
                                     out.cov[moved, 0, 1], out.cov[moved, 1, 1]])
            self.corrections.add_block(out.t[moved], sched.bulk_k[b0:b1][moved],
                                       sched.bulk_src[b0:b1][moved], pre[moved], after)
        n_steps = int(sc["n_steps"])
        n_head = int(sc["n_headings"])
        if n_head:
            # the last raw step headings (before the yaw offset), for the turn test of bearings
            last = recent.tolist()
            if n_head > ev.N_RECENT:      # ring: oldest first
                cut = n_head % ev.N_RECENT
                last = last[cut:] + last[:cut]
            self.recent_heading.extend(
                (float(ts), float(hd)) for ts, hd in last[:min(n_head, ev.N_RECENT)])
        if n_steps < m:
            obs = np.flatnonzero(kind[:m] != ev.EV_STEP) if n_steps else np.arange(m)
            self._kernel_diagnostics(b0, obs, out, sc["n_scans"] > 0 or len(fixes) > 0)
            sched.trim_scan_rows()
        return -1 if stop < 0 else b0 + stop

    def _fix_state(self) -> np.ndarray:
        """The loop's fix state (:data:`hrtls.pipeline._fix_events.FIX_STATE_DTYPE`)."""
        sc_ = self.scale
        return fx.fix_state(
            phase_s=self.parts.fix_corrector.params.phase_s if self.fix_phase_set else None,
            last_slot=self.fix_schedule.last_slot, rejections=self.fix_schedule.rejections,
            corrected_since_fix=self.corrected_since_fix, has_memory=self.stretch is not None,
            run_scale=sc_.run_scale, anchor_xy=sc_.anchor_xy,
            path_since_anchor_m=sc_.path_since_anchor, run_since_anchor_m=sc_.run_since_anchor,
            soft_since_anchor=sc_.soft_since_anchor,
            last_heading_rad=self.recent_heading[-1][1] if self.recent_heading else math.nan,
            last_row_t=(math.nan if (lt := self.track.last_time()) is None else lt))

    def _fixes_back(self, f: np.void, step_scale: float, out: _KernelOut, m: int) -> None:
        """Take back what the loop's fix rows changed.

        The fix policy, the stretching memory, the step-scale learner, the accepted jumps.
        """
        if bool(f["phase_set"]) and not self.fix_phase_set:
            self.fix_phase_set = True
            prm = self.parts.fix_corrector.params
            self.parts.fix_corrector = FixCorrector(replace(prm, phase_s=float(f["phase_s"])))
        self.fix_schedule = FixSchedule(int(f["last_slot"]) if f["has_last_slot"] else None,
                                        int(f["rejections"]))
        if f["memory_new"]:
            mem = f["memory"].tolist()
            empty = np.zeros(0)
            self.stretch = StretchMemory(mem[0], np.array(mem[1:3]), np.array(mem[3:5]), mem[5],
                                         empty, empty, empty)
        sc_ = self.scale
        sc_.step_scale = step_scale
        sc_.run_scale = float(f["run_scale"])
        if f["has_anchor"]:
            sc_.anchor_xy = f["anchor_xy"].copy()
        sc_.path_since_anchor = float(f["path_since_anchor_m"])
        sc_.run_since_anchor = float(f["run_since_anchor_m"])
        done = np.flatnonzero(np.isfinite(out.jump[:m, 0]))
        self.fix_jumps.extend(zip(out.t[done].tolist(), out.jump[done, 0].tolist(),
                                  out.jump[done, 1].tolist(), strict=True))

    def _kernel_diagnostics(self, b0: int, obs: np.ndarray, out: _KernelOut,
                            has_2d: bool) -> None:
        """One diagnostics block for the observation rows ``obs`` (relative to ``b0``)."""
        sched = self.schedule
        rows = obs + b0
        labels = sched.bulk_label[rows]
        reasons = sched.label_reason[labels]
        code = out.status[obs]
        dof = nu2 = s2 = None
        if has_2d:
            evk = sched.bulk_ev[rows]
            dof = np.where((evk == ev.EV_SCAN) | (evk == ev.EV_FIX), 2, 1)
            # a scan with < 3 anchors is "skipped" (its reason was set when it was queued)
            reasons = np.where(code == ev.ST_COLLINEAR, "anchors are collinear",
                               np.where(code == ev.ST_WLS, "WLS position (RSS alone)",
                                        reasons))
            for st_code, fix_code in ((ev.ST_FIX_SERVED, fx.FIX_SERVED),
                                      (ev.ST_FIX_OFF, fx.FIX_OFF_PERIOD)):
                reasons = np.where(code == st_code, fx.SKIP_REASONS[fix_code], reasons)
            code = np.where((code == ev.ST_FEW) | (code == ev.ST_FIX_SERVED)
                            | (code == ev.ST_FIX_OFF), ev.ST_SKIPPED, code)
            nu2 = out.aux[obs, :2]
            s2 = out.aux[obs, 2:5]
        self.diagnostics.add_block(DiagnosticsBlock(
            sched.label_kind[labels], sched.bulk_t[rows], code, out.nis[obs], out.s[obs],
            out.nu[obs], sched.bulk_src[rows], reasons, float(self.params["gate_1d"][0]),
            dof=dof, nu2=nu2, s2=s2, threshold2=float(self.params["gate_2d"][0])))

    def advance_without_steps(self, t: float) -> None:
        """Bring the state to ``t`` before a correction when no step or velocity drives it."""
        if self.velocity_mode:
            self.velocity_to(t)
        if t <= self.state.t:
            return
        st = self.state
        if not self.has_imu:
            self.state = predict_random_walk(st, t, self.parts.random_walk)
        else:   # only the time changes: no need to validate the state again
            self.state = FilterState.from_kernel(t, st.x, st.P, st.input_heading_rad,
                                                 st.has_input_heading, st.reference_pending)

    def moving(self, t: float) -> bool:
        """Whether the user moves at ``t`` (the fixes' motion condition, Colombo eq. 19)."""
        if self.velocity_mode:
            # eq. 19 literally: sigma(a_xu) > sigma_min, i.e. the automaton is in a motion
            # state (non-zero speed) at the last sample up to t
            return self.last_speed > 0.0
        m = self.gait.moving(t)
        return t - self.last_step_end < 1.5 if m is None else m

    # ------------------------------------------------------------------ velocity model
    def buffer_velocity(self, result: GaitResult, t: np.ndarray, q_nd: np.ndarray,
                        mounting_q_bd: tuple[float, ...] | None) -> None:
        """Keep the velocity samples (Colombo eq. 16-17 inputs) until events reach them."""
        vt = result.velocity_t
        q_bd = (np.array([1.0, 0, 0, 0]) if mounting_q_bd is None
                else np.asarray(mounting_q_bd, dtype=np.float64))
        idx = np.clip(np.searchsorted(t, vt), 0, len(t) - 1)
        # yaw of the body x axis (first column of the rotation matrix of q_nb)
        w, x, y, z = quat_multiply(q_nd[idx], quat_conjugate(q_bd)).T
        yaw = np.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))
        assert self.attitude is not None
        var = self.attitude.var_yaw_at(vt)
        var = np.where(np.isfinite(var), var, DEFAULT_VAR_YAW_RAD2)
        self.vel_t = np.concatenate([self.vel_t, vt])
        self.vel_v = np.concatenate([self.vel_v, np.maximum(result.velocity_m_s, 0.0)])
        self.vel_yaw = np.concatenate([self.vel_yaw, yaw])
        self.vel_var = np.concatenate([self.vel_var, var])

    def velocity_to(self, t_end: float) -> None:
        """Colombo eq. 16-17 through the buffered samples up to ``t_end`` (rows at <= 25 Hz)."""
        n = int(np.searchsorted(self.vel_t, t_end, side="right"))
        if n == 0:
            return
        vt, vv = self.vel_t[:n], self.vel_v[:n]
        yaw = np.asarray(wrap_angle(self.vel_yaw[:n] + self.yaw_offset))
        var = self.vel_var[:n]
        self.vel_t, self.vel_v = self.vel_t[n:], self.vel_v[n:]
        self.vel_yaw, self.vel_var = self.vel_yaw[n:], self.vel_var[n:]
        keep = vt > self.state.t
        if self.pose.t_pose > self.t0:
            self.pose.keep("velocity samples", vt)
        if not np.any(keep):
            return
        vt, vv, yaw, var = vt[keep], vv[keep], yaw[keep], var[keep]
        self.scale.walked(float(np.sum(np.diff(vt, prepend=self.state.t) * vv)))
        self.last_speed = float(vv[-1])
        res = self.parts.velocity_predictor.run(self.state, vt, vv, yaw, var)
        self.state = res.state
        if self.stretch is not None:
            self.stretch = self.stretch.extended(vt, vv, yaw)
        # output rows: the first sample of every 40 ms bin (the same in chunked runs)
        bins = np.floor(vt / VELOCITY_ROW_PERIOD_S)
        sel = np.flatnonzero(np.diff(np.concatenate([[self.vel_bin], bins])) != 0)
        self.vel_bin = float(bins[-1])
        if len(sel) == 0:
            return
        x = np.column_stack([res.xyz[sel], res.heading_rad[sel]])
        act = np.where(vv[sel] > 0.05, int(Activity.WALKING), int(Activity.STANDING))
        self.last_activity = int(act[-1])
        self.track.add_block(vt[sel], x, res.cov_xy[sel], res.var_heading[sel], act)

    # ------------------------------------------------------------------ snapshot
    def state_dict(self) -> dict[str, Any]:
        """Plain state for a snapshot (the last output row, not the rows before)."""
        rows = self.track
        last_row = None
        if rows.last_time() is not None:
            last_row = (float(rows.t[-1][-1]), rows.x[-1][-1], rows.cov[-1][-1],
                        float(rows.var_h[-1][-1]), int(rows.activity[-1][-1]))
        out = {name: getattr(self, name) for name in self.STATE}
        out["last_row"] = last_row
        out["fix_phase_s"] = self.parts.fix_corrector.params.phase_s
        out["landmark_versions"] = self.versions.state()
        out["grid"] = self.grid.state_dict()
        out["mag_heading"] = None if self.mag_heading is None else self.mag_heading.state
        out["corrections_count"] = self.corrections.count()
        return out

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict`.

        A state without the flight rule's (from before it was kept) starts it afresh.
        """
        for name in self.STATE:
            setattr(self, name, state.get(name, ev.NO_FLIGHT) if name == "flight"
                    else state[name])
        if "landmark_versions" in state:   # snapshots from before landmark updates have none
            self.versions.restore(state["landmark_versions"])
        self.grid.restore(state.get("grid"))
        if self.mag_heading is not None:
            self.mag_heading.state = state["mag_heading"]
        self.track = TrackRows()
        self.corrections = CorrectionLog(int(state.get("corrections_count", 0)))
        if state["last_row"] is not None:
            t_r, x_r, cov_r, var_r, act_r = state["last_row"]
            self.track.add_block(np.array([t_r]), x_r[None, :], cov_r[None], np.array([var_r]),
                                 np.array([act_r]))
            self.track.hidden = 1
        if self.fix_phase_set:
            self.parts.fix_corrector = FixCorrector(replace(self.parts.fix_corrector.params,
                                                            phase_s=state["fix_phase_s"]))


def _leads(steps: list[StepEvents], t: np.ndarray, data: np.ndarray,
           fixes: np.ndarray) -> np.ndarray:
    """The step in progress at each fix row (``_fix_events.LEAD_*`` columns, NaN: none).

    The fix rows of ``data`` get the index of their row of it.
    """
    lead = np.full((len(fixes), 5), np.nan)
    if not len(fixes):
        return lead
    for j, r in enumerate(fixes.tolist()):
        step = step_at(steps, float(t[r]))
        if step is not None:
            lead[j] = step
    data[fixes, 4] = np.arange(len(fixes))
    return lead


class _KernelOut:
    """Output arrays of one run of the compiled loop (n rows)."""

    def __init__(self, n: int) -> None:
        self.t = np.empty(n)
        self.x = np.empty((n, 4))
        self.cov = np.empty((n, 2, 2))
        self.var_h = np.empty(n)
        self.jump = np.empty((n, 2))
        self.pre = np.empty((n, 5))
        self.act = np.empty(n, dtype=np.int64)
        self.status = np.empty(n, dtype=np.int64)
        self.nis = np.empty(n)
        self.s = np.empty(n)
        self.nu = np.empty(n)
        self.aux = np.empty((n, 5))
