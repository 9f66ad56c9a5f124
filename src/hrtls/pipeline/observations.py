"""Slow events of the fusion engine, applied one at a time in Python (a few per second).

Position fixes (Colombo eq. 18-23) with the yaw from trajectory stretching (eq. 24-28) fed
back, tag groups (Inderst Sec. 4.3.2, with the fall-back to the thesis' strategies when every
lobe fails the gate), bearings of tags (eq. 4.21-4.22), and -- with the velocity-driven
prediction -- single RSS readings, RSS scans and ranges.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from hrtls.data import Activity, Landmark, StepEvents
from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.fusion.fixes import (
    DRIFT_MIN_PATH_M,
    FixCorrector,
    StretchMemory,
    YawPseudoMeasurement,
    partial_step,
    step_in_progress,
)
from hrtls.fusion.gating import UpdateDiagnostics, kalman_update, skipped
from hrtls.fusion.ranges import range_update
from hrtls.fusion.rss import rss_update
from hrtls.fusion.rss_scans import scan_position
from hrtls.fusion.state import IH, FilterState
from hrtls.fusion.tags import bearing_heading_correction
from hrtls.fusion.yaw_stretch import YawStretchParams, stretch_yaw
from hrtls.pipeline.schedule import BEARING, FIX, MAGNETIC, RANGE, RSS, TAGS

if TYPE_CHECKING:
    from hrtls.pipeline.engine import FusionEngine

BEARING_TURN_WINDOW_S = 3.0
"""Steps from this long before a tag read to its confirmation must agree within
``tags.bearing_max_turn_deg`` for the read's bearing to be used, s."""


def apply_observation(eng: FusionEngine, t: float, kind: int, payload: Any) -> None:
    """Apply one slow event at time ``t`` (the state already brought to ``t``)."""
    if kind == FIX:
        apply_fix(eng, t, payload)
    elif kind == RSS:
        apply_rss(eng, t, payload)
    elif kind == TAGS:
        apply_tags(eng, t, payload)
    elif kind == BEARING:
        tag_id, bearings, heading_at_read, t_read = payload
        turn = recent_turn(eng, t_read - BEARING_TURN_WINDOW_S, t)
        if turn > math.radians(eng.config.tags.bearing_max_turn_deg):
            eng.diagnostics.append(skipped(
                "bearing", t, f"turning ({math.degrees(turn):.0f} deg around the read)", tag_id))
            return
        # the bearing judged against the heading at the read, applied to the heading now
        shift = float(wrap_angle(eng.state.heading - heading_at_read))
        apply_bearing(eng, t, tag_id, np.asarray(bearings) + shift)
    elif kind == MAGNETIC:
        apply_magnetic(eng, t, np.asarray(payload))
    elif kind == RANGE:
        node, rng, sigma = payload
        lm = landmark_at(eng, node, t)
        if lm is None or lm.position is None:
            eng.diagnostics.append(skipped("range", t, _why_not(eng, node, t, "node"), node))
            return
        upd_r = range_update(eng.state, lm.xyz(), rng, sigma, params=eng.parts.range_params,
                             t=t, source=node)
        eng.state = upd_r.state
        eng.diagnostics.append(upd_r.diagnostics)
        eng.corrected_since_fix = eng.corrected_since_fix or upd_r.diagnostics.accepted


def apply_magnetic(eng: FusionEngine, t: float, row: np.ndarray) -> None:
    """A block of the field: the magnetic heading measurement (:mod:`~.mag_heading`)."""
    mh = eng.mag_heading
    if mh is None:
        return
    st = eng.state
    walking = eng.last_step_end >= t - mh.params.walk_window_s
    eng.state, diag = mh.apply(st, t, row, walking=walking,
                               input_heading_rad=st.input_heading_rad - eng.yaw_offset,
                               gate_probability=eng.config.gate_probability)
    eng.diagnostics.append(diag)


def landmark_at(eng: FusionEngine, landmark_id: str, t: float) -> Landmark | None:
    """The version of a landmark in force at ``t`` (None: unknown or destroyed)."""
    return eng.versions.at(eng.landmarks, landmark_id, t)


def _why_not(eng: FusionEngine, landmark_id: str, t: float, what: str) -> str:
    if eng.versions.destroyed_at(landmark_id, t):
        return "landmark destroyed"
    return f"{what} without a known position"


def _learn_scale(eng: FusionEngine, prior_xy: np.ndarray, post_xy: np.ndarray) -> None:
    eng.scale.correct(prior_xy, post_xy, learn=eng.config.prediction.learn_step_scale
                      and not eng.velocity_mode)


def apply_tags(eng: FusionEngine, t: float, ids: list[str]) -> None:
    """A group of tag reads (Inderst Sec. 4.3.2), then the bearings of the tags read."""
    cfg = eng.config
    prior_xy = eng.state.x[:2].copy()
    parts = eng.parts
    gone = [i for i in ids if eng.versions.destroyed_at(i, t)]
    eng.diagnostics.extend([skipped("tag", t, "landmark destroyed", i) for i in gone])
    ids = [i for i in ids if i not in gone]
    if not ids:
        return
    known = {i: lm for i in ids if (lm := landmark_at(eng, i, t)) is not None}
    upd = parts.tag_corrector.update_ids(eng.state, t=t, ids=ids, landmarks=known,
                                         memory=eng.tag_memory)
    if (parts.tag_fallback is not None and upd.strategy == 0
            and not any(d.accepted for d in upd.diagnostics)):
        # every lobe failed the gate: the dead reckoning, not the tag, is off --
        # re-initialize by the thesis' strategies (eq. 4.26-4.33)
        upd = parts.tag_fallback.update_ids(eng.state, t=t, ids=ids, landmarks=known,
                                            memory=eng.tag_memory)
    eng.state, eng.tag_memory = upd.state, upd.memory
    eng.diagnostics.extend(upd.diagnostics)
    if upd.strategy != -1 and any(d.accepted for d in upd.diagnostics):
        eng.corrected_since_fix = True
        _learn_scale(eng, prior_xy, eng.state.x[:2].copy())
    if cfg.tags.bearing_correction and upd.strategy != -1:
        for tag_id in ids:
            lm = known.get(tag_id)
            if lm is None or not lm.bearings_rad:
                continue
            if cfg.tags.bearing_confirm_s > 0.0:
                # decide once the next steps show whether the user was turning
                eng.schedule.push(t + cfg.tags.bearing_confirm_s, BEARING,
                                  (tag_id, tuple(lm.bearings_rad), eng.state.heading, t))
            else:
                apply_bearing(eng, t, tag_id, np.asarray(lm.bearings_rad))


def apply_bearing(eng: FusionEngine, t: float, tag_id: str, bearings: np.ndarray) -> None:
    """Inderst eq. 4.21-4.22 with the configured deadband, gate and mode."""
    cfg = eng.config.tags
    hc = bearing_heading_correction(
        eng.state, bearings, t=t, source=tag_id, gate_rad=math.radians(cfg.bearing_gate_deg),
        deadband_rad=math.radians(cfg.bearing_deadband_deg), mode=cfg.bearing_mode,
        sigma_rad=math.radians(cfg.bearing_sigma_deg),
        gate_probability=eng.config.gate_probability)
    eng.state = hc.state
    eng.diagnostics.append(hc.diagnostics)


def recent_turn(eng: FusionEngine, t_from: float, t_to: float) -> float:
    """Largest heading change between the steps ending in ``[t_from, t_to]`` (rad)."""
    hs = [h for (ts, h) in eng.recent_heading if t_from <= ts <= t_to]
    if len(hs) < 2:
        return 0.0 if hs else math.inf
    d = np.asarray(wrap_angle(np.asarray(hs) - hs[-1]))
    return float(np.max(np.abs(d)))


def step_at(steps: list[StepEvents], t: float) -> tuple[float, float, float, float, int] | None:
    """The step in progress at ``t`` with a finite heading, or None.

    ``(t_start, t_end, length_m, heading_rad, activity)`` as detected (before the step scale
    and the yaw offset).
    """
    for st in reversed(steps):
        if len(st) == 0 or st.t_start[0] > t:
            continue
        k = step_in_progress(t, st.t_start, st.t_end)
        if k >= 0 and math.isfinite(st.heading_rad[k]):
            return (float(st.t_start[k]), float(st.t_end[k]), float(st.length_m[k]),
                    float(st.heading_rad[k]), int(st.activity[k]))
        break
    return None


def _step_lead(eng: FusionEngine, t: float) -> np.ndarray:
    """Part of the step in progress at ``t`` (``fixes.partial_step``, our addition), m."""
    step = step_at(eng.gait.steps, t)
    if step is None or not step[1] > eng.state.t:
        return np.zeros(2)
    t_start, t_end, length, h_k, activity = step
    h_last = eng.recent_heading[-1][1] if eng.recent_heading else h_k
    scale = (eng.running_factor * eng.scale.run_scale
             if activity == int(Activity.RUNNING) else eng.scale.step_scale)
    return partial_step(t, t_start=t_start, t_end=t_end, length_m=length * scale,
                        heading_rad=float(eng.state.x[IH] + wrap_angle(h_k - h_last)))


def apply_fix(eng: FusionEngine, t: float, payload: Any) -> None:
    """Colombo eq. 18-23, then the yaw from trajectory stretching (eq. 24-28) fed back."""
    cfg = eng.config
    xyz, sigma, has_z = payload
    if not eng.fix_phase_set:
        # eq. 19 slots i Tp: anchored at the first fix (the query clock is unknown)
        eng.fix_phase_set = True
        prm = eng.parts.fix_corrector.params
        eng.parts.fix_corrector = FixCorrector(replace(prm, phase_s=t - prm.slot_tolerance_s / 2))
    prior_xy = eng.state.x[:2].copy()
    # step model: the state stands at the last finished step; the fix is compared with the
    # state plus the part of the step in progress at t
    lead = (_step_lead(eng, t) if cfg.fixes.partial_step and not eng.velocity_mode
            else np.zeros(2))
    xyz_cmp = np.asarray(xyz, dtype=np.float64).copy()
    xyz_cmp[:2] -= lead
    walked = eng.scale.path_since_anchor
    drift = cfg.fixes.drift_fraction * max(walked, DRIFT_MIN_PATH_M)
    upd = eng.parts.fix_corrector.update(eng.state, eng.fix_schedule, t=t, xyz=xyz_cmp,
                                         sigma_m=sigma, moving=eng.moving(t), has_z=has_z,
                                         drift_var_m2=drift * drift)
    eng.state, eng.fix_schedule = upd.state, upd.schedule
    eng.diagnostics.append(upd.diagnostics)
    if not upd.diagnostics.accepted:
        return
    jump = eng.state.x[:2] - prior_xy
    rows = eng.track.t
    if (np.any(lead != 0.0) and rows and len(rows[-1])
            and float(rows[-1][-1]) == eng.last_step_end):
        # the corrected state is the position at the last step end: its output row
        # replaces that step's row (a row at t would show it one partial step late)
        st_ = eng.state
        eng.state = FilterState.from_kernel(eng.last_step_end, st_.x, st_.P,
                                            st_.input_heading_rad, st_.has_input_heading,
                                            st_.reference_pending)
    # at the time of the output row that shows it
    eng.fix_jumps.append((eng.state.t, float(jump[0]), float(jump[1])))
    _learn_scale(eng, prior_xy, eng.state.x[:2].copy())
    # positions at t: the state plus the step in progress
    prior_xy = prior_xy + lead
    fix_xy = np.asarray(xyz[:2], dtype=np.float64)
    mem = eng.stretch
    if cfg.fixes.yaw_stretch and mem is not None and not eng.corrected_since_fix:
        _feed_back_stretch(eng, t, mem, prior_xy, fix_xy, sigma, walked)
    empty = np.zeros(0)
    eng.stretch = StretchMemory(t, eng.state.x[:2] + lead, fix_xy, sigma, empty, empty, empty)
    eng.corrected_since_fix = False


def _feed_back_stretch(eng: FusionEngine, t: float, mem: StretchMemory, prior_xy: np.ndarray,
                       fix_xy: np.ndarray, sigma: float, walked: float) -> None:
    """Yaw from stretching the path since the last fix onto the two fixes (eq. 24-28)."""
    cfg = eng.config
    if eng.velocity_mode:
        t_in, v_in, yaw_in = mem.t, mem.speed_m_s, mem.yaw_rad
    else:
        # steps since the last fix: one straight sample from the start to the prior, at a
        # nominal 1 m/s (its time only scales eq. 26's spreading; a loop's chord over Tp
        # would otherwise look slower than min_speed_m_s and be dropped)
        chord = prior_xy - mem.post_xy
        length = max(float(np.hypot(*chord)), 1e-3)
        t_in = np.array([mem.t_fix + length])
        v_in = np.array([1.0])
        yaw_in = np.array([math.atan2(chord[1], chord[0])])
    res = stretch_yaw(t_start=mem.t_fix, t=t_in, speed_m_s=v_in, yaw_rad=yaw_in,
                      start_xy=mem.post_xy, offset_start=mem.fix_xy - mem.post_xy,
                      offset_end=fix_xy - prior_xy, sigma_start_m=mem.sigma_m,
                      sigma_end_m=sigma, path_m=walked,
                      params=YawStretchParams(drift_fraction=cfg.fixes.drift_fraction))
    if not res.valid:
        return
    eng.yaw_pseudo.append(YawPseudoMeasurement(t, res.yaw_rad, res.var_yaw_rad2,
                                               res.correction_rad))
    gain = cfg.fixes.yaw_feedback_gain
    p_new = eng.state.P
    if cfg.fixes.yaw_feedback == "kalman":
        # scalar update of the heading by the pseudo-measurement (Joseph form)
        var_h = float(eng.state.P[IH, IH])
        gain *= var_h / (var_h + res.var_yaw_rad2)
        a = np.eye(eng.state.P.shape[0])
        a[IH, IH] = 1.0 - gain
        p_new = a @ eng.state.P @ a.T
        p_new[IH, IH] += gain * gain * res.var_yaw_rad2
    delta = gain * res.correction_rad
    eng.yaw_offset = float(wrap_angle(eng.yaw_offset + delta))
    x = eng.state.x.copy()
    x[IH] = float(wrap_angle(x[IH] + delta))
    eng.state = eng.state.evolve(x=x, P=p_new, input_heading_rad=float(wrap_angle(
        eng.state.input_heading_rad + delta)))


def apply_rss(eng: FusionEngine, t: float, payload: Any) -> None:
    """One RSS reading (tight EKF update) or one scan (WLS jump or Tarrio's Kalman fusion)."""
    cfg = eng.config
    parts = eng.parts
    if payload[0] == "reading":
        anchor, value = payload[1], payload[2]
        # (queued before the shadowing discount, e.g. in an older snapshot: independent)
        info_fraction = payload[3] if len(payload) > 3 else 1.0
        lm = landmark_at(eng, anchor, t)
        if lm is None or lm.position is None:
            eng.diagnostics.append(skipped("rss", t, _why_not(eng, anchor, t, "anchor"), anchor))
            return
        model = parts.path_loss
        if parts.channel_estimator is not None and eng.channel_state is not None:
            d_est = float(np.linalg.norm(eng.state.x[:2] - lm.xyz()[:2]))
            eng.channel_state, _ = parts.channel_estimator.update(
                eng.channel_state, rss_dbm=[value], distance_m=[d_est],
                distance_var_m2=float(np.trace(eng.state.P[:2, :2])))
            model = eng.channel_state.model()
        upd = rss_update(eng.state, lm.xyz(), value, model, min_distance_m=cfg.rss.min_distance_m,
                         gate_probability=cfg.gate_probability, t=t, source=anchor,
                         info_fraction=info_fraction)
        eng.state = upd.state
        eng.diagnostics.append(upd.diagnostics)
        eng.corrected_since_fix = eng.corrected_since_fix or upd.diagnostics.accepted
        return
    scan = payload[1]
    if len(scan.anchor) < 3:
        eng.diagnostics.append(skipped("rss", t, f"{len(scan.anchor)} anchors heard "
                                       "(WLS needs 3)", ",".join(scan.anchor)))
        return
    try:
        fix = scan_position(scan, parts.path_loss)
    except InputError as exc:   # e.g. the heard anchors are collinear
        eng.diagnostics.append(UpdateDiagnostics("rss", t, "rejected",
                                                 source=",".join(scan.anchor),
                                                 reason=exc.problem))
        return
    if cfg.rss.mode == "wls":
        # RSS alone: the estimate jumps to each WLS position (Tarrio's baseline)
        x = eng.state.x.copy()
        x[:2] = fix.xy
        p = eng.state.P.copy()
        p[:2, :] = 0.0
        p[:, :2] = 0.0
        p[:2, :2] = fix.cov
        eng.state = eng.state.evolve(t=t, x=x, P=p)
        eng.diagnostics.append(UpdateDiagnostics("rss", t, "accepted", dof=2,
                                                 source=",".join(scan.anchor),
                                                 reason="WLS position (RSS alone)"))
        return
    h = np.zeros((2, 4))
    h[0, 0] = h[1, 1] = 1.0
    r = fix.cov if cfg.rss.use_wls_covariance else np.eye(2) * cfg.rss.sigma_position_m**2
    res = kalman_update(eng.state.x, eng.state.P, h, r, fix.xy - eng.state.x[:2],
                        gate_probability=cfg.gate_probability, kind="rss", t=t,
                        source=",".join(scan.anchor), angle_index=IH)
    eng.state = eng.state.evolve(x=res.x, P=res.P)
    eng.diagnostics.append(res.diagnostics)
    eng.corrected_since_fix = eng.corrected_since_fix or res.diagnostics.accepted
