"""Compiled helpers shared by the attitude filters (quaternions, gates, rest detection).

Every filter keeps three plain float64 arrays as its state: ``x`` (its own state vector),
``P`` (its covariance, or an empty array) and ``aux`` (the bookkeeping below, the same layout for
all filters). Parameters travel to the kernels as one float64 array; the indices of the shared
part are the ``PRM_*`` constants, the filter-specific part starts at :data:`PRM_SPECIFIC`.

Conventions (see :mod:`hrtls.frames`): quaternions ``[w, x, y, z]``, Hamilton product, ``q``
rotates device vectors into ENU; specific force at rest is ``+g`` on the navigation z axis.
"""

from __future__ import annotations

import math
from collections import namedtuple
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

from hrtls.frames import FloatArray

FASTMATH = {"reassoc", "contract", "arcp", "nsz"}
"""LLVM fast-math flags of the kernels: reassociation and fused multiply-add, but NaN and inf
keep their IEEE meaning (the gates test for them)."""
JIT: dict[str, Any] = {"cache": True, "fastmath": FASTMATH, "error_model": "numpy"}
"""Options of every compiled attitude kernel."""

# ------------------------------------------------------------------------------------------
# aux layout (bookkeeping shared by every filter)
# ------------------------------------------------------------------------------------------
AUX_T_PREV = 0  # time of the previous sample, s
AUX_INIT = 1  # 1.0 once the attitude was initialised from the accelerometer
AUX_BIAS = 2  # 2..4 gyro bias, rad/s
AUX_LP = 5  # 5..7 low-passed gyro rate for rest detection, rad/s
AUX_REST_T = 8  # time spent at rest so far, s
AUX_MREF_N = 9  # reference field norm, uT
AUX_MREF_DIP = 10  # reference dip angle (positive down), rad
AUX_MCAND_N = 11  # candidate new field norm, uT
AUX_MCAND_DIP = 12  # candidate new field dip, rad
AUX_MCAND_T = 13  # time the candidate field has been stable, s
AUX_MPREV = 14  # 14..16 previous valid magnetometer sample, uT
AUX_MPREV_OK = 17  # 1.0 when AUX_MPREV holds a sample
AUX_MREF_SET = 18  # 1.0 once the reference field is known
AUX_N_ACC_REJ = 19  # accelerometer samples rejected (gate, non-finite, saturated)
AUX_N_MAG_REJ = 20  # magnetometer samples rejected
AUX_N_GYR_REJ = 21  # gyroscope samples not integrated (non-finite, saturated, bad dt)
AUX_N_BAD = 22  # samples with at least one non-finite or saturated sensor value
AUX_N = 23  # samples processed
AUX_ALP = 24  # 24..26 low-passed specific force for rest detection, m/s^2
AUX_DYN_MEAN = 27  # 27..29 running mean of the ENU specific force, m/s^2 (NaN: not started)
AUX_DYN_VAR = 30  # running per-axis variance of the ENU specific force, (m/s^2)^2
AUX_SIZE = 31

# ------------------------------------------------------------------------------------------
# shared parameter layout
# ------------------------------------------------------------------------------------------
PRM_GRAVITY = 0  # local gravity, m/s^2
PRM_ACC_GATE = 1  # | |a| - g | gate, m/s^2
PRM_MAG_NORM_GATE = 2  # | |m| - |m_ref| | gate, uT
PRM_MAG_DIP_GATE = 3  # | dip - dip_ref | gate, rad
PRM_MAG_JUMP_GATE = 4  # | m_k - m_{k-1} | gate, uT
PRM_MAG_NEW_S = 5  # a new stable field replaces the reference after this time, s (inf: never)
PRM_MAG_REF_N = 6  # reference field norm, uT (NaN: learn at initialisation)
PRM_MAG_REF_DIP = 7  # reference dip, rad (NaN: learn at initialisation)
PRM_GYR_RANGE = 8  # gyro samples above this rate are saturated, rad/s
PRM_ACC_RANGE = 9  # accelerometer samples above this norm are saturated, m/s^2
PRM_MAX_DT = 10  # longer sample gaps are not integrated, s
PRM_BIAS_EST = 11  # 1.0: estimate the gyro bias whenever the device is at rest
PRM_REST_GYR = 12  # rest: |w - lowpass(w)| and |lowpass(w) - b| below this, rad/s
PRM_REST_ACC = 13  # rest: | |a| - g | below this, m/s^2
PRM_REST_S = 14  # rest must last this long before the bias is updated, s
PRM_BIAS_TAU_S = 15  # time constant of the bias update (and of the rest low-pass), s
PRM_BIAS0 = 16  # 16..18 initial gyro bias, rad/s
PRM_INIT_MAG = 19  # 1.0: use the magnetometer heading at initialisation
PRM_SPECIFIC = 20

FLAG_ACC = 1
FLAG_MAG = 2
FLAG_GYR = 4
FLAG_VALID = 8
FLAG_REST = 16


def new_aux(bias0: FloatArray) -> FloatArray:
    """Fresh bookkeeping array (uninitialised filter, given initial gyro bias)."""
    aux = np.zeros(AUX_SIZE)
    aux[AUX_T_PREV] = np.nan
    aux[AUX_BIAS : AUX_BIAS + 3] = bias0
    aux[AUX_LP : AUX_LP + 3] = bias0
    aux[AUX_DYN_MEAN : AUX_DYN_MEAN + 3] = np.nan
    return aux


# ------------------------------------------------------------------------------------------
# quaternion helpers (scalar first, Hamilton)
# ------------------------------------------------------------------------------------------
@numba.njit(inline="always", **JIT)
def qmul(
    aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float, bz: float
) -> tuple[float, float, float, float]:
    """Hamilton product ``a * b``."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@numba.njit(inline="always", **JIT)
def rot_t(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[float, float, float]:
    """``R(q)^T v`` with the homogeneous rotation matrix (exact for unit ``q``)."""
    return (
        (w * w + x * x - y * y - z * z) * v0 + 2.0 * (x * y + w * z) * v1
        + 2.0 * (x * z - w * y) * v2,
        2.0 * (x * y - w * z) * v0 + (w * w - x * x + y * y - z * z) * v1
        + 2.0 * (y * z + w * x) * v2,
        2.0 * (x * z + w * y) * v0 + 2.0 * (y * z - w * x) * v1
        + (w * w - x * x - y * y + z * z) * v2,
    )


@numba.njit(inline="always", **JIT)
def rot(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[float, float, float]:
    """``R(q) v`` for a unit quaternion (device -> navigation)."""
    return rot_t(w, -x, -y, -z, v0, v1, v2)


Row3 = tuple[float, float, float]
Row4 = tuple[float, float, float, float]


@numba.njit(inline="always", **JIT)
def rot_t_jac(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[Row4, Row4, Row4]:
    """``d(R(q)^T v)/dq`` (3 x 4, columns w, x, y, z) as three row tuples."""
    return (
        (2.0 * (w * v0 + z * v1 - y * v2), 2.0 * (x * v0 + y * v1 + z * v2),
         2.0 * (-y * v0 + x * v1 - w * v2), 2.0 * (-z * v0 + w * v1 + x * v2)),
        (2.0 * (-z * v0 + w * v1 + x * v2), 2.0 * (y * v0 - x * v1 + w * v2),
         2.0 * (x * v0 + y * v1 + z * v2), 2.0 * (-w * v0 - z * v1 + y * v2)),
        (2.0 * (y * v0 - x * v1 + w * v2), 2.0 * (z * v0 - w * v1 - x * v2),
         2.0 * (w * v0 + z * v1 - y * v2), 2.0 * (x * v0 + y * v1 + z * v2)),
    )


@numba.njit(**JIT)
def rot_t_jacobian(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float, out: FloatArray
) -> None:
    """Write ``d(R(q)^T v)/dq`` (3 x 4, columns w, x, y, z) into ``out``."""
    jac = rot_t_jac(w, x, y, z, v0, v1, v2)
    for j in range(3):
        for b in range(4):
            out[j, b] = jac[j][b]


@numba.njit(inline="always", **JIT)
def cos_sinc(a: float) -> tuple[float, float]:
    """``cos(a)`` and ``sin(a)/a``; Taylor series below 0.1 rad (error < 1e-16)."""
    if abs(a) < 0.1:
        a2 = a * a
        c = 1.0 - a2 / 2.0 * (1.0 - a2 / 12.0 * (1.0 - a2 / 30.0 * (1.0 - a2 / 56.0)))
        sc = 1.0 - a2 / 6.0 * (1.0 - a2 / 20.0 * (1.0 - a2 / 42.0 * (1.0 - a2 / 72.0)))
        return c, sc
    return math.cos(a), math.sin(a) / a


@numba.njit(inline="always", **JIT)
def transition(wx: float, wy: float, wz: float, dt: float, phi: FloatArray) -> None:
    """``Phi = exp(Omega dt)`` for ``dq/dt = Omega q = q * [0, w] / 2`` (Inderst eq. 4.10-4.12).

    ``Omega`` is skew, so the exponential is ``cos(a) I + sin(a)/|w| * 2 Omega`` with
    ``a = |w| dt / 2``.
    """
    n = math.sqrt(wx * wx + wy * wy + wz * wz)
    c, sc = cos_sinc(0.5 * n * dt)
    # sin(a)/|w| = sinc(a) dt / 2 (the 2 of 2 Omega cancels the 1/2 inside Omega)
    s = sc * 0.5 * dt
    phi[0, 0] = c
    phi[0, 1] = -s * wx
    phi[0, 2] = -s * wy
    phi[0, 3] = -s * wz
    phi[1, 0] = s * wx
    phi[1, 1] = c
    phi[1, 2] = s * wz
    phi[1, 3] = -s * wy
    phi[2, 0] = s * wy
    phi[2, 1] = -s * wz
    phi[2, 2] = c
    phi[2, 3] = s * wx
    phi[3, 0] = s * wz
    phi[3, 1] = s * wy
    phi[3, 2] = -s * wx
    phi[3, 3] = c


@numba.njit(**JIT)
def shortest_arc_to_up(ax: float, ay: float, az: float) -> tuple[float, float, float, float]:
    """Quaternion rotating the unit vector ``a`` onto ``+z`` by the shortest arc.

    Our reading of Inderst eq. 4.13 (initial tilt from the specific force at rest): the axis is
    ``a x e_z`` and ``cos(angle) = a_z``, so ``q = [1 + a_z, a_y, -a_x, 0] / norm``.
    """
    w = 1.0 + az
    if w < 1e-9:  # upside down: half turn about x
        return 0.0, 1.0, 0.0, 0.0
    n = math.sqrt(w * w + ay * ay + ax * ax)
    return w / n, ay / n, -ax / n, 0.0


@numba.njit(**JIT)
def heading_from_mag(
    w: float, x: float, y: float, z: float, mx: float, my: float, mz: float
) -> tuple[float, float, float, float]:
    """Rotate ``q`` about the vertical so the horizontal field of ``m`` points north (+y ENU)."""
    nx, ny, _ = rot(w, x, y, z, mx, my, mz)
    if nx * nx + ny * ny < 1e-18:
        return w, x, y, z
    ang = 0.5 * math.pi - math.atan2(ny, nx)
    c = math.cos(0.5 * ang)
    s = math.sin(0.5 * ang)
    return qmul(c, 0.0, 0.0, s, w, x, y, z)


@numba.njit(inline="always", **JIT)
def finite3(v0: float, v1: float, v2: float) -> bool:
    """All three components finite."""
    return math.isfinite(v0) and math.isfinite(v1) and math.isfinite(v2)


@numba.njit(inline="always", **JIT)
def gyro_ok(prm: FloatArray, g0: float, g1: float, g2: float) -> bool:
    """Gyro sample finite and inside the measurement range."""
    r = prm[PRM_GYR_RANGE]
    return finite3(g0, g1, g2) and abs(g0) < r and abs(g1) < r and abs(g2) < r


@numba.njit(inline="always", **JIT)
def rest_and_bias(
    aux: FloatArray, prm: FloatArray, g0: float, g1: float, g2: float,
    a0: float, a1: float, a2: float, dt: float,
) -> bool:
    """Rest detection and gyro-bias update at rest; returns True when at rest.

    Rest: the gyro rate stays within ``PRM_REST_GYR`` of its 0.5 s low-pass, the low-pass
    stays within ``2 PRM_REST_GYR`` of the current bias, and the specific force stays within
    ``PRM_REST_ACC`` of its low-pass and of g in norm, all for ``PRM_REST_S``. While at rest
    the bias follows the low-passed rate: a running mean from the start of the rest, then an
    exponential average with time constant ``PRM_BIAS_TAU_S``.
    ``a`` must be finite.
    """
    k = dt / (0.5 + dt)
    aux[AUX_LP] += k * (g0 - aux[AUX_LP])
    aux[AUX_LP + 1] += k * (g1 - aux[AUX_LP + 1])
    aux[AUX_LP + 2] += k * (g2 - aux[AUX_LP + 2])
    aux[AUX_ALP] += k * (a0 - aux[AUX_ALP])
    aux[AUX_ALP + 1] += k * (a1 - aux[AUX_ALP + 1])
    aux[AUX_ALP + 2] += k * (a2 - aux[AUX_ALP + 2])
    d0 = g0 - aux[AUX_LP]
    d1 = g1 - aux[AUX_LP + 1]
    d2 = g2 - aux[AUX_LP + 2]
    e0 = aux[AUX_LP] - aux[AUX_BIAS]
    e1 = aux[AUX_LP + 1] - aux[AUX_BIAS + 1]
    e2 = aux[AUX_LP + 2] - aux[AUX_BIAS + 2]
    f0 = a0 - aux[AUX_ALP]
    f1 = a1 - aux[AUX_ALP + 1]
    f2 = a2 - aux[AUX_ALP + 2]
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    thr = prm[PRM_REST_GYR]
    thr_a = prm[PRM_REST_ACC]
    still = (d0 * d0 + d1 * d1 + d2 * d2 < thr * thr
             and e0 * e0 + e1 * e1 + e2 * e2 < 4.0 * thr * thr
             and f0 * f0 + f1 * f1 + f2 * f2 < thr_a * thr_a
             and abs(an - prm[PRM_GRAVITY]) < thr_a)
    if not still:
        aux[AUX_REST_T] = 0.0
        return False
    aux[AUX_REST_T] += dt
    if aux[AUX_REST_T] < prm[PRM_REST_S]:
        return False
    if prm[PRM_BIAS_EST] > 0.5:
        # running mean over the rest so far, then exponential with PRM_BIAS_TAU_S
        kb = dt / min(prm[PRM_BIAS_TAU_S] + dt, aux[AUX_REST_T] - prm[PRM_REST_S] + dt)
        aux[AUX_BIAS] += kb * e0
        aux[AUX_BIAS + 1] += kb * e1
        aux[AUX_BIAS + 2] += kb * e2
    return True


@numba.njit(**JIT)
def init_rest(aux: FloatArray, g0: float, g1: float, g2: float, a0: float, a1: float,
              a2: float, gyr_ok: bool) -> None:
    """Start the rest low-passes at the first samples (at initialisation)."""
    if gyr_ok:
        aux[AUX_LP] = g0
        aux[AUX_LP + 1] = g1
        aux[AUX_LP + 2] = g2
    aux[AUX_ALP] = a0
    aux[AUX_ALP + 1] = a1
    aux[AUX_ALP + 2] = a2


@numba.njit(inline="always", **JIT)
def mag_gate(
    aux: FloatArray, prm: FloatArray, mx: float, my: float, mz: float,
    ux: float, uy: float, uz: float, dt: float,
) -> bool:
    """Magnetometer gate (Inderst Sec. 4.2.1), extended by a dip test and field re-learning.

    ``u`` is the current estimate of the up direction in the device frame. The sample passes
    when its norm matches the reference norm (``eps_m``), it did not jump since the previous
    sample (``eps_dm``) and its dip matches the reference dip. The reference is learnt at the
    first sample (unless given); a different field that stays stable for ``PRM_MAG_NEW_S`` s
    becomes the new reference (a building's field differs from the outdoor one).
    """
    n = math.sqrt(mx * mx + my * my + mz * mz)
    if n < 1e-6:
        return False
    sd = -(mx * ux + my * uy + mz * uz) / n
    sd = min(1.0, max(-1.0, sd))
    dip = math.asin(sd)
    jump_ok = True
    if aux[AUX_MPREV_OK] > 0.5:
        j0 = mx - aux[AUX_MPREV]
        j1 = my - aux[AUX_MPREV + 1]
        j2 = mz - aux[AUX_MPREV + 2]
        g = prm[PRM_MAG_JUMP_GATE]
        jump_ok = j0 * j0 + j1 * j1 + j2 * j2 < g * g
    aux[AUX_MPREV] = mx
    aux[AUX_MPREV + 1] = my
    aux[AUX_MPREV + 2] = mz
    aux[AUX_MPREV_OK] = 1.0
    if aux[AUX_MREF_SET] < 0.5:
        aux[AUX_MREF_N] = prm[PRM_MAG_REF_N] if math.isfinite(prm[PRM_MAG_REF_N]) else n
        aux[AUX_MREF_DIP] = prm[PRM_MAG_REF_DIP] if math.isfinite(prm[PRM_MAG_REF_DIP]) else dip
        aux[AUX_MCAND_N] = n
        aux[AUX_MCAND_DIP] = dip
        aux[AUX_MCAND_T] = 0.0
        aux[AUX_MREF_SET] = 1.0
    # candidate tracking: a field that stays put for long enough becomes the reference
    gn = prm[PRM_MAG_NORM_GATE]
    gd = prm[PRM_MAG_DIP_GATE]
    if abs(n - aux[AUX_MCAND_N]) < gn and abs(dip - aux[AUX_MCAND_DIP]) < gd:
        aux[AUX_MCAND_T] += dt
        k = dt / (1.0 + dt)
        aux[AUX_MCAND_N] += k * (n - aux[AUX_MCAND_N])
        aux[AUX_MCAND_DIP] += k * (dip - aux[AUX_MCAND_DIP])
    else:
        aux[AUX_MCAND_N] = n
        aux[AUX_MCAND_DIP] = dip
        aux[AUX_MCAND_T] = 0.0
    norm_ok = abs(n - aux[AUX_MREF_N]) < gn
    dip_ok = abs(dip - aux[AUX_MREF_DIP]) < gd
    if not (norm_ok and dip_ok) and aux[AUX_MCAND_T] > prm[PRM_MAG_NEW_S]:
        aux[AUX_MREF_N] = aux[AUX_MCAND_N]
        aux[AUX_MREF_DIP] = aux[AUX_MCAND_DIP]
        norm_ok = True
        dip_ok = abs(dip - aux[AUX_MREF_DIP]) < gd
    return norm_ok and dip_ok and jump_ok


@numba.njit(**JIT)
def init_attitude(
    prm: FloatArray, a0: float, a1: float, a2: float, m0: float, m1: float, m2: float,
    mag_ok: bool,
) -> tuple[float, float, float, float]:
    """Initial ``q`` from the specific force (eq. 4.13 reading) and the magnetometer heading."""
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    w, x, y, z = shortest_arc_to_up(a0 / an, a1 / an, a2 / an)
    if mag_ok and prm[PRM_INIT_MAG] > 0.5:
        w, x, y, z = heading_from_mag(w, x, y, z, m0, m1, m2)
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    return w, x, y, z


@numba.njit(inline="always", **JIT)
def nav_rotation_var(
    w: float, x: float, y: float, z: float, P: FloatArray, out: FloatArray, i: int
) -> None:
    """Variances of the small rotation about the ENU axes implied by a quaternion covariance.

    ``dtheta_n = 2 vec(dq * conj(q)) = 2 M dq``; writes ``diag(4 M P M^T)`` to ``out[i]``.
    """
    m = ((-x, w, -z, y), (-y, z, w, -x), (-z, -y, x, w))
    for r in range(3):
        row = m[r]
        acc = 0.0
        for a in range(4):
            pa = 0.0
            for b in range(4):
                pa += P[a, b] * row[b]
            acc += row[a] * pa
        out[i, r] = 4.0 * acc


@numba.njit(inline="always", **JIT)
def sym3_inverse(
    s00: float, s01: float, s02: float, s11: float, s12: float, s22: float
) -> tuple[bool, float, float, float, float, float, float]:
    """Inverse of a symmetric positive definite 3 x 3 matrix by cofactors (upper triangle).

    Returns False and zeros when the determinant is not positive.
    """
    c00 = s11 * s22 - s12 * s12
    c01 = s02 * s12 - s01 * s22
    c02 = s01 * s12 - s02 * s11
    det = s00 * c00 + s01 * c01 + s02 * c02
    if not det > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    inv = 1.0 / det
    return (True, c00 * inv, c01 * inv, c02 * inv, (s00 * s22 - s02 * s02) * inv,
            (s01 * s02 - s00 * s12) * inv, (s00 * s11 - s01 * s01) * inv)


def make_block3(n: int, m: int) -> Callable[..., bool]:
    """Compile the 3-row block update for ``n`` states of which the first ``m`` are measured.

    ``H`` is zero beyond column ``m`` (e.g. the gyro bias is not measured directly); fixed
    sizes let LLVM unroll the loops.
    """

    # closures of one qualname must not share a cache entry: no cache
    @numba.njit(inline="always", fastmath=FASTMATH, error_model="numpy")
    def update(
        P: FloatArray, dx: FloatArray, H: Any, r0: float, r1: float, r2: float, var: float,
        ph: FloatArray,
    ) -> bool:
        """EKF update with a 3-row measurement block, linearised at the prediction.

        ``dx`` is the correction accumulated so far from earlier blocks (all blocks share one
        linearisation point), so consecutive blocks equal one stacked update (eq. 4.19 / Colombo
        eq. 8-11): ``S = H P H^T + var I``, ``K = P H^T S^-1``, ``dx += K (r - H dx)``,
        ``P -= K H P``. ``H`` is a tuple of three rows, each a tuple of ``m`` values (held in
        registers); ``ph`` is an (n, 3) work array. Returns False (nothing changed) when ``S``
        is not positive definite.
        """
        H0, H1, H2 = H
        for a in range(n):
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            for b in range(m):
                pab = P[a, b]
                acc0 += pab * H0[b]
                acc1 += pab * H1[b]
                acc2 += pab * H2[b]
            ph[a, 0] = acc0
            ph[a, 1] = acc1
            ph[a, 2] = acc2
        s00 = var
        s01 = 0.0
        s02 = 0.0
        s11 = var
        s12 = 0.0
        s22 = var
        e0 = r0
        e1 = r1
        e2 = r2
        for a in range(m):
            h0 = H0[a]
            h1 = H1[a]
            h2 = H2[a]
            s00 += h0 * ph[a, 0]
            s01 += h0 * ph[a, 1]
            s02 += h0 * ph[a, 2]
            s11 += h1 * ph[a, 1]
            s12 += h1 * ph[a, 2]
            s22 += h2 * ph[a, 2]
            e0 -= h0 * dx[a]
            e1 -= h1 * dx[a]
            e2 -= h2 * dx[a]
        ok, i00, i01, i02, i11, i12, i22 = sym3_inverse(s00, s01, s02, s11, s12, s22)
        if not ok:
            return False
        for a in range(n):
            p0 = ph[a, 0]
            p1 = ph[a, 1]
            p2 = ph[a, 2]
            k0 = p0 * i00 + p1 * i01 + p2 * i02
            k1 = p0 * i01 + p1 * i11 + p2 * i12
            k2 = p0 * i02 + p1 * i12 + p2 * i22
            dx[a] += k0 * e0 + k1 * e1 + k2 * e2
            # P[a, b] -= K[a, :] . ph[b, :]; the upper triangle, mirrored afterwards
            for b in range(a, n):
                P[a, b] -= k0 * ph[b, 0] + k1 * ph[b, 1] + k2 * ph[b, 2]
        for a in range(n):
            for b in range(a):
                P[a, b] = P[b, a]
        return True

    return update


block3_update = make_block3(3, 3)
"""Block update for 3 states (the Euler EKF); see ``make_block3``."""
block3_update7 = make_block3(7, 4)
"""Block update for 7 states (the quaternion EKF with bias)."""


# ------------------------------------------------------------------------------------------
# per-sample steps shared by the filter kernels
# ------------------------------------------------------------------------------------------
Sample = namedtuple(
    "Sample",
    ["dt", "a0", "a1", "a2", "an", "acc_fin", "acc_dev", "g0", "g1", "g2", "gyr_fin",
     "m0", "m1", "m2", "mag_fin"],
)
"""One sample as a kernel sees it (see :func:`read_sample`)."""


@numba.njit(inline="always", **JIT)
def read_sample(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, i: int, has_gyr: bool,
    has_mag: bool, prm: FloatArray, aux: FloatArray,
) -> Any:
    """Advance the clock to sample ``i`` and check its sensor values.

    Returns a :data:`Sample`: ``dt`` since the previous sample (0 at the first one), the
    specific force, its norm ``an`` and ``acc_dev = | |a| - g |`` (inf when unusable), the gyro
    and magnetometer values, and per sensor whether the value is usable (finite, inside the
    measurement range). Counts the sample and, when a sensor value is not usable, a bad sample.
    """
    ti = t[i]
    tp = aux[AUX_T_PREV]
    dt = ti - tp if math.isfinite(tp) else 0.0
    aux[AUX_T_PREV] = ti
    aux[AUX_N] += 1.0
    a0 = acc[i, 0]
    a1 = acc[i, 1]
    a2 = acc[i, 2]
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    acc_fin = math.isfinite(an) and 1e-6 < an < prm[PRM_ACC_RANGE]
    g0 = gyr[i, 0]
    g1 = gyr[i, 1]
    g2 = gyr[i, 2]
    gyr_fin = has_gyr and gyro_ok(prm, g0, g1, g2)
    m0 = mag[i, 0]
    m1 = mag[i, 1]
    m2 = mag[i, 2]
    mag_fin = has_mag and finite3(m0, m1, m2)
    if (not acc_fin) or (has_gyr and not gyr_fin) or (has_mag and not mag_fin):
        aux[AUX_N_BAD] += 1.0
    acc_dev = abs(an - prm[PRM_GRAVITY]) if acc_fin else math.inf
    return Sample(dt, a0, a1, a2, an, acc_fin, acc_dev, g0, g1, g2, gyr_fin, m0, m1, m2,
                  mag_fin)


@numba.njit(**JIT)
def try_init(aux: FloatArray, prm: FloatArray, s: Any, has_mag: bool
             ) -> tuple[int, float, float, float, float]:
    """Initialise the shared bookkeeping at the first static-looking sample (eq. 4.13).

    Returns the flags of the sample (0 when it does not pass the accelerometer gate: the
    filter stays uninitialised, the rejections are counted) and the initial attitude ``q``.
    """
    if not (s.acc_fin and s.acc_dev < prm[PRM_ACC_GATE]):
        aux[AUX_N_ACC_REJ] += 1.0
        if has_mag:
            aux[AUX_N_MAG_REJ] += 1.0
        return 0, 1.0, 0.0, 0.0, 0.0
    w, x, y, z = init_attitude(prm, s.a0, s.a1, s.a2, s.m0, s.m1, s.m2, s.mag_fin)
    aux[AUX_INIT] = 1.0
    init_rest(aux, s.g0, s.g1, s.g2, s.a0, s.a1, s.a2, s.gyr_fin)
    flags = FLAG_VALID | FLAG_ACC
    if s.mag_fin:
        ux, uy, uz = rot_t(w, x, y, z, 0.0, 0.0, 1.0)
        if mag_gate(aux, prm, s.m0, s.m1, s.m2, ux, uy, uz, 0.0):
            flags |= FLAG_MAG
        else:
            aux[AUX_N_MAG_REJ] += 1.0
    elif has_mag:
        aux[AUX_N_MAG_REJ] += 1.0
    return flags, w, x, y, z


@numba.njit(inline="always", **JIT)
def gyro_step(aux: FloatArray, prm: FloatArray, s: Any, has_gyr: bool) -> int:
    """Decide whether the gyro sample is integrated; rest detection and bias at rest.

    Returns ``FLAG_GYR`` (with ``FLAG_REST`` at rest) when the sample is usable and the gap is
    at most ``PRM_MAX_DT``; else 0 (counted as not integrated when a gyro exists).
    """
    flags = 0
    if s.gyr_fin and 0.0 < s.dt <= prm[PRM_MAX_DT]:
        flags = FLAG_GYR
        if s.acc_fin and rest_and_bias(aux, prm, s.g0, s.g1, s.g2, s.a0, s.a1, s.a2, s.dt):
            flags |= FLAG_REST
    elif has_gyr:
        aux[AUX_N_GYR_REJ] += 1.0
    return flags


@numba.njit(inline="always", **JIT)
def dynamic_acc_var(aux: FloatArray, s: Any, w: float, x: float, y: float, z: float,
                    tau_s: float) -> float:
    """Running per-axis variance of the body's acceleration, (m/s^2)^2.

    The specific force is rotated into ENU with the predicted attitude ``q``, so that turning
    the device does not count as motion; its exponentially weighted mean and variance (time
    constant ``tau_s``) are kept in ``aux``: with ``k = dt / (tau_s + dt)`` and the deviation
    ``d`` from the previous mean, ``mean += k d`` and ``var = (1 - k) (var + k |d|^2 / 3)``.
    Call only with a usable accelerometer sample.
    """
    n0, n1, n2 = rot(w, x, y, z, s.a0, s.a1, s.a2)
    if not math.isfinite(aux[AUX_DYN_MEAN]):
        aux[AUX_DYN_MEAN] = n0
        aux[AUX_DYN_MEAN + 1] = n1
        aux[AUX_DYN_MEAN + 2] = n2
        aux[AUX_DYN_VAR] = 0.0
        return 0.0
    d0 = n0 - aux[AUX_DYN_MEAN]
    d1 = n1 - aux[AUX_DYN_MEAN + 1]
    d2 = n2 - aux[AUX_DYN_MEAN + 2]
    k = s.dt / (tau_s + s.dt) if s.dt > 0.0 else 0.0
    aux[AUX_DYN_MEAN] += k * d0
    aux[AUX_DYN_MEAN + 1] += k * d1
    aux[AUX_DYN_MEAN + 2] += k * d2
    var = (1.0 - k) * (aux[AUX_DYN_VAR] + k * (d0 * d0 + d1 * d1 + d2 * d2) / 3.0)
    aux[AUX_DYN_VAR] = var
    return var


@numba.njit(inline="always", **JIT)
def unbiased_rate(aux: FloatArray, s: Any) -> tuple[float, float, float]:
    """The gyro rate minus the current bias estimate, rad/s."""
    return s.g0 - aux[AUX_BIAS], s.g1 - aux[AUX_BIAS + 1], s.g2 - aux[AUX_BIAS + 2]


@numba.njit(inline="always", **JIT)
def count_used(aux: FloatArray, flags: int, use_a: bool, use_m: bool, has_mag: bool) -> int:
    """Flags of the static sensors that corrected the attitude; count the others."""
    if use_a:
        flags |= FLAG_ACC
    else:
        aux[AUX_N_ACC_REJ] += 1.0
    if use_m:
        flags |= FLAG_MAG
    elif has_mag:
        aux[AUX_N_MAG_REJ] += 1.0
    return flags


@numba.njit(inline="always", **JIT)
def horizontal_unit(
    m0: float, m1: float, m2: float, ux: float, uy: float, uz: float
) -> tuple[float, float, float, float]:
    """The field minus its component along the unit vertical ``u``, and its norm."""
    md = m0 * ux + m1 * uy + m2 * uz
    z0 = m0 - md * ux
    z1 = m1 - md * uy
    z2 = m2 - md * uz
    return z0, z1, z2, math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)


@numba.njit(inline="always", **JIT)
def write_q(out_q: FloatArray, i: int, w: float, x: float, y: float, z: float) -> None:
    """``out_q[i] = q``."""
    out_q[i, 0] = w
    out_q[i, 1] = x
    out_q[i, 2] = y
    out_q[i, 3] = z


@numba.njit(**JIT)
def write_uninit(out_q: FloatArray, out_var: FloatArray, out_flags: Any, i: int) -> None:
    """Output of a sample before initialisation: identity, variance pi^2 (when kept), no flags."""
    write_q(out_q, i, 1.0, 0.0, 0.0, 0.0)
    if out_var.shape[0] > i:
        out_var[i, 0] = math.pi ** 2
        out_var[i, 1] = math.pi ** 2
        out_var[i, 2] = math.pi ** 2
    out_flags[i] = 0


@numba.njit(inline="always", **JIT)
def update_finite(dx: FloatArray, P: FloatArray) -> bool:
    """The correction and the variances of an EKF update are all finite."""
    ok = True
    for r in range(dx.shape[0]):
        ok = ok and math.isfinite(dx[r]) and math.isfinite(P[r, r])
    return ok


@numba.njit(inline="always", **JIT)
def gyro_quat_step(
    w: float, x: float, y: float, z: float, wx: float, wy: float, wz: float, dt: float
) -> tuple[float, float, float, float]:
    """Gyro step of the attitude, normalised with ``w >= 0`` (Inderst eq. 4.10-4.12).

    ``exp(Omega dt) q = q * [cos(a), sin(a) w / |w|]`` with ``a = |w| dt / 2``.
    """
    c, sc = cos_sinc(0.5 * math.sqrt(wx * wx + wy * wy + wz * wz) * dt)
    sk = 0.5 * dt * sc
    w, x, y, z = qmul(w, x, y, z, c, sk * wx, sk * wy, sk * wz)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return w / n, x / n, y / n, z / n


@numba.njit(inline="always", **JIT)
def set_q(v: FloatArray, k: int, w: float, x: float, y: float, z: float) -> None:
    """``v[k:k + 4] = q`` (a quaternion inside a state vector)."""
    v[k] = w
    v[k + 1] = x
    v[k + 2] = y
    v[k + 3] = z
