"""State layout and per-sample steps shared by the attitude filters (gates, rest detection).

Every filter keeps three plain float64 arrays as its state: ``x`` (its own state vector),
``P`` (its covariance, or an empty array) and ``aux`` (the bookkeeping below, the same layout for
all filters). Parameters travel to the kernels as one float64 array; the indices of the shared
part are the ``PRM_*`` constants, the filter-specific part starts at :data:`PRM_SPECIFIC`.

Conventions (see :mod:`hrtls.frames`): quaternions ``[w, x, y, z]``, Hamilton product, ``q``
rotates device vectors into ENU; specific force at rest is ``+g`` on the navigation z axis.
Quaternion helpers are in :mod:`~hrtls.attitude._quaternion`, the EKF linear algebra in
:mod:`~hrtls.attitude._ekf_update`, the compile options in :mod:`~hrtls.attitude._jit`.
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any

import numpy as np

from hrtls.attitude._jit import JIT
from hrtls.attitude._quaternion import heading_from_mag, rot, rot_t, shortest_arc_to_up, write_q
from hrtls.frames import FloatArray
from hrtls.kernels import njit

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
# gates, rest detection and initialisation
# ------------------------------------------------------------------------------------------


@njit(inline="always", **JIT)
def finite3(v0: float, v1: float, v2: float) -> bool:
    """All three components finite."""
    return math.isfinite(v0) and math.isfinite(v1) and math.isfinite(v2)


@njit(inline="always", **JIT)
def gyro_ok(r: float, g0: float, g1: float, g2: float) -> bool:
    """Gyro sample finite and inside the measurement range ``r``, rad/s."""
    return finite3(g0, g1, g2) and abs(g0) < r and abs(g1) < r and abs(g2) < r


@njit(inline="always", **JIT)
def rest_and_bias(
    aux: FloatArray, prm: FloatArray, g0: float, g1: float, g2: float,
    a0: float, a1: float, a2: float, dt: float, active: bool = True,
) -> bool:
    """Rest detection and gyro-bias update at rest; returns True when at rest.

    Rest: the gyro rate stays within ``PRM_REST_GYR`` of its 0.5 s low-pass, the low-pass
    stays within ``2 PRM_REST_GYR`` of the current bias, and the specific force stays within
    ``PRM_REST_ACC`` of its low-pass and of g in norm, all for ``PRM_REST_S``. While at rest
    the bias follows the low-passed rate: a running mean from the start of the rest, then an
    exponential average with time constant ``PRM_BIAS_TAU_S``. Nothing changes unless
    ``active`` (then ``g`` and ``a`` may be anything); when active, ``g`` and ``a`` must be
    finite.
    """
    # arrays read first, written last and the call is unconditional (see read_sample)
    lp0, lp1, lp2 = aux[AUX_LP], aux[AUX_LP + 1], aux[AUX_LP + 2]
    al0, al1, al2 = aux[AUX_ALP], aux[AUX_ALP + 1], aux[AUX_ALP + 2]
    b0, b1, b2 = aux[AUX_BIAS], aux[AUX_BIAS + 1], aux[AUX_BIAS + 2]
    rest_t = aux[AUX_REST_T]
    thr = prm[PRM_REST_GYR]
    thr_a = prm[PRM_REST_ACC]
    gravity = prm[PRM_GRAVITY]
    rest_s = prm[PRM_REST_S]
    bias_est = prm[PRM_BIAS_EST] > 0.5
    bias_tau = prm[PRM_BIAS_TAU_S]
    k = dt / (0.5 + dt)
    n0 = lp0 + k * (g0 - lp0)
    n1 = lp1 + k * (g1 - lp1)
    n2 = lp2 + k * (g2 - lp2)
    c0 = al0 + k * (a0 - al0)
    c1 = al1 + k * (a1 - al1)
    c2 = al2 + k * (a2 - al2)
    d0 = g0 - n0
    d1 = g1 - n1
    d2 = g2 - n2
    e0 = n0 - b0
    e1 = n1 - b1
    e2 = n2 - b2
    f0 = a0 - c0
    f1 = a1 - c1
    f2 = a2 - c2
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    still = (d0 * d0 + d1 * d1 + d2 * d2 < thr * thr
             and e0 * e0 + e1 * e1 + e2 * e2 < 4.0 * thr * thr
             and f0 * f0 + f1 * f1 + f2 * f2 < thr_a * thr_a
             and abs(an - gravity) < thr_a)
    new_t = rest_t + dt if still else 0.0
    at_rest = active and still and new_t >= rest_s
    if at_rest and bias_est:
        # running mean over the rest so far, then exponential with PRM_BIAS_TAU_S
        kb = dt / min(bias_tau + dt, new_t - rest_s + dt)
        b0 += kb * e0
        b1 += kb * e1
        b2 += kb * e2
    if active:
        lp0, lp1, lp2, al0, al1, al2, rest_t = n0, n1, n2, c0, c1, c2, new_t
    aux[AUX_LP], aux[AUX_LP + 1], aux[AUX_LP + 2] = lp0, lp1, lp2
    aux[AUX_ALP], aux[AUX_ALP + 1], aux[AUX_ALP + 2] = al0, al1, al2
    aux[AUX_REST_T] = rest_t
    aux[AUX_BIAS], aux[AUX_BIAS + 1], aux[AUX_BIAS + 2] = b0, b1, b2
    return at_rest


@njit(**JIT)
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


@njit(inline="always", **JIT)
def first_field(aux: FloatArray, prm: FloatArray, n: float, dip: float) -> bool:
    """Learn the reference field (norm ``n``, uT, and ``dip``, rad) at its first sample.

    The given reference (``PRM_MAG_REF_*``) wins where it is finite; the candidate starts at
    the sample. Returns True when this was the first sample (nothing changes otherwise).
    """
    ref_n = prm[PRM_MAG_REF_N]  # read outside the branches (see read_sample)
    ref_dip = prm[PRM_MAG_REF_DIP]
    if aux[AUX_MREF_SET] > 0.5:
        return False
    aux[AUX_MREF_N] = ref_n if math.isfinite(ref_n) else n
    aux[AUX_MREF_DIP] = ref_dip if math.isfinite(ref_dip) else dip
    aux[AUX_MCAND_N] = n
    aux[AUX_MCAND_DIP] = dip
    aux[AUX_MCAND_T] = 0.0
    aux[AUX_MREF_SET] = 1.0
    return True


@njit(inline="always", **JIT)
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
    first_field(aux, prm, n, dip)
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


@njit(**JIT)
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


# ------------------------------------------------------------------------------------------
# per-sample steps shared by the filter kernels
# ------------------------------------------------------------------------------------------
Sample = namedtuple(
    "Sample",
    ["dt", "a0", "a1", "a2", "an", "acc_fin", "acc_dev", "g0", "g1", "g2", "gyr_fin",
     "m0", "m1", "m2", "mag_fin"],
)
"""One sample as a kernel sees it (see :func:`read_sample`)."""


@njit(inline="always", **JIT)
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
    # the arrays are read first and written last, outside any branch: an array used across
    # the branches of an inlined helper costs reference counting on every sample
    ti = t[i]
    tp = aux[AUX_T_PREV]
    a0 = acc[i, 0]
    a1 = acc[i, 1]
    a2 = acc[i, 2]
    g0 = gyr[i, 0]
    g1 = gyr[i, 1]
    g2 = gyr[i, 2]
    m0 = mag[i, 0]
    m1 = mag[i, 1]
    m2 = mag[i, 2]
    acc_range = prm[PRM_ACC_RANGE]
    gyr_range = prm[PRM_GYR_RANGE]
    gravity = prm[PRM_GRAVITY]
    n_bad = aux[AUX_N_BAD]
    dt = ti - tp if math.isfinite(tp) else 0.0
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    acc_fin = math.isfinite(an) and 1e-6 < an < acc_range
    gyr_fin = has_gyr and gyro_ok(gyr_range, g0, g1, g2)
    mag_fin = has_mag and finite3(m0, m1, m2)
    if (not acc_fin) or (has_gyr and not gyr_fin) or (has_mag and not mag_fin):
        n_bad += 1.0
    acc_dev = abs(an - gravity) if acc_fin else math.inf
    aux[AUX_T_PREV] = ti
    aux[AUX_N] += 1.0
    aux[AUX_N_BAD] = n_bad
    return Sample(dt, a0, a1, a2, an, acc_fin, acc_dev, g0, g1, g2, gyr_fin, m0, m1, m2,
                  mag_fin)


@njit(**JIT)
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


@njit(inline="always", **JIT)
def gyro_step(aux: FloatArray, prm: FloatArray, s: Any, has_gyr: bool) -> int:
    """Decide whether the gyro sample is integrated; rest detection and bias at rest.

    Returns ``FLAG_GYR`` (with ``FLAG_REST`` at rest) when the sample is usable and the gap is
    at most ``PRM_MAX_DT``; else 0 (counted as not integrated when a gyro exists).
    """
    max_dt = prm[PRM_MAX_DT]  # arrays outside the conditions (see read_sample)
    use = s.gyr_fin and 0.0 < s.dt <= max_dt
    rest = rest_and_bias(aux, prm, s.g0, s.g1, s.g2, s.a0, s.a1, s.a2, s.dt, use and s.acc_fin)
    aux[AUX_N_GYR_REJ] += 1.0 if has_gyr and not use else 0.0
    return (FLAG_GYR if use else 0) | (FLAG_REST if rest else 0)


@njit(inline="always", **JIT)
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


@njit(inline="always", **JIT)
def unbiased_rate(aux: FloatArray, s: Any) -> tuple[float, float, float]:
    """The gyro rate minus the current bias estimate, rad/s."""
    return s.g0 - aux[AUX_BIAS], s.g1 - aux[AUX_BIAS + 1], s.g2 - aux[AUX_BIAS + 2]


@njit(inline="always", **JIT)
def count_used(aux: FloatArray, flags: int, use_a: bool, use_m: bool, has_mag: bool) -> int:
    """Flags of the static sensors that corrected the attitude; count the others."""
    # written outside the branches (see read_sample)
    aux[AUX_N_ACC_REJ] += 0.0 if use_a else 1.0
    aux[AUX_N_MAG_REJ] += 1.0 if has_mag and not use_m else 0.0
    return flags | (FLAG_ACC if use_a else 0) | (FLAG_MAG if use_m else 0)


@njit(inline="always", **JIT)
def horizontal_unit(
    m0: float, m1: float, m2: float, ux: float, uy: float, uz: float
) -> tuple[float, float, float, float]:
    """The field minus its component along the unit vertical ``u``, and its norm."""
    md = m0 * ux + m1 * uy + m2 * uz
    z0 = m0 - md * ux
    z1 = m1 - md * uy
    z2 = m2 - md * uz
    return z0, z1, z2, math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)


@njit(**JIT)
def write_uninit(out_q: FloatArray, out_var: FloatArray, out_flags: Any, i: int) -> None:
    """Output of a sample before initialisation: identity, variance pi^2 (when kept), no flags."""
    write_q(out_q, i, 1.0, 0.0, 0.0, 0.0)
    if out_var.shape[0] > i:
        out_var[i, 0] = math.pi ** 2
        out_var[i, 1] = math.pi ** 2
        out_var[i, 2] = math.pi ** 2
    out_flags[i] = 0
