"""Compiled filter of :mod:`hrtls.attitude.inertial_lowpass` (the equations are described there).

The parameter array holds the shared part (:mod:`hrtls.attitude._kernels`) followed by
``TAU_ACC`` .. ``WALK``; the state vector ``x`` has the layout ``QG`` .. ``HS`` (``NX`` values),
``P`` is the 3 x 3 covariance of the gyro bias.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _ekf_update as EK
from hrtls.attitude import _kernels as K
from hrtls.attitude import _quaternion as Q
from hrtls.attitude._jit import JIT
from hrtls.frames import FloatArray
from hrtls.kernels import njit

# ---- parameter layout (after the shared part)
TAU_ACC = K.PRM_SPECIFIC
TAU_MAG = K.PRM_SPECIFIC + 1
BIAS_EST = K.PRM_SPECIFIC + 2
B_SIG0 = K.PRM_SPECIFIC + 3
B_FORGET = K.PRM_SPECIFIC + 4
B_CLIP = K.PRM_SPECIFIC + 5
B_SIG_MOT = K.PRM_SPECIFIC + 6
B_VERT = K.PRM_SPECIFIC + 7
B_SIG_REST = K.PRM_SPECIFIC + 8
M_CUR_TAU = K.PRM_SPECIFIC + 9
M_REF_TAU = K.PRM_SPECIFIC + 10
M_NEW_FIRST = K.PRM_SPECIFIC + 11
M_NEW_RATE = K.PRM_SPECIFIC + 12
M_UNDIST = K.PRM_SPECIFIC + 13
M_MAX_REJ = K.PRM_SPECIFIC + 14
M_REJ_FACTOR = K.PRM_SPECIFIC + 15
TILT_SIG = K.PRM_SPECIFIC + 16
HEAD_SIG = K.PRM_SPECIFIC + 17
WALK = K.PRM_SPECIFIC + 18

BIAS_GROWTH_RAD2_S2 = float(np.deg2rad(0.1)) ** 2  # bias variance growth per bias_forgetting_s
Mat3 = tuple[float, float, float, float, float, float, float, float, float]  # row-major 3 x 3
EYE3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)

# ---- state layout
QG = 0  # 0..3 q_gyr (d -> I)
QA = 4  # 4..7 q_acc (I -> E')
HC = 8  # cos(delta / 2) of the heading correction delta about the vertical
ALP = 9  # 9..14 biquad state of lp(a_I), two per axis
RLP = 15  # 15..32 biquad state of lp(R_6), row-major, two per entry
RBLP = 33  # 33..38 biquad state of lp(R_6 b)
DT = 39  # sample period the coefficients below belong to, s (0: none yet)
CB0 = 40  # biquad b0, b1 (= 2 b0), b2 (= b0), a1, a2 at 40, 41, 42
CA1 = 41
CA2 = 42
KACC = 43  # 1 - exp(-dt / tau_acc)
KMAG = 44  # 1 - exp(-dt / tau_mag)
KCUR = 45  # gain of the norm/dip low-pass
KREF = 46  # gain of the reference update
MN = 47  # low-passed field norm, uT
MDIP = 48  # low-passed dip, rad
MUND_T = 49  # time undisturbed, s
MREJ_T = 50  # rejection time used, s
MDIST = 51  # 1.0 while the field is disturbed
MINIT = 52  # count of the averaging first heading corrections (0: done)
MFIRST = 53  # 1.0 while the reference is only the first sample
VTILT = 54  # roll/pitch variance, rad^2
VHEAD = 55  # heading variance, rad^2
LPOK = 56  # 1.0 once the low-passes were started on a sample
HS = 57  # sin(delta / 2)
NX = 58



@njit(inline="always", **JIT)
def _biquad(x: FloatArray, k: int, u: float, b0: float, a1: float, a2: float) -> float:
    """One step of the Butterworth low-pass (transposed direct form II, ``b = b0 [1, 2, 1]``)."""
    y = b0 * u + x[k]
    x[k] = 2.0 * b0 * u - a1 * y + x[k + 1]
    x[k + 1] = b0 * u - a2 * y
    return y


@njit(inline="always", **JIT)
def _biquad_steady(x: FloatArray, k: int, u: float, b0: float, a1: float, a2: float) -> None:
    """The state of a low-pass that has seen the constant ``u`` forever (output ``u``)."""
    x[k + 1] = (b0 - a2) * u
    x[k] = (3.0 * b0 - a1 - a2) * u


@njit(**JIT)
def _set_gains(x: FloatArray, prm: FloatArray, dt: float) -> None:
    """Gains for the sample period ``dt``.

    Butterworth by the bilinear transform with pre-warping, ``K = tan(pi f_c dt)``,
    ``b0 = K^2 / (1 + sqrt2 K + K^2)``, ``a1 = 2 (K^2 - 1) / (.)``,
    ``a2 = (1 - sqrt2 K + K^2) / (.)``; first-order gains ``1 - exp(-dt / tau)``.
    """
    fc = math.sqrt(2.0) / (2.0 * math.pi * prm[TAU_ACC])
    kk = math.tan(min(math.pi * fc * dt, 1.2))
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * kk + kk * kk)
    x[CB0] = kk * kk * nrm
    x[CA1] = 2.0 * (kk * kk - 1.0) * nrm
    x[CA2] = (1.0 - math.sqrt(2.0) * kk + kk * kk) * nrm
    x[KACC] = 1.0 - math.exp(-dt / prm[TAU_ACC])
    x[KMAG] = 1.0 - math.exp(-dt / prm[TAU_MAG])
    x[KCUR] = 1.0 - math.exp(-dt / prm[M_CUR_TAU])
    x[KREF] = 1.0 - math.exp(-dt / prm[M_REF_TAU])
    x[DT] = dt


@njit(inline="always", **JIT)
def _rotation_matrix(w: float, x: float, y: float, z: float, out: FloatArray) -> None:
    """``R(q)`` row-major into ``out[0:9]``."""
    out[0] = 1.0 - 2.0 * (y * y + z * z)
    out[1] = 2.0 * (x * y - w * z)
    out[2] = 2.0 * (x * z + w * y)
    out[3] = 2.0 * (x * y + w * z)
    out[4] = 1.0 - 2.0 * (x * x + z * z)
    out[5] = 2.0 * (y * z - w * x)
    out[6] = 2.0 * (x * z - w * y)
    out[7] = 2.0 * (y * z + w * x)
    out[8] = 1.0 - 2.0 * (x * x + y * y)


@njit(**JIT)
def _restart_lowpass(x: FloatArray, aux: FloatArray, a_i: tuple[float, float, float],
                     rr: FloatArray) -> None:
    """Low-pass states at rest on the current ``a_I``, ``R_6`` (in ``rr``) and ``R_6 b``."""
    b0 = x[CB0]
    a1 = x[CA1]
    a2 = x[CA2]
    for c in range(3):
        _biquad_steady(x, ALP + 2 * c, a_i[c], b0, a1, a2)
    for r in range(9):
        _biquad_steady(x, RLP + 2 * r, rr[r], b0, a1, a2)
    for r in range(3):
        rb = (rr[3 * r] * aux[K.AUX_BIAS] + rr[3 * r + 1] * aux[K.AUX_BIAS + 1]
              + rr[3 * r + 2] * aux[K.AUX_BIAS + 2])
        _biquad_steady(x, RBLP + 2 * r, rb, b0, a1, a2)


@njit(inline="always", **JIT)
def _steady_noise(var: float, growth: float) -> float:
    """Measurement variance ``w = var^2 / v + var`` whose steady-state estimate variance is ``var``.

    For a scalar random walk with per-sample growth ``v`` measured every sample with variance
    ``w``, the a-priori variance ``p`` solves ``p^2 = v (p + w)``; the a-posteriori one,
    ``p w / (p + w)``, equals ``var`` for this ``w`` [3.4].
    """
    return var * var / max(growth, 1e-300) + var


@njit(inline="always", **JIT)
def _bias_update(P: FloatArray, aux: FloatArray, H: Mat3, y0: float, y1: float, y2: float,
                 w0: float, w1: float, w2: float, clip: float) -> None:
    """Kalman update of the bias, ``b`` clipped.

    ``S = H P H^T + diag(w)``, ``K = P H^T S^-1``, ``b += K y``, ``P -= K H P`` (``H``
    row-major 3 x 3, ``P`` symmetric). The arrays are read first and written last, outside any
    branch (see :func:`hrtls.attitude._kernels.read_sample`); ``S`` not positive definite
    changes nothing.
    """
    p00, p01, p02, p11, p12, p22 = P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]
    b0, b1, b2 = aux[K.AUX_BIAS], aux[K.AUX_BIAS + 1], aux[K.AUX_BIAS + 2]
    h0, h1, h2, h3, h4, h5, h6, h7, h8 = H
    # M = P H^T (m_ar = M[a, r])
    m00, m01, m02 = p00 * h0 + p01 * h1 + p02 * h2, p00 * h3 + p01 * h4 + p02 * h5, \
        p00 * h6 + p01 * h7 + p02 * h8
    m10, m11, m12 = p01 * h0 + p11 * h1 + p12 * h2, p01 * h3 + p11 * h4 + p12 * h5, \
        p01 * h6 + p11 * h7 + p12 * h8
    m20, m21, m22 = p02 * h0 + p12 * h1 + p22 * h2, p02 * h3 + p12 * h4 + p22 * h5, \
        p02 * h6 + p12 * h7 + p22 * h8
    ok, i00, i01, i02, i11, i12, i22 = EK.sym3_inverse(
        h0 * m00 + h1 * m10 + h2 * m20 + w0, h0 * m01 + h1 * m11 + h2 * m21,
        h0 * m02 + h1 * m12 + h2 * m22, h3 * m01 + h4 * m11 + h5 * m21 + w1,
        h3 * m02 + h4 * m12 + h5 * m22, h6 * m02 + h7 * m12 + h8 * m22 + w2)
    k00, k01, k02 = _row_times_sym3(m00, m01, m02, i00, i01, i02, i11, i12, i22)
    k10, k11, k12 = _row_times_sym3(m10, m11, m12, i00, i01, i02, i11, i12, i22)
    k20, k21, k22 = _row_times_sym3(m20, m21, m22, i00, i01, i02, i11, i12, i22)
    b0 = _clipped_step(b0, k00 * y0 + k01 * y1 + k02 * y2, clip) if ok else b0
    b1 = _clipped_step(b1, k10 * y0 + k11 * y1 + k12 * y2, clip) if ok else b1
    b2 = _clipped_step(b2, k20 * y0 + k21 * y1 + k22 * y2, clip) if ok else b2
    p00 = p00 - (k00 * m00 + k01 * m01 + k02 * m02) if ok else p00
    p11 = p11 - (k10 * m10 + k11 * m11 + k12 * m12) if ok else p11
    p22 = p22 - (k20 * m20 + k21 * m21 + k22 * m22) if ok else p22
    p01 = p01 - (k00 * m10 + k01 * m11 + k02 * m12) if ok else p01
    p02 = p02 - (k00 * m20 + k01 * m21 + k02 * m22) if ok else p02
    p12 = p12 - (k10 * m20 + k11 * m21 + k12 * m22) if ok else p12
    aux[K.AUX_BIAS], aux[K.AUX_BIAS + 1], aux[K.AUX_BIAS + 2] = b0, b1, b2
    P[0, 0], P[1, 1], P[2, 2] = p00, p11, p22
    P[0, 1] = P[1, 0] = p01
    P[0, 2] = P[2, 0] = p02
    P[1, 2] = P[2, 1] = p12


@njit(inline="always", **JIT)
def _row_times_sym3(m0: float, m1: float, m2: float, i00: float, i01: float, i02: float,
                    i11: float, i12: float, i22: float) -> tuple[float, float, float]:
    """The row ``m`` times the symmetric matrix with upper triangle ``i``."""
    return (m0 * i00 + m1 * i01 + m2 * i02, m0 * i01 + m1 * i11 + m2 * i12,
            m0 * i02 + m1 * i12 + m2 * i22)


@njit(inline="always", **JIT)
def _clipped_step(b: float, db: float, clip: float) -> float:
    """``b + db`` clipped to ``[-clip, clip]``; ``b`` unchanged when ``db`` is not finite."""
    return min(clip, max(-clip, b + db)) if math.isfinite(db) else b


@njit(inline="always", **JIT)
def _start(x: FloatArray, P: FloatArray, aux: FloatArray, prm: FloatArray, flags: int,
           w: float, qx: float, qy: float, qz: float, r_tilt: float, r_head: float,
           p_max: float) -> None:
    """State at initialisation: ``q_gyr = q``, no inclination or heading correction yet."""
    Q.set_q(x, QG, w, qx, qy, qz)
    Q.set_q(x, QA, 1.0, 0.0, 0.0, 0.0)
    x[HC] = 1.0
    x[HS] = 0.0
    x[DT] = 0.0
    x[LPOK] = 0.0
    mag0 = (flags & K.FLAG_MAG) != 0
    x[MN] = aux[K.AUX_MREF_N]
    x[MDIP] = aux[K.AUX_MREF_DIP]
    x[MUND_T] = 0.0
    x[MREJ_T] = 0.0
    x[MDIST] = 0.0
    x[MINIT] = 2.0 if mag0 else 1.0
    x[MFIRST] = 0.0 if (math.isfinite(prm[K.PRM_MAG_REF_N])
                        and math.isfinite(prm[K.PRM_MAG_REF_DIP])) else 1.0
    x[VTILT] = r_tilt
    x[VHEAD] = r_head if mag0 else math.pi ** 2
    for a in range(3):
        for b in range(3):
            P[a, b] = p_max if a == b else 0.0


@njit(inline="always", **JIT)
def _mag_disturbance(x: FloatArray, aux: FloatArray, prm: FloatArray, mn: float, dip: float,
                     rate: float, dt: float, gn: float, gd: float) -> None:
    """Disturbance detection and reference update [3.5] from the field norm ``mn`` and dip.

    Low-passes norm and dip, sets ``x[MDIST]`` while they leave the reference, slowly updates
    the reference while undisturbed, and makes a candidate field that stays stable while the
    device turns (``rate``, rad/s) the new reference.
    """
    # arrays read first, written last (see _bias_update)
    k_cur, k_ref, und_t, dist, first = x[KCUR], x[KREF], x[MUND_T], x[MDIST], x[MFIRST]
    ref_n, ref_dip = aux[K.AUX_MREF_N], aux[K.AUX_MREF_DIP]
    cand_n, cand_dip, cand_t = aux[K.AUX_MCAND_N], aux[K.AUX_MCAND_DIP], aux[K.AUX_MCAND_T]
    und_min, new_rate, new_s, new_first = prm[M_UNDIST], prm[M_NEW_RATE], prm[K.PRM_MAG_NEW_S], \
        prm[M_NEW_FIRST]
    cn = x[MN] + k_cur * (mn - x[MN])
    cd = x[MDIP] + k_cur * (dip - x[MDIP])
    if abs(cn - ref_n) < gn and abs(cd - ref_dip) < gd:
        und_t += dt
        if und_t >= und_min:
            dist = 0.0
            ref_n += k_ref * (cn - ref_n)
            ref_dip += k_ref * (cd - ref_dip)
    else:
        und_t = 0.0
        dist = 1.0
    if abs(cn - cand_n) < gn and abs(cd - cand_dip) < gd:
        if rate >= new_rate:
            cand_t += dt
            cand_n += k_ref * (cn - cand_n)
            cand_dip += k_ref * (cd - cand_dip)
            if dist > 0.5 and (cand_t >= new_s or (first > 0.5 and cand_t >= new_first)):
                ref_n = cand_n
                ref_dip = cand_dip
                und_t = und_min
                dist = 0.0
                first = 0.0
    else:
        cand_n = cn
        cand_dip = cd
        cand_t = 0.0
    x[MN], x[MDIP], x[MUND_T], x[MDIST], x[MFIRST] = cn, cd, und_t, dist, first
    aux[K.AUX_MREF_N], aux[K.AUX_MREF_DIP] = ref_n, ref_dip
    aux[K.AUX_MCAND_N], aux[K.AUX_MCAND_DIP], aux[K.AUX_MCAND_T] = cand_n, cand_dip, cand_t


@njit(**JIT)
def inertial_lowpass_kernel(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, has_gyr: bool,
    has_mag: bool, prm: FloatArray, x: FloatArray, P: FloatArray, aux: FloatArray,
    out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
    out_extra: FloatArray,
) -> None:
    """The filter over one chunk (module text, steps 1-5); mutates ``x``, ``P`` and ``aux``."""
    n = t.shape[0]
    rr = np.empty(9)  # R_6 of this sample
    hh = np.empty(9)  # lp(R_6)
    sig0 = prm[B_SIG0]
    p_max = sig0 * sig0
    p_grow = BIAS_GROWTH_RAD2_S2 / prm[B_FORGET]
    clip = prm[B_CLIP]
    walk2 = prm[WALK] ** 2
    r_tilt = prm[TILT_SIG] ** 2
    r_head = prm[HEAD_SIG] ** 2
    gn = prm[K.PRM_MAG_NORM_GATE]
    gd = prm[K.PRM_MAG_DIP_GATE]
    bias_on = prm[BIAS_EST] > 0.5
    for i in range(n):
        s = K.read_sample(t, acc, gyr, mag, i, has_gyr, has_mag, prm, aux)
        dt = s.dt
        if aux[K.AUX_INIT] < 0.5:
            flags, w, qx, qy, qz = K.try_init(aux, prm, s, has_mag)
            if flags == 0:
                K.write_uninit(out_q, out_var, out_flags, i)
                out_extra[i, 0] = 0.0
                continue
            _start(x, P, aux, prm, flags, w, qx, qy, qz, r_tilt, r_head, p_max)
            Q.write_q(out_q, i, w, qx, qy, qz)
            out_var[i, 0] = x[VTILT]
            out_var[i, 1] = x[VTILT]
            out_var[i, 2] = x[VHEAD]
            out_flags[i] = flags
            out_extra[i, 0] = 0.0
            continue
        flags = K.FLAG_VALID
        gw = x[QG]
        gx = x[QG + 1]
        gy = x[QG + 2]
        gz = x[QG + 3]
        aw = x[QA]
        ax = x[QA + 1]
        ay = x[QA + 2]
        az = x[QA + 3]
        # ---- 1. strapdown integration [3.1]
        gflags = K.gyro_step(aux, prm, s, has_gyr)
        rate = 0.0
        if gflags:
            flags |= gflags
            wx, wy, wz = K.unbiased_rate(aux, s)
            rate = math.sqrt(wx * wx + wy * wy + wz * wz)
            gw, gx, gy, gz = Q.gyro_quat_step(gw, gx, gy, gz, wx, wy, wz, dt)
        restart = x[LPOK] < 0.5 or dt > prm[K.PRM_MAX_DT]  # not started yet, or a gap
        if abs(dt - x[DT]) > 0.01 * x[DT]:
            _set_gains(x, prm, dt)
        for a in range(3):
            if P[a, a] < p_max:
                P[a, a] += p_grow * dt
        # ---- 2. inclination from lp(a_I) [3.2]
        use_a = s.acc_fin
        k_tilt = 0.0
        wc0 = 0.0
        wc1 = 0.0
        if use_a:
            a_i = Q.rot(gw, gx, gy, gz, s.a0, s.a1, s.a2)
            sw, sx, sy, sz = Q.qmul(aw, ax, ay, az, gw, gx, gy, gz)
            _rotation_matrix(sw, sx, sy, sz, rr)
            b0 = x[CB0]
            a1 = x[CA1]
            a2 = x[CA2]
            if restart:
                _restart_lowpass(x, aux, a_i, rr)
                x[LPOK] = 1.0
            l0 = _biquad(x, ALP, a_i[0], b0, a1, a2)
            l1 = _biquad(x, ALP + 2, a_i[1], b0, a1, a2)
            l2 = _biquad(x, ALP + 4, a_i[2], b0, a1, a2)
            e0, e1, e2 = Q.rot(aw, ax, ay, az, l0, l1, l2)
            en = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if en > 1e-9:
                e0 /= en
                e1 /= en
                e2 /= en
                c = math.sqrt(max(0.5 * (1.0 + e2), 0.0))
                if c > 1e-6:
                    cw, cx, cy = c, 0.5 * e1 / c, -0.5 * e0 / c
                else:  # filtered gravity points down: half turn about x
                    cw, cx, cy = 0.0, 1.0, 0.0
                aw, ax, ay, az = Q.qmul(cw, cx, cy, 0.0, aw, ax, ay, az)
                an = math.sqrt(aw * aw + ax * ax + ay * ay + az * az)
                aw /= an
                ax /= an
                ay /= an
                az /= an
                wc0 = 2.0 * cx / dt
                wc1 = 2.0 * cy / dt
                k_tilt = x[KACC]
            else:
                use_a = False
            # ---- 4. gyro bias [3.4]: lp(R_6), lp(R_6 b) and the pseudo-measurement
            bx0 = aux[K.AUX_BIAS]
            bx1 = aux[K.AUX_BIAS + 1]
            bx2 = aux[K.AUX_BIAS + 2]
            for r in range(9):
                hh[r] = _biquad(x, RLP + 2 * r, rr[r], b0, a1, a2)
            lrb0 = _biquad(x, RBLP, rr[0] * bx0 + rr[1] * bx1 + rr[2] * bx2, b0, a1, a2)
            lrb1 = _biquad(x, RBLP + 2, rr[3] * bx0 + rr[4] * bx1 + rr[5] * bx2, b0, a1, a2)
            lrb2 = _biquad(x, RBLP + 4, rr[6] * bx0 + rr[7] * bx1 + rr[8] * bx2, b0, a1, a2)
            rest = (gflags & K.FLAG_REST) != 0
            if bias_on and (gflags & K.FLAG_GYR) and (rest or use_a):
                if rest:
                    wr = _steady_noise(prm[B_SIG_REST] ** 2, p_grow * dt)
                    hk = EYE3
                    y0 = aux[K.AUX_LP] - bx0
                    y1 = aux[K.AUX_LP + 1] - bx1
                    y2 = aux[K.AUX_LP + 2] - bx2
                    w0, w1, w2 = wr, wr, wr
                else:
                    wm = _steady_noise(prm[B_SIG_MOT] ** 2, p_grow * dt)
                    hk = (hh[0], hh[1], hh[2], hh[3], hh[4], hh[5], hh[6], hh[7], hh[8])
                    y0 = -wc0 + lrb0 - (hh[0] * bx0 + hh[1] * bx1 + hh[2] * bx2)
                    y1 = -wc1 + lrb1 - (hh[3] * bx0 + hh[4] * bx1 + hh[5] * bx2)
                    y2 = lrb2 - (hh[6] * bx0 + hh[7] * bx1 + hh[8] * bx2)
                    w0, w1, w2 = wm, wm, wm / prm[B_VERT]
                _bias_update(P, aux, hk, y0, y1, y2, w0, w1, w2, clip)
        # ---- 3. heading [3.3] with 5. disturbance rejection [3.5]
        use_m = False
        k_head = 0.0
        sw, sx, sy, sz = Q.qmul(aw, ax, ay, az, gw, gx, gy, gz)  # q_6
        hc = x[HC]
        hs = x[HS]
        if s.mag_fin:
            m0, m1, m2 = Q.rot(sw, sx, sy, sz, s.m0, s.m1, s.m2)
            mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            if mn > 1e-6:
                dip = math.asin(min(1.0, max(-1.0, -m2 / mn)))
                if K.first_field(aux, prm, mn, dip):
                    x[MN] = mn
                    x[MDIP] = dip
                _mag_disturbance(x, aux, prm, mn, dip, rate, dt, gn, gd)
                k_head = x[KMAG]
                if x[MINIT] > 0.5:
                    k_head = max(k_head, 1.0 / x[MINIT])
                if x[MDIST] > 0.5:
                    if x[MREJ_T] <= prm[M_MAX_REJ]:
                        x[MREJ_T] += dt
                        k_head = 0.0
                    else:
                        k_head /= prm[M_REJ_FACTOR]
                else:
                    x[MREJ_T] = max(x[MREJ_T] - prm[M_REJ_FACTOR] * dt, 0.0)
                hn = m0 * m0 + m1 * m1
                if k_head > 0.0 and hn > 1e-12:
                    # wrap(delta* - delta) is the angle from the field turned by delta to
                    # north: atan2(h_x, h_y) with h = R_z(delta) m
                    c_d = hc * hc - hs * hs
                    s_d = 2.0 * hc * hs
                    err = math.atan2(c_d * m0 - s_d * m1, s_d * m0 + c_d * m1)
                    # delta += k err, on the half-angle pair
                    c, sc = Q.cos_sinc(0.5 * k_head * err)
                    si = sc * 0.5 * k_head * err
                    hc, hs = hc * c - hs * si, hs * c + hc * si
                    hn = math.sqrt(hc * hc + hs * hs)
                    hc /= hn
                    hs /= hn
                    x[HC] = hc
                    x[HS] = hs
                    use_m = True
                    if x[MINIT] > 0.5:
                        x[MINIT] += 1.0
                        if 1.0 / x[MINIT] < x[KMAG]:
                            x[MINIT] = 0.0
                else:
                    k_head = 0.0
        flags = K.count_used(aux, flags, use_a, use_m, has_mag)
        # ---- variances (module text)
        x[VTILT] = min((1.0 - k_tilt) * x[VTILT] + k_tilt * r_tilt + walk2 * dt, math.pi ** 2)
        x[VHEAD] = min((1.0 - k_head) * x[VHEAD] + k_head * r_head + walk2 * dt, math.pi ** 2)
        Q.set_q(x, QG, gw, gx, gy, gz)
        Q.set_q(x, QA, aw, ax, ay, az)
        # ---- output q = R_z(delta) * q_acc * q_gyr
        w, qx, qy, qz = Q.qmul(hc, 0.0, 0.0, hs, sw, sx, sy, sz)
        w, qx, qy, qz = Q.positive_unit(w, qx, qy, qz)
        Q.write_q(out_q, i, w, qx, qy, qz)
        out_var[i, 0] = x[VTILT]
        out_var[i, 1] = x[VTILT]
        out_var[i, 2] = x[VHEAD]
        out_flags[i] = flags
        out_extra[i, 0] = x[MDIST]
