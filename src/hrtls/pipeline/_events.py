"""Compiled event loop of the tracker: runs of steps, RSS readings or scans and ranges.

The tracker's frequent events -- detected steps (Inderst eq. 4.23-4.25 with the floor level
constraint), single RSS readings in the tight mode (EKF in the dB domain, with the online
channel re-estimation first), ranges to known nodes (eq. 4.34-4.35) and RSS scans
(``[rss] mode = "kalman"`` or ``"wls"``, Tarrio eq. 1-2 and the position update of eq. 10-12) --
are processed here in one numba kernel per run of consecutive such events. The maths of each
event is not written here: the loop calls the compiled functions of :mod:`hrtls.fusion` that
the Python API calls too (:func:`~hrtls.fusion.step_prediction.predict_step`,
:func:`~hrtls.fusion.floors.floor_level_correction`,
:func:`~hrtls.fusion.random_walk.random_walk_covariance`,
:func:`~hrtls.fusion.channel.channel_update`, :func:`~hrtls.fusion.rss.rss_db_correction`,
:func:`~hrtls.fusion.ranges.range_correction`, :func:`~hrtls.fusion.rss_scans.scan_fix`,
:func:`~hrtls.fusion.gating.position_update`) and position fixes (:mod:`._fix_events`). Rare
events (tags, bearings, velocity segments, the fixes the loop hands back) stay in Python.

What the loop adds is the tracker's bookkeeping: the step length scale, running factor and yaw
offset applied to each step, the attitude yaw variance at each step, the known start heading,
the counts the tracker needs afterwards (``n_*``), and a ring of the last step headings, so
that a run costs little Python around the compiled call. Parameters and state are numpy
structured records with named, typed fields (:data:`LOOP_PARAMS_DTYPE`, built by
:func:`loop_params`; :data:`LOOP_STATE_DTYPE`, built by :func:`loop_state`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.data.results import Activity
from hrtls.fusion.channel import (
    CHANNEL_ESTIMATOR_DTYPE,
    CHANNEL_STATE_DTYPE,
    ChannelEstimatorParams,
    ChannelState,
    channel_update,
)
from hrtls.fusion.floors import FLIGHT_STATE, FlightParams, flight_step, floor_level_correction
from hrtls.fusion.gating import (
    ACCEPTED,
    GATED,
    NOT_SPD,
    TOO_NEAR,
    chi2_threshold,
    position_update,
    wrap_rad,
)
from hrtls.fusion.path_loss import PATH_LOSS_DTYPE, PathLossModel
from hrtls.fusion.random_walk import RANDOM_WALK_DTYPE, RandomWalkParams, random_walk_covariance
from hrtls.fusion.ranges import RangeParams, range_correction
from hrtls.fusion.rss import rss_db_correction
from hrtls.fusion.rss_scans import scan_fix
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import STEP_PREDICTION_DTYPE, StepPredictionParams, predict_step
from hrtls.kernels import njit
from hrtls.pipeline._fix_events import (
    FIX_IN_LOOP,
    FIX_IN_PYTHON,
    FIX_SERVED,
    fix_due_code,
    fix_event,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# event kinds of the kernel
EV_STEP, EV_RSS, EV_RANGE, EV_SKIP, EV_SCAN, EV_FIX = 0, 1, 2, 3, 4, 5
# outcome codes: those of hrtls.fusion.gating, then the loop's own (ST_FEW: a scan with fewer
# than 3 known anchors, reported as skipped; ST_FIX_SERVED / ST_FIX_OFF: fixes skipped by the
# slot policy, see hrtls.pipeline._fix_events.SKIP_REASONS)
ST_ACCEPTED, ST_GATE, ST_NEAR, ST_SPD = ACCEPTED, GATED, TOO_NEAR, NOT_SPD
ST_SKIPPED, ST_NONE, ST_COLLINEAR, ST_WLS, ST_FEW = 4, 5, 6, 7, 8
ST_FIX_SERVED, ST_FIX_OFF = 9, 10
# scan store columns: anchor x, anchor y, mean RSS (dBm), number of readings averaged
SC_X, SC_Y, SC_RSS, SC_COUNT = 0, 1, 2, 3
N_RECENT = 16
"""Rows of the kernel's ring of the last (time, raw heading) of steps."""

_WALKING, _STANDING, _RUNNING = (int(Activity.WALKING), int(Activity.STANDING),
                                 int(Activity.RUNNING))
_UPSTAIRS, _DOWNSTAIRS = int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS)

LOOP_PARAMS_DTYPE = np.dtype([
    ("step", STEP_PREDICTION_DTYPE),
    ("random_walk", RANDOM_WALK_DTYPE),
    ("channel", CHANNEL_ESTIMATOR_DTYPE),
    ("path_loss", PATH_LOSS_DTYPE),
    ("estimate_channel", np.bool_),
    ("floor_snap", np.bool_),
    ("floor_height_m", np.float64),
    ("floor_sigma_m", np.float64),
    ("flight_change_fraction", np.float64),
    ("flight_end_flat_steps", np.float64),
    ("flight_direction_fraction", np.float64),
    ("gate_1d", np.float64),
    ("gate_2d", np.float64),
    ("heading_known", np.bool_),
    ("yaw_relative", np.bool_),
    ("has_imu", np.bool_),
    ("rss_min_distance_m", np.float64),
    ("range_default_sigma_m", np.float64),
    ("range_min_distance_m", np.float64),
    ("scan_jump", np.bool_),
    ("scan_wls_covariance", np.bool_),
    ("scan_sigma_position_m", np.float64),
])
"""Parameters of :func:`event_kernel`.

``step``, ``random_walk``, ``channel`` (used when ``estimate_channel``), ``path_loss``: the
records of the fusion components (``path_loss``: the fixed model of the scans, and ``d0_m`` of
the tight readings). ``floor_snap``: the flight rule (``flight_*``, see
:mod:`hrtls.fusion.floors`) decides the floor and pulls z to its level (1-sigma
``floor_sigma_m``) after walking / standing steps. ``gate_1d`` / ``gate_2d``: chi-square gate
thresholds of readings / ranges and of scan positions. ``heading_known``: the first step
heading sets the heading reference before the step (a start pose with a heading).
``yaw_relative``: the input headings have no absolute reference (a yaw without magnetometer);
with ``heading_mode = "input"`` and a known start heading, the first one is aligned to it
through ``yaw_offset_rad``.
``has_imu``: False grows the covariance by the random walk before each observation.
``scan_jump``: ``[rss] mode = "wls"`` (the estimate jumps to each WLS position), else the
Kalman update with the WLS covariance (``scan_wls_covariance``) or
``scan_sigma_position_m^2 I``.
"""

LOOP_STATE_DTYPE = np.dtype([
    ("t", np.float64),
    ("input_heading_rad", np.float64),
    ("has_input_heading", np.bool_),
    ("reference_pending", np.bool_),
    ("last_activity", np.int64),
    ("last_step_end_s", np.float64),
    ("channel", CHANNEL_STATE_DTYPE),
    ("sigma_db", np.float64),
    ("step_scale", np.float64),
    ("running_multiplier", np.float64),
    ("yaw_offset_rad", np.float64),
    ("scan_base", np.int64),
    ("path_m", np.float64),
    ("running_path_m", np.float64),
    ("n_steps", np.int64),
    ("n_soft", np.int64),
    ("n_scan_accepted", np.int64),
    ("n_scans", np.int64),
    ("n_headings", np.int64),
    ("flight", np.float64, (len(FLIGHT_STATE),)),
])
"""Mutable scalars of :func:`event_kernel` (updated in place).

``t`` and the heading input memory are those of :class:`~hrtls.fusion.state.FilterState`.
``channel``: ``A``, ``eta`` of the tight RSS readings (re-estimated when the channel is
estimated), ``sigma_db`` their shadowing. ``step_scale`` multiplies every step length,
``running_multiplier`` running steps once more; ``yaw_offset_rad`` is added to step headings;
``path_m`` / ``running_path_m`` accumulate the (scaled) lengths of all / running steps;
``scan_base`` is subtracted from the scan row index of scan events. Counts of the run:
``n_steps`` steps, ``n_soft`` accepted readings / ranges, ``n_scan_accepted`` accepted scan
updates, ``n_scans`` scans, ``n_headings`` steps with a finite heading (kept in ``recent``).
``flight``: the flight rule's state (:data:`hrtls.fusion.floors.FLIGHT_STATE`).
"""

NO_FLIGHT = (math.nan, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0)
"""The flight rule's state before the first step."""


def loop_params(*, step: StepPredictionParams, path_loss: PathLossModel,
                range_params: RangeParams, channel: ChannelEstimatorParams | None,
                random_walk: RandomWalkParams, floor_snap: bool, floor_height_m: float,
                floor_sigma_m: float, flight: FlightParams | None = None,
                gate_probability: float, heading_known: bool, yaw_relative: bool,
                has_imu: bool, rss_min_distance_m: float, scan_jump: bool,
                scan_wls_covariance: bool, scan_sigma_position_m: float) -> np.ndarray:
    """The :data:`LOOP_PARAMS_DTYPE` record (one-element array) of the given components.

    ``channel`` None: the tight readings use ``path_loss`` as it is (no re-estimation).
    """
    rec = np.zeros(1, dtype=LOOP_PARAMS_DTYPE)
    rec["step"] = step.record()
    rec["random_walk"] = random_walk.record()
    rec["channel"] = (channel or ChannelEstimatorParams()).record()
    rec["path_loss"] = path_loss.record()
    rec["estimate_channel"] = channel is not None
    rec["floor_snap"] = floor_snap
    rec["floor_height_m"] = floor_height_m
    rec["floor_sigma_m"] = floor_sigma_m
    fp = flight or FlightParams()
    rec["flight_change_fraction"] = fp.change_fraction
    rec["flight_end_flat_steps"] = fp.end_flat_steps
    rec["flight_direction_fraction"] = fp.direction_fraction
    rec["gate_1d"] = chi2_threshold(1, gate_probability)
    rec["gate_2d"] = chi2_threshold(2, gate_probability)
    rec["heading_known"] = heading_known
    rec["yaw_relative"] = yaw_relative
    rec["has_imu"] = has_imu
    rec["rss_min_distance_m"] = rss_min_distance_m
    rec["range_default_sigma_m"] = range_params.default_sigma_m
    rec["range_min_distance_m"] = range_params.min_distance_m
    rec["scan_jump"] = scan_jump
    rec["scan_wls_covariance"] = scan_wls_covariance
    rec["scan_sigma_position_m"] = scan_sigma_position_m
    return rec


def loop_state(state: FilterState, *, path_loss: PathLossModel, channel: ChannelState | None,
               last_activity: int = _STANDING, last_step_end_s: float = 0.0,
               step_scale: float = 1.0, running_multiplier: float = 1.0,
               yaw_offset_rad: float = 0.0, scan_base: int = 0,
               flight: tuple[float, ...] = NO_FLIGHT) -> tuple[np.ndarray, FloatArray]:
    """The :data:`LOOP_STATE_DTYPE` record (one-element array) and the channel covariance.

    ``channel`` None: the tight readings use ``path_loss`` (and the covariance is unused).
    """
    if channel is not None:
        chan = (float(channel.theta[0]), float(channel.theta[1]), channel.residual_var_db2,
                channel.count)
        sigma_db, cov = math.sqrt(channel.residual_var_db2), channel.cov.copy()
    else:
        chan = (path_loss.a_dbm, path_loss.eta, path_loss.sigma_db**2, 0)
        sigma_db, cov = path_loss.sigma_db, np.eye(2)
    # one tuple in the order of LOOP_STATE_DTYPE (counts and path start at zero)
    rec = np.array([(state.t, state.input_heading_rad, state.has_input_heading,
                     state.reference_pending, last_activity, last_step_end_s, chan, sigma_db,
                     step_scale, running_multiplier, yaw_offset_rad, scan_base, 0.0, 0.0, 0, 0,
                     0, 0, 0, flight)], dtype=LOOP_STATE_DTYPE)
    return rec, cov


@njit(cache=True, error_model="numpy")
def _step(prm: np.record, s: np.record, x: FloatArray, p: FloatArray, t: float, length: float,
          heading: float, dz: float, act: int, var_h: float) -> None:  # pragma: no cover
    """One step (``predict_step``), the known start heading, the flight rule and the floor."""
    # the reference is set by this step's heading: before it with a known start heading
    # (preset), else by the predictor; either way the first stride completes it
    first = not s.has_input_heading and np.isfinite(heading)
    if prm.heading_known and first and prm.yaw_relative and not prm.step.heading_from_state:
        # the input replaces the state heading: align its arbitrary zero to the start heading
        s.yaw_offset_rad = wrap_rad(s.yaw_offset_rad + x[3] - heading)
        heading = x[3]
    if prm.heading_known and first:
        s.input_heading_rad = wrap_rad(heading)
        s.has_input_heading = True
    heading_in, has_in, pending = predict_step(
        prm.step, x, p, s.input_heading_rad, s.has_input_heading, s.reference_pending, length,
        heading, dz, act, var_h)
    s.input_heading_rad = heading_in
    s.has_input_heading = has_in
    s.reference_pending = pending or first
    s.t = max(t, s.t)
    s.last_activity = act
    s.last_step_end_s = t
    if not prm.floor_snap:
        return
    h = prm.floor_height_m
    fl = s.flight
    if not math.isfinite(fl[1]):
        fl[1] = np.rint((x[2] - dz) / h)
        fl[0] = fl[1]
    stairs = act in (_UPSTAIRS, _DOWNSTAIRS)
    pull = flight_step(fl, dz, stairs, h, prm.flight_change_fraction, prm.flight_end_flat_steps,
                       prm.flight_direction_fraction)
    if pull and (stairs or act in (_WALKING, _STANDING)):
        # np.bool_, not a literal: the build Python's callers use serves this call too
        floor_level_correction(x, p, h, 0.0, prm.floor_sigma_m, 0.0, np.bool_(False), fl[1])


@njit(cache=True, error_model="numpy")
def _advance(prm: np.record, s: np.record, p: FloatArray, t: float) -> None:
    # pragma: no cover - compiled
    """Bring the state to t before an observation (random walk without an IMU)."""
    if t <= s.t:
        return
    if not prm.has_imu:
        random_walk_covariance(prm.random_walk, p, t - s.t)
    s.t = t


@njit(cache=True, error_model="numpy")
def _scan(prm: np.record, s: np.record, x: FloatArray, p: FloatArray, t: float, rows: FloatArray,
          aux: FloatArray) -> tuple[int, float]:  # pragma: no cover - compiled
    """One RSS scan: eq. 1-2 position (``scan_fix``), then the WLS jump or the 2-D update."""
    if rows.shape[0] < 3:
        return ST_FEW, math.nan
    fix = np.empty(5)
    if scan_fix(prm.path_loss, rows[:, SC_X:SC_Y + 1], rows[:, SC_RSS], rows[:, SC_COUNT],
                fix) < 0:
        return ST_COLLINEAR, math.nan
    if prm.scan_jump:
        # RSS alone: the estimate jumps to the WLS position (independent of the rest)
        x[0] = fix[0]
        x[1] = fix[1]
        for i in range(2):
            for j in range(4):
                p[i, j] = 0.0
                p[j, i] = 0.0
        p[0, 0] = fix[2]
        p[0, 1] = fix[3]
        p[1, 0] = fix[3]
        p[1, 1] = fix[4]
        s.t = t
        return ST_WLS, math.nan
    if prm.scan_wls_covariance:
        r00, r01, r11 = fix[2], fix[3], fix[4]
    else:
        r00 = prm.scan_sigma_position_m ** 2
        r01 = 0.0
        r11 = r00
    return position_update(x, p, r00, r01, r11, fix[0] - x[0], fix[1] - x[1], prm.gate_2d, aux)


@njit(cache=True, error_model="numpy")
def _interp(xp: FloatArray, fp: FloatArray, x: float) -> float:  # pragma: no cover - compiled
    """``np.interp(x, xp, fp)`` for one point (ends held; xp increasing, non-empty)."""
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    slope = (fp[hi] - fp[lo]) / (xp[hi] - xp[lo])
    return slope * (x - xp[lo]) + fp[lo]


@njit(cache=True)
def _pre(x: FloatArray, p: FloatArray, out: FloatArray) -> None:  # pragma: no cover - compiled
    out[0] = x[0]
    out[1] = x[1]
    out[2] = p[0, 0]
    out[3] = p[0, 1]
    out[4] = p[1, 1]


@njit(cache=True, error_model="numpy")
def event_kernel(kind: IntArray, t: FloatArray, data: FloatArray, params: np.ndarray,
                 state: np.ndarray, chan_cov: FloatArray, x: FloatArray, p: FloatArray,
                 t_out: FloatArray, x_out: FloatArray, cov_out: FloatArray, var_h_out: FloatArray,
                 act_out: IntArray, status: IntArray, nis_out: FloatArray, s_out: FloatArray,
                 nu_out: FloatArray, scan: FloatArray, aux_out: FloatArray,
                 var_t: FloatArray, var_v: FloatArray, recent: FloatArray,
                 fix_params: np.ndarray, fix_state: np.ndarray, lead: FloatArray,
                 jump_out: FloatArray, pre_out: FloatArray) -> None:  # pragma: no cover - compiled
    """Process a run of events in order; ``x``, ``p``, ``state``, ``chan_cov`` change in place.

    ``params``: a :data:`LOOP_PARAMS_DTYPE` record (one-element array); ``state``: a
    :data:`LOOP_STATE_DTYPE` record. ``data`` columns: step ``[length, heading, dz, activity,
    var_heading]`` (length and heading before the step scale, running multiplier and yaw offset
    of ``state``; the heading variance is interpolated in ``(var_t, var_v)`` when ``var_t`` is
    not empty); rss ``[ax, ay, az, rss_dbm]``; range ``[nx, ny, nz, range, sigma (NaN:
    default)]``; scan ``[first row in scan, number of rows]`` with ``scan`` (M, 4) the anchors
    heard (``SC_*`` columns); fix ``[x, y, z, sigma, row of lead]`` with ``lead`` (F, 5) the
    step in progress at each fix (:mod:`hrtls.pipeline._fix_events`, whose ``fix_params`` /
    ``fix_state`` records the fixes use); an rss row's fifth column is its information fraction
    (:mod:`hrtls.fusion.shadowing`; NaN: 1). Output rows: time, state, horizontal covariance
    ``cov_out`` (n, 2, 2) and heading variance. ``aux_out`` (n, 5): innovation (2) and ``S``
    (``S00, S01, S11``) of the 2-D scan and fix updates (NaN otherwise); ``jump_out`` (n, 2):
    the position change of an accepted fix (NaN otherwise); ``pre_out`` (n, 5): the state before
    an observation's update, ``[x, y, P00, P01, P11]`` (NaN for steps). ``recent``
    (``N_RECENT``, 2): ring of the last steps' ``(t, heading)`` with a finite heading (before the
    yaw offset); row ``i`` of the ring is the ``i + N_RECENT j``-th such step of the run
    (``n_headings`` counts them). The loop stops before a fix that Python must apply
    (``fix_state.stop``: its row, else -1); the rows before it are done.
    """
    prm = params[0]
    s = state[0]
    fp = fix_params[0]
    fs = fix_state[0]
    fs.stop = -1
    for k in range(kind.shape[0]):
        ev = kind[k]
        status[k] = ST_NONE
        nis_out[k] = math.nan
        s_out[k] = math.nan
        nu_out[k] = math.nan
        jump_out[k, 0] = math.nan
        jump_out[k, 1] = math.nan
        for i in range(5):
            pre_out[k, i] = math.nan
        for i in range(aux_out.shape[1]):
            aux_out[k, i] = math.nan
        if ev == EV_FIX:
            # the path walked so far counts for the fix (the learner's stretch)
            fs.path_since_anchor_m += s.path_m
            fs.run_since_anchor_m += s.running_path_m
            s.path_m = 0.0
            s.running_path_m = 0.0
            code = fix_due_code(fp, fs, t[k], data[k])
            if code == FIX_IN_PYTHON:
                fs.stop = k
                return
            _advance(prm, s, p, t[k])
            _pre(x, p, pre_out[k])
            if code == FIX_IN_LOOP:
                st, nis = fix_event(fp, fs, s, x, p, t[k], data[k], lead[int(data[k, 4])],
                                    prm.gate_2d, aux_out[k], jump_out[k])
                status[k] = st
                nis_out[k] = nis
            else:
                status[k] = ST_FIX_SERVED if code == FIX_SERVED else ST_FIX_OFF
        elif ev == EV_STEP:
            act = int(data[k, 3])
            length = data[k, 0] * s.step_scale
            if act == _RUNNING:
                # running steps: their own calibrated factor and learned scale
                length *= s.running_multiplier
                s.running_path_m += length
            s.path_m += length
            var_h = _interp(var_t, var_v, t[k]) if var_t.shape[0] else data[k, 4]
            s.n_steps += 1
            if np.isfinite(data[k, 1]):
                r = s.n_headings % recent.shape[0]
                recent[r, 0] = t[k]
                recent[r, 1] = data[k, 1]
                s.n_headings += 1
                fs.last_heading_rad = data[k, 1]
            _step(prm, s, x, p, t[k], length, data[k, 1] + s.yaw_offset_rad, data[k, 2], act,
                  var_h)
        else:
            _advance(prm, s, p, t[k])
            _pre(x, p, pre_out[k])
            if ev == EV_SKIP:
                status[k] = ST_SKIPPED
            elif ev == EV_SCAN:
                i0 = int(data[k, 0]) - s.scan_base
                st, nis = _scan(prm, s, x, p, t[k], scan[i0:i0 + int(data[k, 1])], aux_out[k])
                status[k] = st
                nis_out[k] = nis
                s.n_scans += 1
                if st == ST_ACCEPTED:
                    s.n_scan_accepted += 1
                    fs.corrected_since_fix = True
            elif ev in (EV_RSS, EV_RANGE):
                if ev == EV_RSS:
                    if prm.estimate_channel:
                        dx = x[0] - data[k, 0]
                        dy = x[1] - data[k, 1]
                        channel_update(prm.channel, s.channel, chan_cov, data[k, 3],
                                       math.sqrt(dx * dx + dy * dy), p[0, 0] + p[1, 1],
                                       prm.path_loss.d0_m)
                        s.sigma_db = math.sqrt(max(s.channel.residual_var_db2, 1e-6))
                    st, nis, sv, nu = rss_db_correction(
                        x, p, data[k, 0], data[k, 1], data[k, 2], data[k, 3], s.channel.a_dbm,
                        s.channel.eta, prm.path_loss.d0_m, s.sigma_db, prm.rss_min_distance_m,
                        prm.gate_1d, np.bool_(True), np.bool_(False),
                        data[k, 4] if np.isfinite(data[k, 4]) else 1.0)
                else:
                    sig = data[k, 4] if np.isfinite(data[k, 4]) else prm.range_default_sigma_m
                    st, nis, sv, nu = range_correction(
                        x, p, data[k, 0], data[k, 1], data[k, 2], data[k, 3], sig,
                        prm.range_min_distance_m, prm.gate_1d, np.bool_(True), np.bool_(False))
                if st == ST_ACCEPTED:
                    s.n_soft += 1
                    fs.corrected_since_fix = True
                    fs.soft_since_anchor = True
                status[k] = st
                nis_out[k] = nis
                s_out[k] = sv
                nu_out[k] = nu
        t_out[k] = s.t
        fs.last_row_t = s.t
        for i in range(4):
            x_out[k, i] = x[i]
        cov_out[k, 0, 0] = p[0, 0]
        cov_out[k, 0, 1] = p[0, 1]
        cov_out[k, 1, 0] = p[1, 0]
        cov_out[k, 1, 1] = p[1, 1]
        var_h_out[k] = p[3, 3]
        act_out[k] = s.last_activity
