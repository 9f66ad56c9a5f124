"""Slow, readable reference of the ``inertial-lp`` filter (numpy matrices, scipy filters).

The low-pass filters are scipy's (``butter`` designs them, ``lfilter`` runs them one sample at
a time with its own state); rotations are matrices, the bias update is the textbook Kalman
update with a matrix inverse. The rest detector is the kernels' own Python function, so that
both sides see the same rest samples.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi

from hrtls.attitude import _inertial_lowpass_kernel as ILK
from hrtls.attitude import _kernels as K

from ._reference import _read, init_q, mag_gate, qmul, rest_and_bias, rot_h


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class _Lowpass:
    """Second-order Butterworth per channel (scipy), coefficients for a sample period."""

    def __init__(self, tau, dt, n):
        fc = math.sqrt(2.0) / (2 * math.pi * tau)
        self.b, self.a = butter(2, fc, fs=1.0 / dt)
        self.zi = np.zeros((n, 2))

    def restart(self, u):
        self.zi = np.outer(u, lfilter_zi(self.b, self.a))

    def step(self, u):
        y = np.empty(len(u))
        for c, v in enumerate(u):
            out, self.zi[c] = lfilter(self.b, self.a, [v], zi=self.zi[c])
            y[c] = out[0]
        return y

    def retune(self, tau, dt):
        self.b, self.a = butter(2, math.sqrt(2.0) / (2 * math.pi * tau), fs=1.0 / dt)


def inertial_lowpass_reference(t, acc, gyr, mag, prm, has_gyr=True, has_mag=True):
    """Returns q (N, 4), var_rpy (N, 3), disturbed (N,), final bias and bias covariance."""
    n = len(t)
    aux = K.new_aux(prm[K.PRM_BIAS0:K.PRM_BIAS0 + 3].copy())
    out_q = np.tile([1.0, 0, 0, 0], (n, 1))
    out_var = np.full((n, 3), math.pi ** 2)
    out_dist = np.zeros(n)
    qg = qa = None
    delta = 0.0
    lp_a = lp_r = lp_rb = None
    dt_gain = 0.0
    gains = {}
    P = np.zeros((3, 3))
    sig0 = prm[ILK.B_SIG0]
    gn, gd = prm[K.PRM_MAG_NORM_GATE], prm[K.PRM_MAG_DIP_GATE]
    r_tilt, r_head = prm[ILK.TILT_SIG] ** 2, prm[ILK.HEAD_SIG] ** 2
    walk2 = prm[ILK.WALK] ** 2
    det = {}
    lp_ok = False
    v_tilt = v_head = math.pi ** 2
    for i in range(n):
        dt = t[i] - aux[K.AUX_T_PREV] if np.isfinite(aux[K.AUX_T_PREV]) else 0.0
        aux[K.AUX_T_PREV] = t[i]
        a, an, acc_fin, g, gyr_fin, m, mag_fin = _read(prm, acc, gyr, mag, has_gyr, has_mag, i)
        if aux[K.AUX_INIT] < 0.5:
            if not (acc_fin and abs(an - prm[K.PRM_GRAVITY]) < prm[K.PRM_ACC_GATE]):
                continue
            qg = init_q(a, m, mag_fin and prm[K.PRM_INIT_MAG] > 0.5)
            qa = np.array([1.0, 0, 0, 0])
            delta = 0.0
            aux[K.AUX_INIT] = 1.0
            K.init_rest.py_func(aux, *g, *a, gyr_fin)
            mag0 = bool(mag_fin and mag_gate(aux, prm, *m, *(rot_h(qg).T @ [0, 0, 1.0]), 0.0))
            det = {"n": aux[K.AUX_MREF_N], "dip": aux[K.AUX_MREF_DIP], "und": 0.0, "rej": 0.0,
                   "dist": 0.0, "init": 2.0 if mag0 else 1.0,
                   "first": 0.0 if (np.isfinite(prm[K.PRM_MAG_REF_N])
                                    and np.isfinite(prm[K.PRM_MAG_REF_DIP])) else 1.0}
            v_tilt, v_head = r_tilt, (r_head if mag0 else math.pi ** 2)
            P = np.eye(3) * sig0 ** 2
            dt_gain = 0.0
            lp_ok = False
            out_q[i] = qg
            out_var[i] = [v_tilt, v_tilt, v_head]
            continue
        rest = False
        used_gyr = gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]
        rate = 0.0
        if used_gyr:
            if acc_fin:
                rest = rest_and_bias(aux, prm, *g, *a, dt)
            w = g - aux[K.AUX_BIAS:K.AUX_BIAS + 3]
            rate = float(np.linalg.norm(w))
            ang = rate * dt
            dq = np.r_[math.cos(ang / 2), (math.sin(ang / 2) / rate * w) if rate > 0 else 0 * w]
            qg = qmul(qg, dq)
            qg = qg / np.linalg.norm(qg) * (1 if qg[0] >= 0 else -1)
        restart = (not lp_ok) or dt > prm[K.PRM_MAX_DT]
        if abs(dt - dt_gain) > 0.01 * dt_gain:
            dt_gain = dt
            if lp_a is None:
                lp_a = _Lowpass(prm[ILK.TAU_ACC], dt, 3)
                lp_r = _Lowpass(prm[ILK.TAU_ACC], dt, 9)
                lp_rb = _Lowpass(prm[ILK.TAU_ACC], dt, 3)
            for f in (lp_a, lp_r, lp_rb):
                f.retune(prm[ILK.TAU_ACC], dt)
            gains = {k: 1 - math.exp(-dt / prm[idx]) for k, idx in (
                ("acc", ILK.TAU_ACC), ("mag", ILK.TAU_MAG), ("cur", ILK.M_CUR_TAU),
                ("ref", ILK.M_REF_TAU))}
        for r in range(3):
            if P[r, r] < sig0 ** 2:
                P[r, r] += math.radians(0.1) ** 2 / prm[ILK.B_FORGET] * dt
        use_a = acc_fin
        k_tilt = 0.0
        if acc_fin:
            a_i = rot_h(qg) @ a
            R6 = rot_h(qmul(qa, qg))
            b = aux[K.AUX_BIAS:K.AUX_BIAS + 3].copy()
            if restart:
                lp_ok = True
                lp_a.restart(a_i)
                lp_r.restart(R6.ravel())
                lp_rb.restart(R6 @ b)
            e = rot_h(qa) @ lp_a.step(a_i)
            wc = np.zeros(3)
            if np.linalg.norm(e) > 1e-9:
                e = e / np.linalg.norm(e)
                c = math.sqrt(max(0.5 * (1 + e[2]), 0.0))
                qc = np.array([c, 0.5 * e[1] / c, -0.5 * e[0] / c, 0.0]) if c > 1e-6 else \
                    np.array([0.0, 1.0, 0.0, 0.0])
                qa = qmul(qc, qa)
                qa = qa / np.linalg.norm(qa)
                wc = 2 * qc[1:] / dt
                k_tilt = gains["acc"]
            else:
                use_a = False
            H = lp_r.step(R6.ravel()).reshape(3, 3)
            lrb = lp_rb.step(R6 @ b)
            if prm[ILK.BIAS_EST] > 0.5 and used_gyr:
                v = math.radians(0.1) ** 2 / prm[ILK.B_FORGET] * dt
                if rest:
                    Hm, y = np.eye(3), aux[K.AUX_LP:K.AUX_LP + 3] - b
                    W = np.eye(3) * (prm[ILK.B_SIG_REST] ** 4 / v + prm[ILK.B_SIG_REST] ** 2)
                elif use_a:
                    Hm = H
                    y = np.r_[-wc[:2], 0.0] + lrb - H @ b
                    wm = prm[ILK.B_SIG_MOT] ** 4 / v + prm[ILK.B_SIG_MOT] ** 2
                    W = np.diag([wm, wm, wm / prm[ILK.B_VERT]])
                else:
                    Hm = None
                if Hm is not None:
                    S = Hm @ P @ Hm.T + W
                    Kg = P @ Hm.T @ np.linalg.inv(S)
                    clip = prm[ILK.B_CLIP]
                    aux[K.AUX_BIAS:K.AUX_BIAS + 3] = np.clip(b + Kg @ y, -clip, clip)
                    P = P - Kg @ Hm @ P
        k_head = 0.0
        if mag_fin:
            mE = rot_h(qmul(qa, qg)) @ m
            mn = float(np.linalg.norm(mE))
            if mn > 1e-6:
                dip = math.asin(np.clip(-mE[2] / mn, -1, 1))
                if aux[K.AUX_MREF_SET] < 0.5:
                    aux[K.AUX_MREF_N] = prm[K.PRM_MAG_REF_N] if np.isfinite(
                        prm[K.PRM_MAG_REF_N]) else mn
                    aux[K.AUX_MREF_DIP] = prm[K.PRM_MAG_REF_DIP] if np.isfinite(
                        prm[K.PRM_MAG_REF_DIP]) else dip
                    aux[K.AUX_MCAND_N], aux[K.AUX_MCAND_DIP] = mn, dip
                    aux[K.AUX_MCAND_T] = 0.0
                    aux[K.AUX_MREF_SET] = 1.0
                    det["n"], det["dip"] = mn, dip
                det["n"] += gains["cur"] * (mn - det["n"])
                det["dip"] += gains["cur"] * (dip - det["dip"])
                cn, cd = det["n"], det["dip"]
                if abs(cn - aux[K.AUX_MREF_N]) < gn and abs(cd - aux[K.AUX_MREF_DIP]) < gd:
                    det["und"] += dt
                    if det["und"] >= prm[ILK.M_UNDIST]:
                        det["dist"] = 0.0
                        aux[K.AUX_MREF_N] += gains["ref"] * (cn - aux[K.AUX_MREF_N])
                        aux[K.AUX_MREF_DIP] += gains["ref"] * (cd - aux[K.AUX_MREF_DIP])
                else:
                    det["und"], det["dist"] = 0.0, 1.0
                if abs(cn - aux[K.AUX_MCAND_N]) < gn and abs(cd - aux[K.AUX_MCAND_DIP]) < gd:
                    if rate >= prm[ILK.M_NEW_RATE]:
                        aux[K.AUX_MCAND_T] += dt
                        aux[K.AUX_MCAND_N] += gains["ref"] * (cn - aux[K.AUX_MCAND_N])
                        aux[K.AUX_MCAND_DIP] += gains["ref"] * (cd - aux[K.AUX_MCAND_DIP])
                        if det["dist"] > 0.5 and (
                                aux[K.AUX_MCAND_T] >= prm[K.PRM_MAG_NEW_S]
                                or (det["first"] > 0.5
                                    and aux[K.AUX_MCAND_T] >= prm[ILK.M_NEW_FIRST])):
                            aux[K.AUX_MREF_N] = aux[K.AUX_MCAND_N]
                            aux[K.AUX_MREF_DIP] = aux[K.AUX_MCAND_DIP]
                            det["und"], det["dist"], det["first"] = prm[ILK.M_UNDIST], 0.0, 0.0
                else:
                    aux[K.AUX_MCAND_N], aux[K.AUX_MCAND_DIP] = cn, cd
                    aux[K.AUX_MCAND_T] = 0.0
                k_head = gains["mag"]
                if det["init"] > 0.5:
                    k_head = max(k_head, 1.0 / det["init"])
                if det["dist"] > 0.5:
                    if det["rej"] <= prm[ILK.M_MAX_REJ]:
                        det["rej"] += dt
                        k_head = 0.0
                    else:
                        k_head /= prm[ILK.M_REJ_FACTOR]
                else:
                    det["rej"] = max(det["rej"] - prm[ILK.M_REJ_FACTOR] * dt, 0.0)
                if k_head > 0 and mE[0] ** 2 + mE[1] ** 2 > 1e-12:
                    delta = _wrap(delta + k_head * _wrap(
                        math.pi / 2 - math.atan2(mE[1], mE[0]) - delta))
                    if det["init"] > 0.5:
                        det["init"] += 1
                        if 1 / det["init"] < gains["mag"]:
                            det["init"] = 0.0
                else:
                    k_head = 0.0
        v_tilt = min((1 - k_tilt) * v_tilt + k_tilt * r_tilt + walk2 * dt, math.pi ** 2)
        v_head = min((1 - k_head) * v_head + k_head * r_head + walk2 * dt, math.pi ** 2)
        q = qmul([math.cos(delta / 2), 0, 0, math.sin(delta / 2)], qmul(qa, qg))
        q = q / np.linalg.norm(q)
        out_q[i] = q if q[0] >= 0 else -q
        out_var[i] = [v_tilt, v_tilt, v_head]
        out_dist[i] = det["dist"]
    return out_q, out_var, out_dist, aux[K.AUX_BIAS:K.AUX_BIAS + 3].copy(), P
