"""Slow, readable reference versions of the attitude filters (pure Python + numpy/scipy).

They restate the papers' equations in matrix form (stacked measurement, matrix exponential,
Jacobians by complex-step differentiation, FQA by trigonometry) and are compared with the
compiled kernels. The bookkeeping helpers (gates, rest detection) are the kernels' own Python
functions (``.py_func``), so that both sides make the same gate decisions.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from hrtls.attitude import _kernels as K

mag_gate = K.mag_gate.py_func
rest_and_bias = K.rest_and_bias.py_func
init_rest = K.init_rest.py_func


def rot_h(q):
    """Homogeneous rotation matrix (works for complex q)."""
    w, x, y, z = q
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ])


def complex_step_jacobian(f, x, h=1e-30):
    x = np.asarray(x, dtype=np.complex128)
    cols = []
    for k in range(len(x)):
        xp = x.copy()
        xp[k] += 1j * h
        cols.append(np.imag(f(xp)) / h)
    return np.column_stack(cols)


def omega(w):
    wx, wy, wz = w
    return 0.5 * np.array([[0, -wx, -wy, -wz], [wx, 0, wz, -wy], [wy, -wz, 0, wx],
                           [wz, wy, -wx, 0]])


def xi(q):
    w, x, y, z = q
    return np.array([[-x, -y, -z], [w, -z, y], [z, w, -x], [-y, x, w]])


def qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


def init_q(a, m, use_mag):
    a = np.asarray(a) / np.linalg.norm(a)
    axis = np.cross(a, [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis)
    ang = math.atan2(s, a[2])
    q = np.array([1.0, 0, 0, 0]) if s < 1e-15 else np.concatenate(
        [[math.cos(ang / 2)], math.sin(ang / 2) * axis / s])
    if use_mag:
        mn = rot_h(q) @ np.asarray(m)
        if mn[0] ** 2 + mn[1] ** 2 >= 1e-18:
            turn = math.pi / 2 - math.atan2(mn[1], mn[0])
            q = qmul([math.cos(turn / 2), 0, 0, math.sin(turn / 2)], q)
    return q if q[0] >= 0 else -q


def _read(prm, acc, gyr, mag, has_gyr, has_mag, i):
    a = acc[i]
    an = float(np.linalg.norm(a))
    acc_fin = bool(np.isfinite(an) and 1e-6 < an < prm[K.PRM_ACC_RANGE])
    g = gyr[i]
    gyr_fin = bool(has_gyr and np.all(np.isfinite(g)) and np.all(np.abs(g) < prm[K.PRM_GYR_RANGE]))
    m = mag[i]
    mag_fin = bool(has_mag and np.all(np.isfinite(m)))
    return a, an, acc_fin, g, gyr_fin, m, mag_fin


def dynamic_var(aux, a, R, dt, tau):
    """Running per-axis variance of the ENU specific force ``R a`` (EW mean and variance)."""
    an = R @ a
    sl = slice(K.AUX_DYN_MEAN, K.AUX_DYN_MEAN + 3)
    if not np.all(np.isfinite(aux[sl])):
        aux[sl] = an
        aux[K.AUX_DYN_VAR] = 0.0
        return 0.0
    d = an - aux[sl]
    k = dt / (tau + dt) if dt > 0 else 0.0
    aux[sl] += k * d
    aux[K.AUX_DYN_VAR] = (1 - k) * (aux[K.AUX_DYN_VAR] + k * float(d @ d) / 3)
    return aux[K.AUX_DYN_VAR]


# ---------------------------------------------------------------------------------------------
# quaternion EKF (Inderst 4.2.1), 7 states [q, b]
# ---------------------------------------------------------------------------------------------
def quat_ekf_reference(t, acc, gyr, mag, prm, has_gyr=True, has_mag=True):
    from hrtls.attitude.quat_ekf import (
        _ACC_NOISE,
        _BIAS_P0,
        _BIAS_WALK,
        _DYN_CORR,
        _DYN_TAU,
        _GYR_NOISE,
        _MAG_MODE,
        _MAG_NOISE,
        _P0,
        _RATE_REF,
        _REST_VAR,
    )

    aux = K.new_aux(prm[K.PRM_BIAS0:K.PRM_BIAS0 + 3].copy())
    q = np.array([1.0, 0, 0, 0])
    P = np.zeros((7, 7))
    out = np.zeros((len(t), 4))
    flags_out = np.zeros(len(t), dtype=int)
    g_ = prm[K.PRM_GRAVITY]
    for i in range(len(t)):
        dt = t[i] - aux[K.AUX_T_PREV] if np.isfinite(aux[K.AUX_T_PREV]) else 0.0
        aux[K.AUX_T_PREV] = t[i]
        a, an, acc_fin, g, gyr_fin, m, mag_fin = _read(prm, acc, gyr, mag, has_gyr, has_mag, i)
        acc_dev = abs(an - g_) if acc_fin else math.inf
        flags = 0
        rate2 = 0.0
        if aux[K.AUX_INIT] < 0.5:
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                q = init_q(a, m, mag_fin and prm[K.PRM_INIT_MAG] > 0.5)
                P = np.diag([prm[_P0]] * 4 + [prm[_BIAS_P0]] * 3)
                J = np.eye(7)
                J[:4, :4] -= np.outer(q, q)
                P = J @ P @ J.T
                aux[K.AUX_INIT] = 1.0
                init_rest(aux, *g, *a, gyr_fin)
                flags = K.FLAG_VALID | K.FLAG_ACC
                if mag_fin:
                    u = rot_h(q).T @ [0, 0, 1.0]
                    if mag_gate(aux, prm, *m, *u, 0.0):
                        flags |= K.FLAG_MAG
            else:
                out[i] = [1, 0, 0, 0]
                continue
        else:
            flags = K.FLAG_VALID
            if gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]:
                if acc_fin and rest_and_bias(aux, prm, *g, *a, dt):
                    flags |= K.FLAG_REST
                b = aux[K.AUX_BIAS:K.AUX_BIAS + 3].copy()
                rate2 = float((g - b) @ (g - b))
                Phi = expm(omega(g - b) * dt)  # eq. 4.12
                F = np.eye(7)
                F[:4, :4] = Phi
                F[:4, 4:] = -0.5 * dt * xi(q)
                q = Phi @ q
                q = q / np.linalg.norm(q)
                Q = np.zeros((7, 7))
                Q[:4, :4] = (0.5 * dt * prm[_GYR_NOISE]) ** 2 * xi(q) @ xi(q).T  # eq. 4.14
                Q[4:, 4:] = prm[_BIAS_WALK] * dt * np.eye(3)
                P = F @ P @ F.T + Q
                if q[0] < 0:
                    q = -q
                    P[:4, 4:] *= -1
                    P[4:, :4] *= -1
                if prm[_REST_VAR] > 0.5 and flags & K.FLAG_REST:
                    # bias variances down to that of the rest average: P <- D P D
                    kb = dt / min(prm[K.PRM_BIAS_TAU_S] + dt,
                                  aux[K.AUX_REST_T] - prm[K.PRM_REST_S] + dt)
                    v_rest = prm[_GYR_NOISE] ** 2 * kb / (2 - kb)
                    d = np.ones(7)
                    d[4:] = np.sqrt(np.minimum(1.0, v_rest / np.diag(P)[4:]))
                    P = d[:, None] * P * d[None, :]
                flags |= K.FLAG_GYR
            u = rot_h(q).T @ [0, 0, 1.0]
            rows_h, rows_z, rows_v, rows_H = [], [], [], []
            v_dyn = 0.0
            if acc_fin and prm[_DYN_CORR] > 0:  # white-noise equivalent of the body's acceleration
                var_dyn = dynamic_var(aux, a, rot_h(q), dt, prm[_DYN_TAU])
                if dt > 0:
                    v_dyn = 2 * prm[_DYN_CORR] * var_dyn / (dt * g_**2)
            use_a = acc_fin and acc_dev < prm[K.PRM_ACC_GATE]
            if use_a:  # eq. 4.16
                v = np.array([0, 0, 1.0])
                rows_z.append(a / an)
                rows_h.append(rot_h(q).T @ v)
                rows_H.append(complex_step_jacobian(lambda qq, v=v: rot_h(qq).T @ v, q))
                rows_v += [prm[_ACC_NOISE] ** 2 * (1 + rate2 / prm[_RATE_REF] ** 2) + v_dyn] * 3
                flags |= K.FLAG_ACC
            if mag_fin and mag_gate(aux, prm, *m, *u, dt):  # eq. 4.18
                if prm[_MAG_MODE] > 0.5:
                    z = m - (m @ u) * u
                    v = np.array([0, 1.0, 0])
                else:
                    z = m.copy()
                    dip = aux[K.AUX_MREF_DIP]
                    v = np.array([0, math.cos(dip), -math.sin(dip)])
                rows_z.append(z / np.linalg.norm(z))
                rows_h.append(rot_h(q).T @ v)
                rows_H.append(complex_step_jacobian(lambda qq, v=v: rot_h(qq).T @ v, q))
                rows_v += [prm[_MAG_NOISE] ** 2] * 3
                flags |= K.FLAG_MAG
            if rows_z:  # eq. 4.19, stacked
                z = np.concatenate(rows_z)
                h = np.concatenate(rows_h)
                H = np.hstack([np.vstack(rows_H), np.zeros((len(z), 3))])
                S = H @ P @ H.T + np.diag(rows_v)
                Kg = P @ H.T @ np.linalg.inv(S)
                dx = Kg @ (z - h)
                P = (np.eye(7) - Kg @ H) @ P
                P = 0.5 * (P + P.T)
                q = q + dx[:4]
                aux[K.AUX_BIAS:K.AUX_BIAS + 3] += dx[4:]
                q = q / np.linalg.norm(q)
                if q[0] < 0:
                    q = -q
                    P[:4, 4:] *= -1
                    P[4:, :4] *= -1
                J = np.eye(7)
                J[:4, :4] -= np.outer(q, q)
                P = J @ P @ J.T
        out[i] = q
        flags_out[i] = flags
    return out, flags_out, P, aux


# ---------------------------------------------------------------------------------------------
# Euler EKF (Colombo III-B)
# ---------------------------------------------------------------------------------------------
def r_zyx(th):
    r, p, y = th
    cr, sr, cp, sp, cy, sy = (np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def e_matrix(th):
    r, p, _ = th
    return np.array([[1, np.sin(r) * np.tan(p), np.cos(r) * np.tan(p)],
                     [0, np.cos(r), -np.sin(r)],
                     [0, np.sin(r) / np.cos(p), np.cos(r) / np.cos(p)]])


def wrap(a):
    return math.pi - ((math.pi - a) % (2 * math.pi))


def quat_to_euler(q):
    w, x, y, z = q
    return np.array([math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                     math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x)))),
                     math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))])


def euler_ekf_reference(t, acc, gyr, mag, prm, yaw=None, has_gyr=True, has_mag=True):
    from hrtls.attitude.euler_ekf import (
        _DYN_CORR,
        _DYN_TAU,
        _EXACT,
        _P0,
        _QETA,
        _QG,
        _QN,
        _QW,
        _RATE_REF,
    )

    aux = K.new_aux(prm[K.PRM_BIAS0:K.PRM_BIAS0 + 3].copy())
    th = np.zeros(3)
    P = np.zeros((3, 3))
    out = np.zeros((len(t), 3))
    var = np.zeros((len(t), 3))
    g_ = prm[K.PRM_GRAVITY]
    for i in range(len(t)):
        dt = t[i] - aux[K.AUX_T_PREV] if np.isfinite(aux[K.AUX_T_PREV]) else 0.0
        aux[K.AUX_T_PREV] = t[i]
        a, an, acc_fin, g, gyr_fin, m, mag_fin = _read(prm, acc, gyr, mag, has_gyr, has_mag, i)
        acc_dev = abs(an - g_) if acc_fin else math.inf
        if aux[K.AUX_INIT] < 0.5:
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                q = init_q(a, m, mag_fin and prm[K.PRM_INIT_MAG] > 0.5)
                th = quat_to_euler(q)
                P = prm[_P0] * np.eye(3)
                aux[K.AUX_INIT] = 1.0
                init_rest(aux, *g, *a, gyr_fin)
                if mag_fin:
                    mag_gate(aux, prm, *m, *(rot_h(q).T @ [0, 0, 1.0]), 0.0)
            else:
                out[i] = np.nan
                continue
        else:
            rate2 = 0.0
            if gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]:
                if acc_fin:
                    rest_and_bias(aux, prm, *g, *a, dt)
                w = g - aux[K.AUX_BIAS:K.AUX_BIAS + 3]
                rate2 = float(w @ w)
                F = np.eye(3) + dt * complex_step_jacobian(lambda x, w=w: e_matrix(x) @ w, th)
                G = dt * e_matrix(th)
                if prm[_EXACT] > 0.5:  # R+ = R(theta) exp([w]x dt)
                    from scipy.spatial.transform import Rotation

                    rot = Rotation.from_matrix(r_zyx(th)) * Rotation.from_rotvec(w * dt)
                    yaw_, pitch_, roll_ = rot.as_euler("ZYX")
                    th = np.array([roll_, pitch_, yaw_])
                else:
                    th = th + dt * e_matrix(th) @ w  # eq. 5
                th[0] = wrap(th[0])
                th[2] = wrap(th[2])
                P = F @ P @ F.T + G @ (prm[_QW] * np.eye(3)) @ G.T  # eq. 6
            R = r_zyx(th)
            u = R.T @ [0, 0, 1.0]
            z, h, Hs, v = [], [], [], []
            q_dyn = 0.0
            if acc_fin and prm[_DYN_CORR] > 0:  # white-noise equivalent of the body's acceleration
                var_dyn = dynamic_var(aux, a, R, dt, prm[_DYN_TAU])
                if dt > 0:
                    q_dyn = 2 * prm[_DYN_CORR] * var_dyn / dt
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                z.append(a)
                h.append(R.T @ [0, 0, g_])
                Hs.append(complex_step_jacobian(lambda x: r_zyx(x).T @ [0, 0, g_], th))
                # Q_g grows with the rate of turn (rate_ref_rad_s)
                v += [prm[_QG] * (1.0 + rate2 / prm[_RATE_REF] ** 2) + q_dyn] * 3
            if mag_fin and mag_gate(aux, prm, *m, *u, dt):
                nb = m - (m @ u) * u
                z.append(nb / np.linalg.norm(nb))
                h.append(R.T @ [0, 1.0, 0])
                Hs.append(complex_step_jacobian(lambda x: r_zyx(x).T @ [0, 1.0, 0], th))
                v += [prm[_QN]] * 3
            yv = np.nan if yaw is None else yaw[i]
            if np.isfinite(yv):
                z.append([th[2] + wrap(yv - th[2])])
                h.append([th[2]])
                Hs.append(np.array([[0, 0, 1.0]]))
                v.append(prm[_QETA])
            if z:  # eq. 8-11, stacked
                zz = np.concatenate(z)
                hh = np.concatenate(h)
                H = np.vstack(Hs)
                S = H @ P @ H.T + np.diag(v)
                Kg = P @ H.T @ np.linalg.inv(S)
                th = th + Kg @ (zz - hh)
                P = (np.eye(3) - Kg @ H) @ P
                P = 0.5 * (P + P.T)
                th[0] = wrap(th[0])
                th[2] = wrap(th[2])
        out[i] = th
        var[i] = np.diag(P)
    return out, var


# ---------------------------------------------------------------------------------------------
# FQA and complementary filter (Inderst 4.2.2)
# ---------------------------------------------------------------------------------------------
def fqa_reference(a, m):
    from hrtls.frames import quat_from_euler

    a = np.asarray(a) / np.linalg.norm(a)
    pitch = math.asin(max(-1.0, min(1.0, -a[0])))
    roll = math.atan2(a[1], a[2]) if math.cos(pitch) > 1e-9 else 0.0
    q_pr = quat_from_euler(roll, pitch, 0.0)
    ml = rot_h(q_pr) @ np.asarray(m)
    if math.hypot(ml[0], ml[1]) < 1e-9:
        return q_pr
    yaw = math.atan2(ml[0], ml[1])
    return quat_from_euler(roll, pitch, yaw)


def complementary_reference(t, acc, gyr, mag, prm, has_gyr=True, has_mag=True):
    from hrtls.attitude.complementary import _B_MAX, _TAU_A, _TAU_B, _TAU_M, _W_REF

    aux = K.new_aux(prm[K.PRM_BIAS0:K.PRM_BIAS0 + 3].copy())
    q = np.array([1.0, 0, 0, 0])
    out = np.zeros((len(t), 4))
    g_ = prm[K.PRM_GRAVITY]

    def blend(gam, qs, qd):  # eq. 4.20
        if qs @ qd < 0:
            qs = -qs
        r = gam * qs + (1 - gam) * qd
        return r / np.linalg.norm(r)

    for i in range(len(t)):
        dt = t[i] - aux[K.AUX_T_PREV] if np.isfinite(aux[K.AUX_T_PREV]) else 0.0
        aux[K.AUX_T_PREV] = t[i]
        a, an, acc_fin, g, gyr_fin, m, mag_fin = _read(prm, acc, gyr, mag, has_gyr, has_mag, i)
        acc_dev = abs(an - g_) if acc_fin else math.inf
        if aux[K.AUX_INIT] < 0.5:
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                q = init_q(a, m, mag_fin and prm[K.PRM_INIT_MAG] > 0.5)
                aux[K.AUX_INIT] = 1.0
                init_rest(aux, *g, *a, gyr_fin)
                if mag_fin:
                    mag_gate(aux, prm, *m, *(rot_h(q).T @ [0, 0, 1.0]), 0.0)
            else:
                out[i] = [1, 0, 0, 0]
                continue
        else:
            rate = 0.0
            used_gyr = False
            qd = q
            if gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]:
                if acc_fin:
                    rest_and_bias(aux, prm, *g, *a, dt)
                w = g - aux[K.AUX_BIAS:K.AUX_BIAS + 3]
                rate = float(np.linalg.norm(w))
                qd = expm(omega(w) * dt) @ q
                qd = qd / np.linalg.norm(qd)
                used_gyr = True
            trust = 1.0 / (1.0 + (rate / prm[_W_REF]) ** 2)
            step = max(dt, 0.0)
            qn = qd
            ga = gm = 0.0
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                ga = (1 - math.exp(-step / prm[_TAU_A])) * trust * (
                    1 - acc_dev / prm[K.PRM_ACC_GATE])
                qn = blend(ga, fqa_reference(a, rot_h(qn).T @ [0, 1.0, 0]), qn)
            qt = qn
            u = rot_h(qn).T @ [0, 0, 1.0]
            if mag_fin and mag_gate(aux, prm, *m, *u, dt):
                dev = abs(np.linalg.norm(m) - aux[K.AUX_MREF_N])
                gm = (1 - math.exp(-step / prm[_TAU_M])) * trust * max(
                    0.0, 1 - dev / prm[K.PRM_MAG_NORM_GATE])
                qn = blend(gm, fqa_reference(u, m), qn)
            if used_gyr and (ga > 0 or gm > 0) and prm[K.PRM_BIAS_EST] > 0.5:
                e = qmul(qd * [1, -1, -1, -1], qt)
                delta = 2.0 * e[1:] * (1.0 if e[0] >= 0 else -1.0)
                e = qmul(qt * [1, -1, -1, -1], qn)
                dh = 2.0 * e[1:] * (1.0 if e[0] >= 0 else -1.0)
                delta = delta + (dh @ u) * u
                aux[K.AUX_BIAS:K.AUX_BIAS + 3] = np.clip(
                    aux[K.AUX_BIAS:K.AUX_BIAS + 3] - delta / prm[_TAU_B], -prm[_B_MAX],
                    prm[_B_MAX])
            q = qn if qn[0] >= 0 else -qn
        out[i] = q
    return out
