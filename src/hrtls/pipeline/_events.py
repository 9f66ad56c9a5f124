"""Compiled event loop of the tracker: runs of steps, tight RSS readings and ranges.

The tracker's frequent events -- detected steps (Inderst eq. 4.23-4.25 with the floor level
constraint), single RSS readings in the tight mode (EKF in the dB domain, with the online
channel re-estimation first) and ranges to known nodes (eq. 4.34-4.35) -- are processed here
in one numba kernel per run of consecutive such events. Each event does exactly what the Python
parts do one at a time (:meth:`hrtls.fusion.step_prediction.StepPredictor.predict`,
:func:`hrtls.fusion.floors.floor_level_update`, :meth:`hrtls.fusion.rss.ChannelEstimator.update`,
:func:`hrtls.fusion.rss.rss_update`, :func:`hrtls.fusion.ranges.range_update`,
:func:`hrtls.fusion.random_walk.predict_random_walk`); ``tests/pipeline`` checks the equality.
Rare events (fixes, tags, bearings, RSS scans, velocity segments) stay in Python.

Every scalar measurement goes through :func:`_scalar_update`: the chi-square gate on the NIS
and the Joseph-form covariance, symmetrized (as :func:`hrtls.fusion.gating.kalman_update`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# event kinds of the kernel
EV_STEP, EV_RSS, EV_RANGE, EV_SKIP = 0, 1, 2, 3
# outcome codes
ST_ACCEPTED, ST_GATE, ST_NEAR, ST_SPD, ST_SKIPPED, ST_NONE = 0, 1, 2, 3, 4, 5

# indices into the parameter vector
(P_Q_ALONG, P_Q_ACROSS, P_Q_VERT, P_STAIR_D, P_STAIR_H, P_STAIRS_MODEL, P_MODE_STATE,
 P_SIG_HEAD, P_SIG_HEAD_INC, P_FLOOR_SNAP, P_FLOOR_H, P_FLOOR_SIG, P_CHI2_1, P_HEAD_KNOWN,
 P_HAS_IMU, P_RW_SPEED, P_RW_VERT, P_RW_HEAD, P_RSS_MIN_D, P_D0, P_RANGE_SIG, P_RANGE_MIN_D,
 P_CHAN_EST, P_FORGET, P_CHAN_MIN_D, P_CHAN_MAX_VAR, P_ETA_LO, P_ETA_HI, P_CAP_A, P_CAP_ETA,
 P_USE_CHI2) = range(31)
N_PARAMS = 31
# indices into the mutable scalar state vector
(S_T, S_IN_HEAD, S_HAS_IN, S_LAST_ACT, S_LAST_STEP_END, S_A, S_ETA, S_RESVAR, S_COUNT,
 S_SIGMA_DB) = range(10)
N_SCALARS = 10

WALKING, STANDING, UPSTAIRS, DOWNSTAIRS = 1, 0, 3, 4
LN10 = math.log(10.0)


@numba.njit(cache=True)
def _wrap(a: float) -> float:  # pragma: no cover - compiled
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@numba.njit(cache=True)
def _scalar_update(x: FloatArray, p: FloatArray, h: FloatArray, r: float, nu: float,
                   threshold: float, gated: bool) -> tuple[int, float, float]:
    # pragma: no cover - compiled
    """Gated Joseph-form update with one scalar measurement; returns (status, nis, S)."""
    ph = np.zeros(4)
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += p[i, j] * h[j]
        ph[i] = acc
    s = r
    for i in range(4):
        s += h[i] * ph[i]
    if not s > 0.0:
        return ST_SPD, math.nan, s
    nis = nu * nu / s
    if gated and nis > threshold:
        return ST_GATE, nis, s
    k = ph / s
    for i in range(4):
        x[i] += k[i] * nu
    x[3] = _wrap(x[3])
    a = np.eye(4)
    for i in range(4):
        for j in range(4):
            a[i, j] -= k[i] * h[j]
    apa = a @ p @ a.T
    for i in range(4):
        for j in range(4):
            p[i, j] = apa[i, j] + k[i] * r * k[j]
    for i in range(4):
        for j in range(i + 1, 4):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m
    return ST_ACCEPTED, nis, s


@numba.njit(cache=True)
def _symmetrize(p: FloatArray) -> None:  # pragma: no cover - compiled
    for i in range(4):
        for j in range(i + 1, 4):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m


@numba.njit(cache=True)
def _step(prm: FloatArray, sc: FloatArray, x: FloatArray, p: FloatArray, t: float,
          length: float, heading: float, dz: float, act: int,
          var_h_in: float) -> None:  # pragma: no cover - compiled
    """Eq. 4.23-4.25 (StepPredictor.predict) and the floor constraint, in place."""
    if prm[P_HEAD_KNOWN] > 0.5 and sc[S_HAS_IN] < 0.5 and np.isfinite(heading):
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
            x[3] = _wrap(x[3] + _wrap(h_in - sc[S_IN_HEAD]))
            p[3, 3] += prm[P_SIG_HEAD_INC] ** 2
        elif p[3, 3] > var_h:
            x[3] = h_in
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_h
        sc[S_IN_HEAD] = h_in
        sc[S_HAS_IN] = 1.0
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def event_kernel(kind: IntArray, t: FloatArray, data: FloatArray, prm: FloatArray,
                 sc: FloatArray, chan_cov: FloatArray, x: FloatArray, p: FloatArray,
                 t_out: FloatArray, x_out: FloatArray, p_out: FloatArray, act_out: IntArray,
                 status: IntArray, nis_out: FloatArray, s_out: FloatArray,
                 nu_out: FloatArray) -> None:  # pragma: no cover - compiled
    """Process a run of events in order; ``x``, ``p``, ``sc``, ``chan_cov`` are updated in place.

    ``data`` columns: step ``[length, heading, dz, activity, var_heading]``; rss
    ``[ax, ay, az, rss_dbm]``; range ``[nx, ny, nz, range, sigma (NaN: default)]``.
    """
    h = np.zeros(4)
    for k in range(kind.shape[0]):
        ev = kind[k]
        status[k] = ST_NONE
        nis_out[k] = math.nan
        s_out[k] = math.nan
        nu_out[k] = math.nan
        if ev == EV_STEP:
            _step(prm, sc, x, p, t[k], data[k, 0], data[k, 1], data[k, 2], int(data[k, 3]),
                  data[k, 4])
        else:
            _advance(prm, sc, p, t[k])
            if ev == EV_SKIP:
                status[k] = ST_SKIPPED
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
