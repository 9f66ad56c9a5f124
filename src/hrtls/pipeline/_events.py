"""Compiled event loop of the tracker: runs of steps, RSS readings or scans and ranges.

The tracker's frequent events -- detected steps (Inderst eq. 4.23-4.25 with the floor level
constraint), single RSS readings in the tight mode (EKF in the dB domain, with the online
channel re-estimation first) and ranges to known nodes (eq. 4.34-4.35) -- are processed here
in one numba kernel per run of consecutive such events. Each event does exactly what the Python
parts do one at a time (:meth:`hrtls.fusion.step_prediction.StepPredictor.predict`,
:func:`hrtls.fusion.floors.floor_level_update`, :meth:`hrtls.fusion.rss.ChannelEstimator.update`,
:func:`hrtls.fusion.rss.rss_update`, :func:`hrtls.fusion.ranges.range_update`,
:func:`hrtls.fusion.random_walk.predict_random_walk`); ``tests/pipeline`` checks the equality.
RSS scans (``[rss] mode = "kalman"`` or ``"wls"``, Tarrio eq. 1-2 and the position update of
eq. 10-12) are kernel events too: :func:`_scan` repeats :func:`hrtls.fusion.rss.scan_position`
(:func:`hrtls.fusion.rss.hyperbolic_wls`) and the 2-D gated Joseph update of
:func:`hrtls.fusion.gating.kalman_update` with ``H = [I2 0]``. Rare events (fixes, tags,
bearings, velocity segments) stay in Python.

Every scalar measurement goes through :func:`_scalar_update`: the chi-square gate on the NIS
and the Joseph-form covariance, symmetrized (as :func:`hrtls.fusion.gating.kalman_update`).
The step length scale, running factor and yaw offset of the tracker and the attitude yaw
variance at each step are applied inside the loop too, and the loop counts what the tracker
needs afterwards (``S_N_*``), so that a run costs little Python around the compiled call.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from hrtls.fusion.step_prediction import FIRST_STRIDE_MAX_TURN_RAD

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# event kinds of the kernel
EV_STEP, EV_RSS, EV_RANGE, EV_SKIP, EV_SCAN = 0, 1, 2, 3, 4
# outcome codes (ST_FEW: a scan with fewer than 3 known anchors, reported as skipped)
ST_ACCEPTED, ST_GATE, ST_NEAR, ST_SPD, ST_SKIPPED, ST_NONE = 0, 1, 2, 3, 4, 5
ST_COLLINEAR, ST_WLS, ST_FEW = 6, 7, 8

# indices into the parameter vector
(P_Q_ALONG, P_Q_ACROSS, P_Q_VERT, P_STAIR_D, P_STAIR_H, P_STAIRS_MODEL, P_MODE_STATE,
 P_SIG_HEAD, P_SIG_HEAD_INC, P_FLOOR_SNAP, P_FLOOR_H, P_FLOOR_SIG, P_CHI2_1, P_HEAD_KNOWN,
 P_HAS_IMU, P_RW_SPEED, P_RW_VERT, P_RW_HEAD, P_RSS_MIN_D, P_D0, P_RANGE_SIG, P_RANGE_MIN_D,
 P_CHAN_EST, P_FORGET, P_CHAN_MIN_D, P_CHAN_MAX_VAR, P_ETA_LO, P_ETA_HI, P_CAP_A, P_CAP_ETA,
 P_USE_CHI2, P_SCAN_WLS, P_SCAN_WLS_COV, P_SCAN_SIG_P, P_CHI2_2, P_PL_A, P_PL_ETA,
 P_PL_SIG) = range(38)
N_PARAMS = 38
# scan store columns: anchor x, anchor y, mean RSS (dBm), number of readings averaged
SC_X, SC_Y, SC_RSS, SC_COUNT = 0, 1, 2, 3
# indices into the mutable scalar state vector (start from :func:`initial_scalars`)
(S_T, S_IN_HEAD, S_HAS_IN, S_LAST_ACT, S_LAST_STEP_END, S_A, S_ETA, S_RESVAR, S_COUNT,
 S_SIGMA_DB, S_STEP_SCALE, S_RUN_MULT, S_YAW_OFFSET, S_PATH, S_RUN_PATH,
 S_SCAN_BASE, S_N_STEPS, S_N_SOFT, S_N_SCAN_OK, S_N_SCANS, S_N_HEADINGS,
 S_REF_PENDING) = range(22)
N_SCALARS = 22
# S_STEP_SCALE multiplies every step length, S_RUN_MULT running steps once more; S_YAW_OFFSET
# is added to step headings; S_PATH / S_RUN_PATH accumulate the (scaled) lengths of all /
# running steps; S_SCAN_BASE is subtracted from the scan row index of scan events. Counts of
# the run: S_N_STEPS steps, S_N_SOFT accepted readings / ranges, S_N_SCAN_OK accepted scan
# updates, S_N_SCANS scans, S_N_HEADINGS steps with a finite heading (kept in ``recent``).
# S_REF_PENDING: FilterState.reference_pending (the heading reference is one step's heading).
N_RECENT = 16
"""Rows of the kernel's ring of the last (time, raw heading) of steps."""

WALKING, STANDING, RUNNING, UPSTAIRS, DOWNSTAIRS = 1, 0, 2, 3, 4


def initial_scalars() -> FloatArray:
    """Scalar state vector with the neutral step scale and yaw offset (zeros elsewhere)."""
    sc = np.zeros(N_SCALARS)
    sc[S_STEP_SCALE] = 1.0
    sc[S_RUN_MULT] = 1.0
    return sc


LN10 = math.log(10.0)


@numba.njit(cache=True, error_model="numpy")
def _wrap(a: float) -> float:  # pragma: no cover - compiled
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@numba.njit(cache=True, error_model="numpy")
def _scalar_update(x: FloatArray, p: FloatArray, h: FloatArray, r: float, nu: float,
                   threshold: float, gated: bool) -> tuple[int, float, float]:
    # pragma: no cover - compiled
    """Gated Joseph-form update with one scalar measurement; returns (status, nis, S).

    ``P+ = (I - k h^T) P (I - k h^T)^T + k r k^T`` expanded without temporaries:
    ``P+_ij = P_ij - k_i (h^T P)_j - q_i k_j + r k_i k_j`` with ``q = (I - k h^T) P h``.
    """
    ph0 = p[0, 0] * h[0] + p[0, 1] * h[1] + p[0, 2] * h[2] + p[0, 3] * h[3]
    ph1 = p[1, 0] * h[0] + p[1, 1] * h[1] + p[1, 2] * h[2] + p[1, 3] * h[3]
    ph2 = p[2, 0] * h[0] + p[2, 1] * h[1] + p[2, 2] * h[2] + p[2, 3] * h[3]
    ph3 = p[3, 0] * h[0] + p[3, 1] * h[1] + p[3, 2] * h[2] + p[3, 3] * h[3]
    s = r + (h[0] * ph0 + h[1] * ph1 + h[2] * ph2 + h[3] * ph3)
    if not s > 0.0:
        return ST_SPD, math.nan, s
    nis = nu * nu / s
    if gated and nis > threshold:
        return ST_GATE, nis, s
    k = (ph0 / s, ph1 / s, ph2 / s, ph3 / s)
    ph = (ph0, ph1, ph2, ph3)
    # h^T P (row) and h^T P h
    hp = (h[0] * p[0, 0] + h[1] * p[1, 0] + h[2] * p[2, 0] + h[3] * p[3, 0],
          h[0] * p[0, 1] + h[1] * p[1, 1] + h[2] * p[2, 1] + h[3] * p[3, 1],
          h[0] * p[0, 2] + h[1] * p[1, 2] + h[2] * p[2, 2] + h[3] * p[3, 2],
          h[0] * p[0, 3] + h[1] * p[1, 3] + h[2] * p[2, 3] + h[3] * p[3, 3])
    hph = hp[0] * h[0] + hp[1] * h[1] + hp[2] * h[2] + hp[3] * h[3]
    for i in range(4):
        x[i] += k[i] * nu
    x[3] = _wrap(x[3])
    for i in range(4):
        qi = ph[i] - k[i] * hph
        for j in range(4):
            p[i, j] = p[i, j] - k[i] * hp[j] - qi * k[j] + k[i] * r * k[j]
    for i in range(4):
        for j in range(i + 1, 4):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m
    return ST_ACCEPTED, nis, s


@numba.njit(cache=True, error_model="numpy")
def _symmetrize(p: FloatArray) -> None:  # pragma: no cover - compiled
    for i in range(4):
        for j in range(i + 1, 4):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m


@numba.njit(cache=True, error_model="numpy")
def _step(prm: FloatArray, sc: FloatArray, x: FloatArray, p: FloatArray, t: float,
          length: float, heading: float, dz: float, act: int,
          var_h_in: float) -> None:  # pragma: no cover - compiled
    """Eq. 4.23-4.25 (StepPredictor.predict) and the floor constraint, in place."""
    # the reference is set by this step's heading: before it with a known start heading
    # (preset), else by the heading logic below; either way the first stride completes it
    first = sc[S_HAS_IN] < 0.5 and np.isfinite(heading)
    if prm[P_HEAD_KNOWN] > 0.5 and first:
        sc[S_IN_HEAD] = _wrap(heading)
        sc[S_HAS_IN] = 1.0
    t_new = max(t, sc[S_T])
    var_h = prm[P_SIG_HEAD] ** 2 if not np.isfinite(var_h_in) else var_h_in
    if np.isfinite(heading):
        h_in = _wrap(heading)
        if prm[P_MODE_STATE] < 0.5:
            x[3] = h_in
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_h
        elif sc[S_HAS_IN] > 0.5:
            inc = _wrap(h_in - sc[S_IN_HEAD])
            if sc[S_REF_PENDING] > 0.5 and abs(inc) < FIRST_STRIDE_MAX_TURN_RAD:
                inc *= 0.5   # reference = mean of the first two step headings
            x[3] = _wrap(x[3] + inc)
            p[3, 3] += prm[P_SIG_HEAD_INC] ** 2
        elif p[3, 3] > var_h:
            x[3] = h_in
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_h
        sc[S_IN_HEAD] = h_in
        sc[S_HAS_IN] = 1.0
        sc[S_REF_PENDING] = 1.0 if first else 0.0
    x[3] = _wrap(x[3])
    sc[S_T] = t_new
    sc[S_LAST_ACT] = act
    sc[S_LAST_STEP_END] = t
    if act != STANDING:
        if (act in (UPSTAIRS, DOWNSTAIRS)) and prm[P_STAIRS_MODEL] > 0.5:
            horiz = prm[P_STAIR_D]
            vert = prm[P_STAIR_H] if act == UPSTAIRS else -prm[P_STAIR_H]
        else:
            horiz = length
            vert = dz
        c = math.cos(x[3])
        s = math.sin(x[3])
        size2 = horiz * horiz + vert * vert
        qa = size2 * prm[P_Q_ALONG]
        qc = size2 * prm[P_Q_ACROSS]
        qv = size2 * prm[P_Q_VERT]
        # F P F^T with F = I + f0 e0 e3^T + f1 e1 e3^T
        f0 = -horiz * s
        f1 = horiz * c
        for j in range(4):
            p[0, j] += f0 * p[3, j]
            p[1, j] += f1 * p[3, j]
        for i in range(4):
            p[i, 0] += f0 * p[i, 3]
            p[i, 1] += f1 * p[i, 3]
        # + R diag(qa, qc, qv) R^T
        p[0, 0] += c * c * qa + s * s * qc
        p[0, 1] += c * s * qa - s * c * qc
        p[1, 0] += s * c * qa - c * s * qc
        p[1, 1] += s * s * qa + c * c * qc
        p[2, 2] += qv
        _symmetrize(p)
        x[0] += horiz * c
        x[1] += horiz * s
        x[2] += vert
    if prm[P_FLOOR_SNAP] > 0.5 and (act in (WALKING, STANDING)):
        fh = prm[P_FLOOR_H]
        level = fh * np.rint(x[2] / fh)
        h = np.zeros(4)
        h[2] = 1.0
        _scalar_update(x, p, h, prm[P_FLOOR_SIG] ** 2, level - x[2], 0.0, False)


@numba.njit(cache=True, error_model="numpy")
def _advance(prm: FloatArray, sc: FloatArray, p: FloatArray, t: float) -> None:
    # pragma: no cover - compiled
    """Bring the state to t before an observation (random walk without an IMU)."""
    if t <= sc[S_T]:
        return
    if prm[P_HAS_IMU] < 0.5:
        dt = t - sc[S_T]
        p[0, 0] += prm[P_RW_SPEED] ** 2 * dt
        p[1, 1] += prm[P_RW_SPEED] ** 2 * dt
        p[2, 2] += prm[P_RW_VERT] ** 2 * dt
        p[3, 3] += prm[P_RW_HEAD] ** 2 * dt
    sc[S_T] = t


@numba.njit(cache=True, error_model="numpy")
def _channel(prm: FloatArray, sc: FloatArray, cov: FloatArray, rss: float, d: float,
             dvar: float) -> None:  # pragma: no cover - compiled
    """One reading of ChannelEstimator.update (RLS with forgetting), in place."""
    if d < prm[P_CHAN_MIN_D] or dvar > prm[P_CHAN_MAX_VAR]:
        return
    lam = prm[P_FORGET]
    phi0 = 1.0
    phi1 = -10.0 * math.log10(d / prm[P_D0])
    e = rss - (phi0 * sc[S_A] + phi1 * sc[S_ETA])
    slope = 10.0 * sc[S_ETA] / LN10
    res_var = sc[S_RESVAR]
    s2 = res_var + slope * slope * dvar / (d * d)
    pp0 = cov[0, 0] * phi0 + cov[0, 1] * phi1
    pp1 = cov[1, 0] * phi0 + cov[1, 1] * phi1
    # bounded pull of one reading (as ChannelEstimator.update)
    lim = 2.5 * math.sqrt(s2 + (phi0 * pp0 + phi1 * pp1))
    e = min(max(e, -lim), lim)
    w = res_var / s2
    den = lam / w + (phi0 * pp0 + phi1 * pp1)
    k0 = pp0 / den
    k1 = pp1 / den
    sc[S_A] += k0 * e
    sc[S_ETA] += k1 * e
    c00 = (cov[0, 0] - k0 * pp0) / lam
    c01 = (cov[0, 1] - k0 * pp1) / lam
    c10 = (cov[1, 0] - k1 * pp0) / lam
    c11 = (cov[1, 1] - k1 * pp1) / lam
    m = 0.5 * (c01 + c10)
    cov[0, 0] = c00
    cov[0, 1] = m
    cov[1, 0] = m
    cov[1, 1] = c11
    cap = prm[P_CAP_A] + prm[P_CAP_ETA]
    tr = c00 + c11
    if tr > cap:
        f = cap / tr
        for i in range(2):
            for j in range(2):
                cov[i, j] *= f
    eta_c = min(max(sc[S_ETA], prm[P_ETA_LO]), prm[P_ETA_HI])
    if eta_c != sc[S_ETA]:
        sc[S_A] += cov[0, 1] / cov[1, 1] * (eta_c - sc[S_ETA])
        sc[S_ETA] = eta_c
    sc[S_RESVAR] = max(lam * res_var + (1.0 - lam) * e * e, 1e-6)
    sc[S_COUNT] += 1.0


@numba.njit(cache=True, error_model="numpy")
def hyperbolic_wls_kernel(axy: FloatArray, d: FloatArray, sigma_ln: float,
                          out: FloatArray) -> bool:  # pragma: no cover - compiled
    """Tarrio eq. 2 as :func:`hrtls.fusion.rss.hyperbolic_wls` (nearest reference).

    ``out`` receives ``[x, y, cov_xx, cov_xy, cov_yy]``; False when the anchors are collinear.
    With ``h_i = 2 (a_i - a_r)``, ``w_i = 1 / d_i^4`` and ``S^-1 = diag(w) - k w w^T``
    (Sherman-Morrison, ``k = d_r^4 / (1 + d_r^4 sum w)``): ``H^T S^-1 H = sum w_i h_i h_i^T -
    k g g^T`` with ``g = sum w_i h_i``, and ``H^T S^-1 b = sum w_i b_i h_i - k g (sum w_i b_i)``.
    """
    n = d.shape[0]
    ref = 0
    for i in range(1, n):
        if d[i] < d[ref]:
            ref = i
    ax = axy[ref, 0]
    ay = axy[ref, 1]
    dr2 = d[ref] * d[ref]
    c_ref = dr2 * dr2
    sw = 0.0
    for i in range(n):
        if i != ref:
            d2 = d[i] * d[i]
            sw += 1.0 / (d2 * d2)
    k = c_ref / (1.0 + c_ref * sw)
    i00 = 0.0
    i01 = 0.0
    i11 = 0.0
    gx = 0.0
    gy = 0.0
    wb = 0.0
    r0 = 0.0
    r1 = 0.0
    for i in range(n):
        if i == ref:
            continue
        rx = axy[i, 0] - ax
        ry = axy[i, 1] - ay
        hx = 2.0 * rx
        hy = 2.0 * ry
        d2 = d[i] * d[i]
        w = 1.0 / (d2 * d2)
        b = (rx * rx + ry * ry) - d2 + dr2
        i00 += w * hx * hx
        i01 += w * hx * hy
        i11 += w * hy * hy
        gx += w * hx
        gy += w * hy
        wb += w * b
        r0 += w * b * hx
        r1 += w * b * hy
    i00 -= k * gx * gx
    i01 -= k * gx * gy
    i11 -= k * gy * gy
    r0 -= k * gx * wb
    r1 -= k * gy * wb
    det = i00 * i11 - i01 * i01
    tr = i00 + i11
    disc = math.sqrt(max(0.25 * tr * tr - det, 0.0))
    lam_min = 0.5 * tr - disc
    lam_max = 0.5 * tr + disc
    if not lam_min > 0.0 or lam_max / lam_min > 1e12 or not det > 0.0:
        return False
    v00 = i11 / det
    v01 = -i01 / det
    v11 = i00 / det
    out[0] = v00 * r0 + v01 * r1 + ax
    out[1] = v01 * r0 + v11 * r1 + ay
    f = 4.0 * sigma_ln * sigma_ln
    out[2] = f * v00
    out[3] = f * v01
    out[4] = f * v11
    return bool(np.all(np.isfinite(out)))


@numba.njit(cache=True, error_model="numpy")
def _position_update(x: FloatArray, p: FloatArray, r00: float, r01: float, r11: float,
                     nu0: float, nu1: float, threshold: float,
                     aux: FloatArray) -> tuple[int, float]:  # pragma: no cover - compiled
    """Gated Joseph update with a 2-D position (``H = [I2 0]``); ``aux = [nu, S00, S01, S11]``."""
    s00 = p[0, 0] + r00
    s11 = p[1, 1] + r11
    s01 = 0.5 * ((p[0, 1] + r01) + (p[1, 0] + r01))
    aux[0] = nu0
    aux[1] = nu1
    aux[2] = s00
    aux[3] = s01
    aux[4] = s11
    det = s00 * s11 - s01 * s01
    if not (s00 > 0.0 and det > 0.0):      # Cholesky of a 2x2 fails
        return ST_SPD, math.nan
    i00 = s11 / det
    i01 = -s01 / det
    i11 = s00 / det
    nis = nu0 * (i00 * nu0 + i01 * nu1) + nu1 * (i01 * nu0 + i11 * nu1)
    if nis > threshold:
        return ST_GATE, nis
    # K = P H^T S^-1 (4x2)
    kk = np.empty((4, 2))
    for i in range(4):
        kk[i, 0] = p[i, 0] * i00 + p[i, 1] * i01
        kk[i, 1] = p[i, 0] * i01 + p[i, 1] * i11
    for i in range(4):
        x[i] += kk[i, 0] * nu0 + kk[i, 1] * nu1
    x[3] = _wrap(x[3])
    a = np.eye(4)
    for i in range(4):
        a[i, 0] -= kk[i, 0]
        a[i, 1] -= kk[i, 1]
    apa = a @ p @ a.T
    for i in range(4):
        for j in range(4):
            krk = (kk[i, 0] * (r00 * kk[j, 0] + r01 * kk[j, 1])
                   + kk[i, 1] * (r01 * kk[j, 0] + r11 * kk[j, 1]))
            p[i, j] = apa[i, j] + krk
    _symmetrize(p)
    return ST_ACCEPTED, nis


@numba.njit(cache=True, error_model="numpy")
def _scan(prm: FloatArray, sc: FloatArray, x: FloatArray, p: FloatArray, t: float,
          rows: FloatArray, aux: FloatArray) -> tuple[int, float]:  # pragma: no cover
    """One RSS scan: eq. 1 distances, eq. 2 WLS position, then the jump or the update."""
    n = rows.shape[0]
    if n < 3:
        return ST_FEW, math.nan
    a_dbm = prm[P_PL_A]
    eta = prm[P_PL_ETA]
    d = np.empty(n)
    mean_count = 0.0
    for i in range(n):
        d[i] = prm[P_D0] * 10.0 ** ((a_dbm - rows[i, SC_RSS]) / (10.0 * eta))
        mean_count += rows[i, SC_COUNT]
    mean_count /= n
    # averaging n readings in dB shrinks the shadowing spread by sqrt(n)
    sigma_ln = prm[P_PL_SIG] * LN10 / (10.0 * eta) / math.sqrt(mean_count)
    fix = np.empty(5)
    if not hyperbolic_wls_kernel(rows[:, SC_X:SC_Y + 1], d, sigma_ln, fix):
        return ST_COLLINEAR, math.nan
    if prm[P_SCAN_WLS] > 0.5:
        # RSS alone: the estimate jumps to the WLS position
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
        sc[S_T] = t
        return ST_WLS, math.nan
    if prm[P_SCAN_WLS_COV] > 0.5:
        r00, r01, r11 = fix[2], fix[3], fix[4]
    else:
        r00 = prm[P_SCAN_SIG_P] ** 2
        r01 = 0.0
        r11 = r00
    return _position_update(x, p, r00, r01, r11, fix[0] - x[0], fix[1] - x[1],
                            prm[P_CHI2_2], aux)


@numba.njit(cache=True, error_model="numpy")
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


@numba.njit(cache=True, error_model="numpy")
def event_kernel(kind: IntArray, t: FloatArray, data: FloatArray, prm: FloatArray,
                 sc: FloatArray, chan_cov: FloatArray, x: FloatArray, p: FloatArray,
                 t_out: FloatArray, x_out: FloatArray, p_out: FloatArray, act_out: IntArray,
                 status: IntArray, nis_out: FloatArray, s_out: FloatArray,
                 nu_out: FloatArray, scan: FloatArray, aux_out: FloatArray,
                 var_t: FloatArray, var_v: FloatArray,
                 recent: FloatArray) -> None:  # pragma: no cover - compiled
    """Process a run of events in order; ``x``, ``p``, ``sc``, ``chan_cov`` are updated in place.

    ``data`` columns: step ``[length, heading, dz, activity, var_heading]`` (length and
    heading before the ``S_STEP_SCALE`` / ``S_RUN_MULT`` / ``S_YAW_OFFSET`` of ``sc``; the
    heading variance is interpolated in ``(var_t, var_v)`` when ``var_t`` is not empty); rss
    ``[ax, ay, az, rss_dbm]``; range ``[nx, ny, nz, range, sigma (NaN: default)]``; scan
    ``[first row in scan, number of rows]`` with ``scan`` (M, 4) the anchors heard
    (``SC_*`` columns). ``aux_out`` (n, 5): innovation (2) and ``S`` (``S00, S01, S11``) of
    the 2-D scan updates (NaN otherwise). ``recent`` (``N_RECENT``, 2): ring of the last steps'
    ``(t, heading)`` with a finite heading (before the yaw offset); row ``i`` of the ring is
    the ``i + N_RECENT j``-th such step of the run (``S_N_HEADINGS`` counts them).
    """
    h = np.zeros(4)
    for k in range(kind.shape[0]):
        ev = kind[k]
        status[k] = ST_NONE
        nis_out[k] = math.nan
        s_out[k] = math.nan
        nu_out[k] = math.nan
        for i in range(aux_out.shape[1]):
            aux_out[k, i] = math.nan
        if ev == EV_STEP:
            act = int(data[k, 3])
            length = data[k, 0] * sc[S_STEP_SCALE]
            if act == RUNNING:
                # running steps: their own calibrated factor and learned scale
                length *= sc[S_RUN_MULT]
                sc[S_RUN_PATH] += length
            sc[S_PATH] += length
            var_h = _interp(var_t, var_v, t[k]) if var_t.shape[0] else data[k, 4]
            sc[S_N_STEPS] += 1.0
            if np.isfinite(data[k, 1]):
                r = int(sc[S_N_HEADINGS]) % recent.shape[0]
                recent[r, 0] = t[k]
                recent[r, 1] = data[k, 1]
                sc[S_N_HEADINGS] += 1.0
            _step(prm, sc, x, p, t[k], length, data[k, 1] + sc[S_YAW_OFFSET], data[k, 2], act,
                  var_h)
        else:
            _advance(prm, sc, p, t[k])
            if ev == EV_SKIP:
                status[k] = ST_SKIPPED
            elif ev == EV_SCAN:
                i0 = int(data[k, 0] - sc[S_SCAN_BASE])
                st, nis = _scan(prm, sc, x, p, t[k], scan[i0:i0 + int(data[k, 1])],
                                aux_out[k])
                status[k] = st
                nis_out[k] = nis
                sc[S_N_SCANS] += 1.0
                if st == ST_ACCEPTED:
                    sc[S_N_SCAN_OK] += 1.0
            elif ev == EV_RSS:
                dx = x[0] - data[k, 0]
                dy = x[1] - data[k, 1]
                if prm[P_CHAN_EST] > 0.5:
                    _channel(prm, sc, chan_cov, data[k, 3], math.sqrt(dx * dx + dy * dy),
                             p[0, 0] + p[1, 1])
                    sc[S_SIGMA_DB] = math.sqrt(max(sc[S_RESVAR], 1e-6))
                dist = math.sqrt(dx * dx + dy * dy)
                if dist < prm[P_RSS_MIN_D]:
                    status[k] = ST_NEAR
                else:
                    eta = sc[S_ETA]
                    pred = sc[S_A] - 10.0 * eta * math.log10(dist / prm[P_D0])
                    g = -10.0 * eta / LN10 / (dist * dist)
                    h[0] = g * dx
                    h[1] = g * dy
                    h[2] = 0.0
                    h[3] = 0.0
                    nu = data[k, 3] - pred
                    st, nis, s = _scalar_update(x, p, h, sc[S_SIGMA_DB] ** 2, nu,
                                                prm[P_CHI2_1], prm[P_USE_CHI2] > 0.5)
                    if st == ST_ACCEPTED:
                        sc[S_N_SOFT] += 1.0
                    status[k] = st
                    nis_out[k] = nis
                    s_out[k] = s
                    nu_out[k] = nu
            elif ev == EV_RANGE:
                dx = x[0] - data[k, 0]
                dy = x[1] - data[k, 1]
                pred = math.sqrt(dx * dx + dy * dy)
                if pred < prm[P_RANGE_MIN_D]:
                    status[k] = ST_NEAR
                else:
                    sig = data[k, 4] if np.isfinite(data[k, 4]) else prm[P_RANGE_SIG]
                    h[0] = dx / pred
                    h[1] = dy / pred
                    h[2] = 0.0
                    h[3] = 0.0
                    nu = data[k, 3] - pred
                    st, nis, s = _scalar_update(x, p, h, sig * sig, nu, prm[P_CHI2_1],
                                                prm[P_USE_CHI2] > 0.5)
                    if st == ST_ACCEPTED:
                        sc[S_N_SOFT] += 1.0
                    status[k] = st
                    nis_out[k] = nis
                    s_out[k] = s
                    nu_out[k] = nu
        t_out[k] = sc[S_T]
        for i in range(4):
            x_out[k, i] = x[i]
            for j in range(4):
                p_out[k, i, j] = p[i, j]
        act_out[k] = int(sc[S_LAST_ACT])
