"""Position fixes inside the compiled event loop (Colombo eq. 18-23, as :mod:`.observations`).

A fix row of the loop does what :func:`hrtls.pipeline.observations.apply_fix` does: the slot
policy of eq. 19 (:meth:`hrtls.fusion.fixes.FixCorrector.due`, the slots anchored at the first
fix), the comparison with the state plus the step in progress
(:func:`hrtls.fusion.fixes.partial_step_xy`), the drift variance, the gated Joseph update
(:func:`hrtls.fusion.gating.joseph_kernel`), the step-scale learning of
:class:`hrtls.pipeline.step_scale.StepScaleLearner` and the new stretching memory.
:func:`fix_due_code` sends back to Python the fixes the loop does not handle: those whose
acceptance would run the yaw stretching (eq. 24-28) and the recovery without gate after
rejections. The loop is used only when the fixes are gated and not conditioned on motion
(:func:`fixes_in_loop`); otherwise every fix goes through Python.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.fusion.fixes import DRIFT_MIN_PATH_M, FixParams, partial_step_xy
from hrtls.fusion.gating import ACCEPTED, GATED, NOT_SPD, joseph_kernel, wrap_rad
from hrtls.kernels import njit
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.step_scale import StepScaleParams

FloatArray = NDArray[np.float64]

FIX_IN_LOOP, FIX_SERVED, FIX_OFF_PERIOD, FIX_IN_PYTHON = 0, 1, 2, 3
"""Codes of :func:`fix_due_code`: apply in the loop, skip (period slot already served), skip
(not at a multiple of the period), return to Python."""
SKIP_REASONS = {FIX_SERVED: "period slot already served",
                FIX_OFF_PERIOD: "not at a multiple of the period"}
"""Diagnostics reason of the skip codes (those of :meth:`FixCorrector.due`)."""
LEAD_T_START, LEAD_T_END, LEAD_LENGTH, LEAD_HEADING, LEAD_ACTIVITY = 0, 1, 2, 3, 4
"""Columns of the step in progress at a fix (NaN row: none), before scale and yaw offset."""
_RUNNING = 5

FIX_PARAMS_DTYPE = np.dtype([
    ("period_s", np.float64),
    ("slot_tolerance_s", np.float64),
    ("max_rejections", np.int64),
    ("drift_fraction", np.float64),
    ("partial_step", np.bool_),
    ("yaw_stretch", np.bool_),
    ("learn_scale", np.bool_),
    ("running_factor", np.float64),
    ("min_baseline_m", np.float64),
    ("scale_gain", np.float64),
    ("min_scale", np.float64),
    ("max_scale", np.float64),
])
"""Parameters of the fix rows: ``[fixes]`` (period, tolerance, consecutive rejections, drift
fraction, partial step, yaw stretching), the step-scale learning and the running factor."""

FIX_STATE_DTYPE = np.dtype([
    ("phase_set", np.bool_),
    ("phase_s", np.float64),
    ("has_last_slot", np.bool_),
    ("last_slot", np.int64),
    ("rejections", np.int64),
    ("corrected_since_fix", np.bool_),
    ("has_memory", np.bool_),
    ("memory_new", np.bool_),
    ("memory", np.float64, (6,)),
    ("run_scale", np.float64),
    ("has_anchor", np.bool_),
    ("anchor_xy", np.float64, (2,)),
    ("path_since_anchor_m", np.float64),
    ("run_since_anchor_m", np.float64),
    ("soft_since_anchor", np.bool_),
    ("last_heading_rad", np.float64),
    ("last_row_t", np.float64),
    ("stop", np.int64),
])
"""State of the fix rows (updated in place): the slot phase, :class:`FixSchedule`, the
engine's ``corrected_since_fix``, the stretching memory (``memory``: ``t_fix``, post x, y,
fix x, y, sigma; ``memory_new``: set by the loop), the step-scale learner (with the walking
scale ``step_scale`` of the loop state), the last raw step heading (NaN: none), the time of
the last output row and ``stop``: the row the loop returned to Python at (-1: none)."""


def fixes_in_loop(config: TrackerConfig, *, slow_only: bool) -> bool:
    """Whether the fixes can be rows of the compiled loop (gated, not conditioned on motion)."""
    fx = config.fixes
    return fx.enabled and fx.gate and not fx.require_motion and not slow_only


def fix_params(config: TrackerConfig, fix: FixParams, scale: StepScaleParams, *,
               running_factor: float) -> np.ndarray:
    """The :data:`FIX_PARAMS_DTYPE` record (one-element array)."""
    fx = config.fixes
    assert fix.period_s is not None
    rec = np.zeros(1, dtype=FIX_PARAMS_DTYPE)
    rec["period_s"] = fx.period_s
    rec["slot_tolerance_s"] = fix.slot_tolerance_s
    rec["max_rejections"] = fx.max_consecutive_rejections
    rec["drift_fraction"] = fx.drift_fraction
    rec["partial_step"] = fx.partial_step
    rec["yaw_stretch"] = fx.yaw_stretch
    rec["learn_scale"] = config.prediction.learn_step_scale
    rec["running_factor"] = running_factor
    rec["min_baseline_m"] = scale.min_baseline_m
    rec["scale_gain"] = scale.gain
    rec["min_scale"] = scale.min_scale
    rec["max_scale"] = scale.max_scale
    return rec


@njit(cache=True, error_model="numpy")
def _slot(fp: np.record, fs: np.record, t: float) -> int:  # pragma: no cover - compiled
    return math.floor((t - fs.phase_s) / fp.period_s)


@njit(cache=True, error_model="numpy")
def fix_due_code(fp: np.record, fs: np.record, t: float, row: FloatArray) -> int:
    # pragma: no cover - compiled
    """What the loop does with the fix ``row`` at ``t`` (``FIX_*``), before touching the state.

    Non-finite values go to Python (whose checks name them).
    """
    for i in range(4):
        if not math.isfinite(row[i]):
            return FIX_IN_PYTHON
    if not row[3] > 0.0:
        return FIX_IN_PYTHON
    if not fs.phase_set:
        # eq. 19 slots i Tp: anchored at the first fix (the query clock is unknown)
        fs.phase_set = True
        fs.phase_s = t - fp.slot_tolerance_s / 2
    slot = _slot(fp, fs, t)
    if fs.has_last_slot and slot <= fs.last_slot:
        return FIX_SERVED
    if t - fs.phase_s - slot * fp.period_s > fp.slot_tolerance_s:
        return FIX_OFF_PERIOD
    if fs.rejections >= fp.max_rejections:
        return FIX_IN_PYTHON     # applied without the gate, with its own diagnostics
    if fp.yaw_stretch and fs.has_memory and not fs.corrected_since_fix:
        return FIX_IN_PYTHON     # an accepted fix would run the yaw stretching
    return FIX_IN_LOOP


@njit(cache=True, error_model="numpy")
def _lead(fp: np.record, fs: np.record, x: FloatArray, state_t: float, step_scale: float,
          t: float, lead: FloatArray) -> tuple[float, float]:  # pragma: no cover - compiled
    """The part of the step in progress at ``t`` (``observations._step_lead``), m."""
    if not fp.partial_step or not math.isfinite(lead[LEAD_HEADING]):
        return 0.0, 0.0
    if not lead[LEAD_T_END] > state_t:
        return 0.0, 0.0
    h_k = lead[LEAD_HEADING]
    h_last = fs.last_heading_rad if math.isfinite(fs.last_heading_rad) else h_k
    scale = (fp.running_factor * fs.run_scale if int(lead[LEAD_ACTIVITY]) == _RUNNING
             else step_scale)
    return partial_step_xy(t, lead[LEAD_T_START], lead[LEAD_T_END], lead[LEAD_LENGTH] * scale,
                           x[3] + wrap_rad(h_k - h_last))


@njit(cache=True, error_model="numpy")
def learn_scale(fp: np.record, fs: np.record, step_scale: float, prior_x: float, prior_y: float,
                post_x: float, post_y: float) -> float:  # pragma: no cover - compiled
    """:meth:`StepScaleLearner.correct`; returns the walking scale (the running one in ``fs``)."""
    if fp.learn_scale and fs.has_anchor and not fs.soft_since_anchor:
        d0 = prior_x - fs.anchor_xy[0]
        d1 = prior_y - fs.anchor_xy[1]
        base = math.hypot(d0, d1)
        if base >= fp.min_baseline_m and base >= 0.95 * fs.path_since_anchor_m:
            ratio = ((post_x - fs.anchor_xy[0]) * d0 + (post_y - fs.anchor_xy[1]) * d1) / (
                base * base)
            if 0.7 < ratio < 1.4:
                share_run = fs.run_since_anchor_m / max(fs.path_since_anchor_m, 1e-9)
                if share_run < 0.8:
                    step_scale = min(max(step_scale * ratio ** fp.scale_gain, fp.min_scale),
                                     fp.max_scale)
                if share_run > 0.2:
                    fs.run_scale = min(max(fs.run_scale * ratio ** fp.scale_gain,
                                           fp.min_scale), fp.max_scale)
    fs.has_anchor = True
    fs.anchor_xy[0] = post_x
    fs.anchor_xy[1] = post_y
    fs.path_since_anchor_m = 0.0
    fs.run_since_anchor_m = 0.0
    fs.soft_since_anchor = False
    return step_scale


def fix_state(*, phase_s: float | None, last_slot: int | None, rejections: int,
              corrected_since_fix: bool, has_memory: bool, run_scale: float,
              anchor_xy: FloatArray | None, path_since_anchor_m: float,
              run_since_anchor_m: float, soft_since_anchor: bool, last_heading_rad: float,
              last_row_t: float) -> np.ndarray:
    """The :data:`FIX_STATE_DTYPE` record (one-element array); ``None``: not set yet."""
    # one tuple in the order of FIX_STATE_DTYPE (a new stretching memory starts empty)
    return np.array([(phase_s is not None, 0.0 if phase_s is None else phase_s,
                      last_slot is not None, 0 if last_slot is None else last_slot, rejections,
                      corrected_since_fix, has_memory, False, (0.0,) * 6, run_scale,
                      anchor_xy is not None,
                      (0.0, 0.0) if anchor_xy is None else tuple(anchor_xy.tolist()),
                      path_since_anchor_m, run_since_anchor_m, soft_since_anchor,
                      last_heading_rad, last_row_t, -1)], dtype=FIX_STATE_DTYPE)


@njit(cache=True, error_model="numpy")
def fix_event(fp: np.record, fs: np.record, s: np.record, x: FloatArray, p: FloatArray,
              t: float, row: FloatArray, lead: FloatArray, threshold: float, aux: FloatArray,
              jump: FloatArray) -> tuple[int, float]:  # pragma: no cover - compiled
    """One due fix ``row = [x, y, z, sigma]`` (code ``FIX_IN_LOOP``), in place.

    ``s``: the loop state (:data:`hrtls.pipeline._events.LOOP_STATE_DTYPE`), its path already
    added to ``fs``. Returns the gating outcome (0 accepted, 1 gated, 3 not positive definite)
    and the NIS; ``aux`` gets ``[nu0, nu1, S00, S01, S11]``, ``jump`` the position change of
    an accepted fix.
    """
    lx, ly = _lead(fp, fs, x, s.t, s.step_scale, t, lead)
    drift = fp.drift_fraction * max(fs.path_since_anchor_m, DRIFT_MIN_PATH_M)
    drift_var = drift * drift
    p_prior = p.copy()
    if drift_var > 0.0:
        p_prior[0, 0] += drift_var
        p_prior[1, 1] += drift_var
    h = np.zeros((2, 4))
    h[0, 0] = 1.0
    h[1, 1] = 1.0
    r = np.eye(2) * row[3] ** 2
    nu = np.empty(2)
    nu[0] = (row[0] - lx) - x[0]
    nu[1] = (row[1] - ly) - x[1]
    x_new = np.empty(4)
    p_new = np.empty((4, 4))
    s_in = np.empty((2, 2))
    # np.int64, not a literal: the build Python's callers use serves this call too
    code, nis = joseph_kernel(x, p_prior, h, r, nu, threshold, np.int64(3), x_new, p_new, s_in)
    aux[0], aux[1] = nu[0], nu[1]
    aux[2], aux[3], aux[4] = s_in[0, 0], s_in[0, 1], s_in[1, 1]
    if code != 0:
        fs.rejections += 1
        return (GATED, nis) if code == 1 else (NOT_SPD, math.nan)
    fs.has_last_slot = True
    fs.last_slot = _slot(fp, fs, t)
    fs.rejections = 0
    prior_x, prior_y = x[0], x[1]
    for i in range(4):
        x[i] = x_new[i]
        for j in range(4):
            p[i, j] = p_new[i, j]
    jump[0] = x[0] - prior_x
    jump[1] = x[1] - prior_y
    if (lx != 0.0 or ly != 0.0) and fs.last_row_t == s.last_step_end_s:
        # the corrected state is the position at the last step end: its output row
        # replaces that step's row
        s.t = s.last_step_end_s
    step_scale = learn_scale(fp, fs, s.step_scale, prior_x, prior_y, x[0], x[1])
    s.step_scale = step_scale
    s.running_multiplier = fp.running_factor * fs.run_scale / step_scale
    mem = fs.memory
    mem[0] = t
    mem[1] = x[0] + lx
    mem[2] = x[1] + ly
    mem[3] = row[0]
    mem[4] = row[1]
    mem[5] = row[3]
    fs.has_memory = True
    fs.memory_new = True
    fs.corrected_since_fix = False
    return ACCEPTED, nis
