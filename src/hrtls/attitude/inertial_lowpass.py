"""Attitude from a low-pass filtered specific force in an almost-inertial frame (after VQF).

Our implementation of the ideas of Laidig & Seel 2023 ("VQF: Highly accurate IMU orientation
estimation with bias estimation and magnetic disturbance rejection", Information Fusion 91),
written from the paper's equations; numbers in brackets refer to its sections. Frames: ``d``
device, ``I`` the almost-inertial frame of the pure gyro integration, ``E'`` the inclination-
corrected frame (vertical right, heading free), ``n`` ENU.

1. Strapdown [3.1]: ``q_gyr <- q_gyr * exp((w - b) dt / 2)``, the bias-corrected rate
   integrated without any correction; ``q_gyr`` is ``q_Id``.
2. Inclination [3.2]: the specific force is rotated into ``I``, ``a_I = R(q_gyr) a``, and
   low-pass filtered there (second-order Butterworth, cut-off ``sqrt(2) / (2 pi tau_acc)``,
   bilinear transform). In ``I`` the body's accelerations integrate to velocity changes, which
   are bounded, so the low-pass keeps gravity and removes them: no gate on ``| |a| - g |`` is
   needed. The filtered vector in ``E'``, ``e = R(q_acc) lp(a_I) / |.|``, is turned onto the
   vertical by the shortest arc ``q_c = [c, e_y / 2c, -e_x / 2c, 0]`` with
   ``c = sqrt((1 + e_z) / 2)``, and ``q_acc <- q_c * q_acc`` (``q_acc`` is ``q_E'I``). The
   inclination is ``q_6 = q_acc * q_gyr``.
3. Heading [3.3]: ``delta`` rotates ``E'`` about the vertical; ``q = R_z(delta) * q_6``. The
   field in ``E'`` has azimuth ``phi = atan2(m_y, m_x)``; north (+y) needs ``delta* = pi/2 - phi``
   and ``delta <- delta + k wrap(delta* - delta)``, ``k = 1 - exp(-dt / tau_mag)``. The first
   corrections average (``k = max(k, 1 / n)`` for the ``n``-th), so the heading converges at once.
4. Gyro bias [3.4]: a 3-state Kalman filter on ``b`` (covariance in ``P``). In motion the
   inclination correction rate ``w_c`` (rotation vector of ``q_c`` over ``dt``, in ``E'``) is a
   pseudo-measurement: the strapdown error drifts at ``R_6 (b_true - b)``, and after the low-pass
   ``-w_c + lp(R_6 b) = lp(R_6) b_true``; the horizontal rows are measured with variance
   ``bias_sigma_motion^2``, the vertical row (unobservable from gravity) weakly, with the variance
   divided by ``bias_vertical_forgetting``. At rest (the shared detector,
   :func:`hrtls.attitude._kernels.rest_and_bias` without its own bias update) the low-passed
   rate measures ``b`` with variance ``bias_sigma_rest^2``. The variance grows by
   ``v = (0.1 deg/s)^2 dt / bias_forgetting_s`` per sample up to ``bias_sigma_init^2``;
   ``|b|`` is clipped per axis to ``bias_clip_rad_s``. A measurement of nominal standard
   deviation ``sigma`` gets the variance ``w = sigma^4 / v + sigma^2``, for which the
   steady-state variance of a bias measured every sample is ``sigma^2`` at any sample rate.
5. Magnetic disturbances [3.5]: the norm and dip of the field, low-passed with
   ``mag_current_tau_s``, are compared with a reference (first field seen, or given); outside
   ``mag_norm_gate_uT`` / ``mag_dip_gate_rad`` the field is disturbed and the heading correction
   stops, for at most ``mag_max_rejection_s`` (after that it runs at ``k / mag_rejection_factor``;
   the time budget refills at ``mag_rejection_factor`` times real time while undisturbed). An
   undisturbed field (for ``mag_min_undisturbed_s``) slowly updates the reference
   (``mag_ref_tau_s``); a different field that stays stable while the device turns faster than
   ``mag_new_min_rate_rad_s`` becomes the reference after ``mag_new_field_s`` (after
   ``mag_new_first_s`` for the first reference, which was only the first sample).

Variances (our addition, for the tracker): the filter has fixed gains, so roll, pitch and
heading are each treated as a scalar error that relaxes towards the error of its reference with
the filter's gain and grows with ``attitude_walk_rad_s`` between corrections:
``var <- (1 - k) var + k sigma_ref^2 + walk^2 dt`` (``k`` the gain actually used; the references'
errors are slowly varying, not white, so they do not average out). ``var_rpy`` holds
``(var_tilt, var_tilt, var_heading)``; ``extra['mag_disturbed']`` is 1 while rejected.

Shared parameters used here: gravity, ranges, ``max_dt_s`` (a longer gap restarts the
low-pass), the rest detector, ``estimate_bias``, initial bias, the magnetometer gates named above
and ``acc_gate_m_s2`` for the first sample only. ``mag_jump_gate_uT`` and ``bias_tau_s`` are not
used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _kernels as K
from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.errors import InputError
from hrtls.frames import FloatArray

__all__ = ["InertialLowpass", "InertialLowpassParams"]

# ---- parameter layout (after the shared part)
_TAU_ACC = K.PRM_SPECIFIC
_TAU_MAG = K.PRM_SPECIFIC + 1
_BIAS_EST = K.PRM_SPECIFIC + 2
_B_SIG0 = K.PRM_SPECIFIC + 3
_B_FORGET = K.PRM_SPECIFIC + 4
_B_CLIP = K.PRM_SPECIFIC + 5
_B_SIG_MOT = K.PRM_SPECIFIC + 6
_B_VERT = K.PRM_SPECIFIC + 7
_B_SIG_REST = K.PRM_SPECIFIC + 8
_M_CUR_TAU = K.PRM_SPECIFIC + 9
_M_REF_TAU = K.PRM_SPECIFIC + 10
_M_NEW_FIRST = K.PRM_SPECIFIC + 11
_M_NEW_RATE = K.PRM_SPECIFIC + 12
_M_UNDIST = K.PRM_SPECIFIC + 13
_M_MAX_REJ = K.PRM_SPECIFIC + 14
_M_REJ_FACTOR = K.PRM_SPECIFIC + 15
_TILT_SIG = K.PRM_SPECIFIC + 16
_HEAD_SIG = K.PRM_SPECIFIC + 17
_WALK = K.PRM_SPECIFIC + 18

_BIAS_GROWTH_RAD2_S2 = float(np.deg2rad(0.1)) ** 2  # bias variance growth per bias_forgetting_s

# ---- state layout
_QG = 0  # 0..3 q_gyr (d -> I)
_QA = 4  # 4..7 q_acc (I -> E')
_HC = 8  # cos(delta / 2) of the heading correction delta about the vertical
_ALP = 9  # 9..14 biquad state of lp(a_I), two per axis
_RLP = 15  # 15..32 biquad state of lp(R_6), row-major, two per entry
_RBLP = 33  # 33..38 biquad state of lp(R_6 b)
_DT = 39  # sample period the coefficients below belong to, s (0: none yet)
_CB0 = 40  # biquad b0, b1 (= 2 b0), b2 (= b0), a1, a2 at 40, 41, 42
_CA1 = 41
_CA2 = 42
_KACC = 43  # 1 - exp(-dt / tau_acc)
_KMAG = 44  # 1 - exp(-dt / tau_mag)
_KCUR = 45  # gain of the norm/dip low-pass
_KREF = 46  # gain of the reference update
_MN = 47  # low-passed field norm, uT
_MDIP = 48  # low-passed dip, rad
_MUND_T = 49  # time undisturbed, s
_MREJ_T = 50  # rejection time used, s
_MDIST = 51  # 1.0 while the field is disturbed
_MINIT = 52  # count of the averaging first heading corrections (0: done)
_MFIRST = 53  # 1.0 while the reference is only the first sample
_VTILT = 54  # roll/pitch variance, rad^2
_VHEAD = 55  # heading variance, rad^2
_LPOK = 56  # 1.0 once the low-passes were started on a sample
_HS = 57  # sin(delta / 2)
_NX = 58


@dataclass(frozen=True, kw_only=True)
class InertialLowpassParams(CommonParams):
    """Parameters of :class:`InertialLowpass` (see the module text for the equations).

    Attributes
    ----------
    tau_acc_s:
        Time constant of the low-pass of the specific force in the inertial frame, s.
    tau_mag_s:
        Time constant of the heading correction, s.
    bias_sigma_init_rad_s:
        Initial standard deviation (and upper bound) of the gyro bias estimate, rad/s.
    bias_forgetting_s:
        Time over which the bias variance regrows by ``(0.1 deg/s)^2``, s.
    bias_clip_rad_s:
        Bound on each bias component, rad/s.
    bias_sigma_motion_rad_s:
        Standard deviation of the in-motion pseudo-measurement (horizontal rows), rad/s.
    bias_vertical_forgetting:
        Weight of the vertical row relative to the horizontal ones (its variance is divided
        by this), in (0, 1].
    bias_sigma_rest_rad_s:
        Standard deviation of the rest measurement of the bias, rad/s.
    mag_current_tau_s:
        Time constant of the low-pass of the field norm and dip, s.
    mag_ref_tau_s:
        Time constant of the reference (and candidate) norm and dip updates, s.
    mag_new_first_s:
        Stable time after which a new field replaces a reference that is only the first
        sample, s.
    mag_new_min_rate_rad_s:
        A candidate field gains stable time only while the device turns at least this fast.
    mag_min_undisturbed_s:
        A field must match the reference this long before it counts as undisturbed, s.
    mag_max_rejection_s:
        Longest continuous rejection of a disturbed field, s.
    mag_rejection_factor:
        Gain divisor past the rejection time; also the refill rate of the rejection budget.
    tilt_sigma_rad, heading_sigma_rad:
        Error of the inclination and heading references (for ``var_rpy``), rad.
    attitude_walk_rad_s:
        Growth of the attitude error between corrections (gyro noise and bias), rad/sqrt(s).
    """

    mag_norm_gate_uT: float = 5.0
    mag_dip_gate_rad: float = float(np.deg2rad(10.0))
    tau_acc_s: float = 3.0
    tau_mag_s: float = 9.0
    bias_sigma_init_rad_s: float = float(np.deg2rad(0.5))
    bias_forgetting_s: float = 100.0
    bias_clip_rad_s: float = float(np.deg2rad(2.0))
    bias_sigma_motion_rad_s: float = float(np.deg2rad(0.1))
    bias_vertical_forgetting: float = 1e-4
    bias_sigma_rest_rad_s: float = float(np.deg2rad(0.03))
    mag_current_tau_s: float = 0.05
    mag_ref_tau_s: float = 20.0
    mag_new_first_s: float = 5.0
    mag_new_min_rate_rad_s: float = float(np.deg2rad(20.0))
    mag_min_undisturbed_s: float = 0.5
    mag_max_rejection_s: float = 60.0
    mag_rejection_factor: float = 2.0
    tilt_sigma_rad: float = float(np.deg2rad(1.0))
    heading_sigma_rad: float = float(np.deg2rad(5.0))
    attitude_walk_rad_s: float = float(np.deg2rad(0.1))

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        self._require_positive(
            ("tau_acc_s", "tau_mag_s", "bias_sigma_init_rad_s", "bias_forgetting_s",
             "bias_clip_rad_s", "bias_sigma_motion_rad_s", "bias_vertical_forgetting",
             "bias_sigma_rest_rad_s", "mag_current_tau_s", "mag_ref_tau_s", "mag_new_first_s",
             "mag_max_rejection_s", "mag_rejection_factor", "tilt_sigma_rad",
             "heading_sigma_rad", "attitude_walk_rad_s"),
            inf_ok=("tau_mag_s", "bias_forgetting_s", "mag_max_rejection_s"))
        for name in ("mag_new_min_rate_rad_s", "mag_min_undisturbed_s"):
            value = getattr(self, name)
            if not value >= 0.0:
                raise InputError(f"{name} = {value}", where=type(self).__name__,
                                 expected="a number >= 0")
        if not self.bias_vertical_forgetting <= 1.0:
            raise InputError(f"bias_vertical_forgetting = {self.bias_vertical_forgetting}",
                             where=type(self).__name__, expected="a number in (0, 1]")

    def common_array(self) -> FloatArray:
        """Shared part; the rest detector runs without its own bias update (``_BIAS_EST``)."""
        p = CommonParams.common_array(self)
        p[K.PRM_BIAS_EST] = 0.0
        return p

    def specific_values(self) -> tuple[float, ...]:
        """Kernel parameters ``_TAU_ACC`` .. ``_WALK``."""
        return (self.tau_acc_s, self.tau_mag_s, 1.0 if self.estimate_bias else 0.0,
                self.bias_sigma_init_rad_s, self.bias_forgetting_s, self.bias_clip_rad_s,
                self.bias_sigma_motion_rad_s, self.bias_vertical_forgetting,
                self.bias_sigma_rest_rad_s, self.mag_current_tau_s, self.mag_ref_tau_s,
                self.mag_new_first_s, self.mag_new_min_rate_rad_s, self.mag_min_undisturbed_s,
                self.mag_max_rejection_s, self.mag_rejection_factor, self.tilt_sigma_rad,
                self.heading_sigma_rad, self.attitude_walk_rad_s)


# ------------------------------------------------------------------------------------------
# compiled parts
# ------------------------------------------------------------------------------------------
@numba.njit(inline="always", **K.JIT)
def _biquad(x: FloatArray, k: int, u: float, b0: float, a1: float, a2: float) -> float:
    """One step of the Butterworth low-pass (transposed direct form II, ``b = b0 [1, 2, 1]``)."""
    y = b0 * u + x[k]
    x[k] = 2.0 * b0 * u - a1 * y + x[k + 1]
    x[k + 1] = b0 * u - a2 * y
    return y


@numba.njit(inline="always", **K.JIT)
def _biquad_steady(x: FloatArray, k: int, u: float, b0: float, a1: float, a2: float) -> None:
    """The state of a low-pass that has seen the constant ``u`` forever (output ``u``)."""
    x[k + 1] = (b0 - a2) * u
    x[k] = (3.0 * b0 - a1 - a2) * u


@numba.njit(**K.JIT)
def _set_gains(x: FloatArray, prm: FloatArray, dt: float) -> None:
    """Gains for the sample period ``dt``.

    Butterworth by the bilinear transform with pre-warping, ``K = tan(pi f_c dt)``,
    ``b0 = K^2 / (1 + sqrt2 K + K^2)``, ``a1 = 2 (K^2 - 1) / (.)``,
    ``a2 = (1 - sqrt2 K + K^2) / (.)``; first-order gains ``1 - exp(-dt / tau)``.
    """
    fc = math.sqrt(2.0) / (2.0 * math.pi * prm[_TAU_ACC])
    kk = math.tan(min(math.pi * fc * dt, 1.2))
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * kk + kk * kk)
    x[_CB0] = kk * kk * nrm
    x[_CA1] = 2.0 * (kk * kk - 1.0) * nrm
    x[_CA2] = (1.0 - math.sqrt(2.0) * kk + kk * kk) * nrm
    x[_KACC] = 1.0 - math.exp(-dt / prm[_TAU_ACC])
    x[_KMAG] = 1.0 - math.exp(-dt / prm[_TAU_MAG])
    x[_KCUR] = 1.0 - math.exp(-dt / prm[_M_CUR_TAU])
    x[_KREF] = 1.0 - math.exp(-dt / prm[_M_REF_TAU])
    x[_DT] = dt


@numba.njit(inline="always", **K.JIT)
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


@numba.njit(**K.JIT)
def _restart_lowpass(x: FloatArray, aux: FloatArray, a_i: tuple[float, float, float],
                     rr: FloatArray) -> None:
    """Low-pass states at rest on the current ``a_I``, ``R_6`` (in ``rr``) and ``R_6 b``."""
    b0 = x[_CB0]
    a1 = x[_CA1]
    a2 = x[_CA2]
    for c in range(3):
        _biquad_steady(x, _ALP + 2 * c, a_i[c], b0, a1, a2)
    for r in range(9):
        _biquad_steady(x, _RLP + 2 * r, rr[r], b0, a1, a2)
    for r in range(3):
        rb = (rr[3 * r] * aux[K.AUX_BIAS] + rr[3 * r + 1] * aux[K.AUX_BIAS + 1]
              + rr[3 * r + 2] * aux[K.AUX_BIAS + 2])
        _biquad_steady(x, _RBLP + 2 * r, rb, b0, a1, a2)


@numba.njit(inline="always", **K.JIT)
def _steady_noise(var: float, growth: float) -> float:
    """Measurement variance ``w = var^2 / v + var`` whose steady-state estimate variance is ``var``.

    For a scalar random walk with per-sample growth ``v`` measured every sample with variance
    ``w``, the a-priori variance ``p`` solves ``p^2 = v (p + w)``; the a-posteriori one,
    ``p w / (p + w)``, equals ``var`` for this ``w`` [3.4].
    """
    return var * var / max(growth, 1e-300) + var


@numba.njit(inline="always", **K.JIT)
def _bias_update(P: FloatArray, aux: FloatArray, H: FloatArray, y: FloatArray,
                 wv: FloatArray, clip: float, M: FloatArray, k: FloatArray) -> None:
    """Kalman update of the bias, ``b`` clipped.

    ``S = H P H^T + diag(wv)``, ``K = P H^T S^-1``, ``b += K y``, ``P -= K H P`` (``H``
    row-major 3 x 3, ``M`` and ``k`` work space).
    """
    for a in range(3):
        for r in range(3):
            M[a, r] = P[a, 0] * H[3 * r] + P[a, 1] * H[3 * r + 1] + P[a, 2] * H[3 * r + 2]
    s00 = H[0] * M[0, 0] + H[1] * M[1, 0] + H[2] * M[2, 0] + wv[0]
    s01 = H[0] * M[0, 1] + H[1] * M[1, 1] + H[2] * M[2, 1]
    s02 = H[0] * M[0, 2] + H[1] * M[1, 2] + H[2] * M[2, 2]
    s11 = H[3] * M[0, 1] + H[4] * M[1, 1] + H[5] * M[2, 1] + wv[1]
    s12 = H[3] * M[0, 2] + H[4] * M[1, 2] + H[5] * M[2, 2]
    s22 = H[6] * M[0, 2] + H[7] * M[1, 2] + H[8] * M[2, 2] + wv[2]
    ok, i00, i01, i02, i11, i12, i22 = K.sym3_inverse(s00, s01, s02, s11, s12, s22)
    if not ok:
        return
    for a in range(3):
        m0 = M[a, 0]
        m1 = M[a, 1]
        m2 = M[a, 2]
        k[a, 0] = m0 * i00 + m1 * i01 + m2 * i02
        k[a, 1] = m0 * i01 + m1 * i11 + m2 * i12
        k[a, 2] = m0 * i02 + m1 * i12 + m2 * i22
    for a in range(3):
        db = k[a, 0] * y[0] + k[a, 1] * y[1] + k[a, 2] * y[2]
        if math.isfinite(db):
            aux[K.AUX_BIAS + a] = min(clip, max(-clip, aux[K.AUX_BIAS + a] + db))
    for a in range(3):
        for b in range(a, 3):
            v = P[a, b] - (k[a, 0] * M[b, 0] + k[a, 1] * M[b, 1] + k[a, 2] * M[b, 2])
            P[a, b] = v
            P[b, a] = v


@numba.njit(**K.JIT)
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
    yv = np.empty(3)
    wv = np.empty(3)
    M = np.empty((3, 3))
    kw = np.empty((3, 3))
    eye = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    sig0 = prm[_B_SIG0]
    p_max = sig0 * sig0
    p_grow = _BIAS_GROWTH_RAD2_S2 / prm[_B_FORGET]
    clip = prm[_B_CLIP]
    walk2 = prm[_WALK] ** 2
    r_tilt = prm[_TILT_SIG] ** 2
    r_head = prm[_HEAD_SIG] ** 2
    gn = prm[K.PRM_MAG_NORM_GATE]
    gd = prm[K.PRM_MAG_DIP_GATE]
    bias_on = prm[_BIAS_EST] > 0.5
    for i in range(n):
        s = K.read_sample(t, acc, gyr, mag, i, has_gyr, has_mag, prm, aux)
        dt = s.dt
        if aux[K.AUX_INIT] < 0.5:
            flags, w, qx, qy, qz = K.try_init(aux, prm, s, has_mag)
            if flags == 0:
                K.write_uninit(out_q, out_var, out_flags, i)
                out_extra[i, 0] = 0.0
                continue
            K.set_q(x, _QG, w, qx, qy, qz)
            K.set_q(x, _QA, 1.0, 0.0, 0.0, 0.0)
            x[_HC] = 1.0
            x[_HS] = 0.0
            x[_DT] = 0.0
            x[_LPOK] = 0.0
            mag0 = (flags & K.FLAG_MAG) != 0
            x[_MN] = aux[K.AUX_MREF_N]
            x[_MDIP] = aux[K.AUX_MREF_DIP]
            x[_MUND_T] = 0.0
            x[_MREJ_T] = 0.0
            x[_MDIST] = 0.0
            x[_MINIT] = 2.0 if mag0 else 1.0
            x[_MFIRST] = 0.0 if (math.isfinite(prm[K.PRM_MAG_REF_N])
                                 and math.isfinite(prm[K.PRM_MAG_REF_DIP])) else 1.0
            x[_VTILT] = r_tilt
            x[_VHEAD] = r_head if mag0 else math.pi ** 2
            for a in range(3):
                for b in range(3):
                    P[a, b] = p_max if a == b else 0.0
            K.write_q(out_q, i, w, qx, qy, qz)
            out_var[i, 0] = x[_VTILT]
            out_var[i, 1] = x[_VTILT]
            out_var[i, 2] = x[_VHEAD]
            out_flags[i] = flags
            out_extra[i, 0] = 0.0
            continue
        flags = K.FLAG_VALID
        gw = x[_QG]
        gx = x[_QG + 1]
        gy = x[_QG + 2]
        gz = x[_QG + 3]
        aw = x[_QA]
        ax = x[_QA + 1]
        ay = x[_QA + 2]
        az = x[_QA + 3]
        # ---- 1. strapdown integration [3.1]
        gflags = K.gyro_step(aux, prm, s, has_gyr)
        rate = 0.0
        if gflags:
            flags |= gflags
            wx, wy, wz = K.unbiased_rate(aux, s)
            rate = math.sqrt(wx * wx + wy * wy + wz * wz)
            gw, gx, gy, gz = K.gyro_quat_step(gw, gx, gy, gz, wx, wy, wz, dt)
        restart = x[_LPOK] < 0.5 or dt > prm[K.PRM_MAX_DT]  # not started yet, or a gap
        if abs(dt - x[_DT]) > 0.01 * x[_DT]:
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
            a_i = K.rot(gw, gx, gy, gz, s.a0, s.a1, s.a2)
            sw, sx, sy, sz = K.qmul(aw, ax, ay, az, gw, gx, gy, gz)
            _rotation_matrix(sw, sx, sy, sz, rr)
            b0 = x[_CB0]
            a1 = x[_CA1]
            a2 = x[_CA2]
            if restart:
                _restart_lowpass(x, aux, a_i, rr)
                x[_LPOK] = 1.0
            l0 = _biquad(x, _ALP, a_i[0], b0, a1, a2)
            l1 = _biquad(x, _ALP + 2, a_i[1], b0, a1, a2)
            l2 = _biquad(x, _ALP + 4, a_i[2], b0, a1, a2)
            e0, e1, e2 = K.rot(aw, ax, ay, az, l0, l1, l2)
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
                aw, ax, ay, az = K.qmul(cw, cx, cy, 0.0, aw, ax, ay, az)
                an = math.sqrt(aw * aw + ax * ax + ay * ay + az * az)
                aw /= an
                ax /= an
                ay /= an
                az /= an
                wc0 = 2.0 * cx / dt
                wc1 = 2.0 * cy / dt
                k_tilt = x[_KACC]
            else:
                use_a = False
            # ---- 4. gyro bias [3.4]: lp(R_6), lp(R_6 b) and the pseudo-measurement
            bx0 = aux[K.AUX_BIAS]
            bx1 = aux[K.AUX_BIAS + 1]
            bx2 = aux[K.AUX_BIAS + 2]
            for r in range(9):
                hh[r] = _biquad(x, _RLP + 2 * r, rr[r], b0, a1, a2)
            lrb0 = _biquad(x, _RBLP, rr[0] * bx0 + rr[1] * bx1 + rr[2] * bx2, b0, a1, a2)
            lrb1 = _biquad(x, _RBLP + 2, rr[3] * bx0 + rr[4] * bx1 + rr[5] * bx2, b0, a1, a2)
            lrb2 = _biquad(x, _RBLP + 4, rr[6] * bx0 + rr[7] * bx1 + rr[8] * bx2, b0, a1, a2)
            if bias_on and (gflags & K.FLAG_GYR):
                if gflags & K.FLAG_REST:
                    yv[0] = aux[K.AUX_LP] - bx0
                    yv[1] = aux[K.AUX_LP + 1] - bx1
                    yv[2] = aux[K.AUX_LP + 2] - bx2
                    wr = _steady_noise(prm[_B_SIG_REST] ** 2, p_grow * dt)
                    wv[0] = wr
                    wv[1] = wr
                    wv[2] = wr
                    _bias_update(P, aux, eye, yv, wv, clip, M, kw)
                elif use_a:
                    yv[0] = -wc0 + lrb0 - (hh[0] * bx0 + hh[1] * bx1 + hh[2] * bx2)
                    yv[1] = -wc1 + lrb1 - (hh[3] * bx0 + hh[4] * bx1 + hh[5] * bx2)
                    yv[2] = lrb2 - (hh[6] * bx0 + hh[7] * bx1 + hh[8] * bx2)
                    wm = _steady_noise(prm[_B_SIG_MOT] ** 2, p_grow * dt)
                    wv[0] = wm
                    wv[1] = wm
                    wv[2] = wm / prm[_B_VERT]
                    _bias_update(P, aux, hh, yv, wv, clip, M, kw)
        # ---- 3. heading [3.3] with 5. disturbance rejection [3.5]
        use_m = False
        k_head = 0.0
        sw, sx, sy, sz = K.qmul(aw, ax, ay, az, gw, gx, gy, gz)  # q_6
        hc = x[_HC]
        hs = x[_HS]
        if s.mag_fin:
            m0, m1, m2 = K.rot(sw, sx, sy, sz, s.m0, s.m1, s.m2)
            mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            if mn > 1e-6:
                dip = math.asin(min(1.0, max(-1.0, -m2 / mn)))
                if aux[K.AUX_MREF_SET] < 0.5:
                    aux[K.AUX_MREF_N] = prm[K.PRM_MAG_REF_N] \
                        if math.isfinite(prm[K.PRM_MAG_REF_N]) else mn
                    aux[K.AUX_MREF_DIP] = prm[K.PRM_MAG_REF_DIP] \
                        if math.isfinite(prm[K.PRM_MAG_REF_DIP]) else dip
                    aux[K.AUX_MCAND_N] = mn
                    aux[K.AUX_MCAND_DIP] = dip
                    aux[K.AUX_MCAND_T] = 0.0
                    aux[K.AUX_MREF_SET] = 1.0
                    x[_MN] = mn
                    x[_MDIP] = dip
                x[_MN] += x[_KCUR] * (mn - x[_MN])
                x[_MDIP] += x[_KCUR] * (dip - x[_MDIP])
                cn = x[_MN]
                cd = x[_MDIP]
                if abs(cn - aux[K.AUX_MREF_N]) < gn and abs(cd - aux[K.AUX_MREF_DIP]) < gd:
                    x[_MUND_T] += dt
                    if x[_MUND_T] >= prm[_M_UNDIST]:
                        x[_MDIST] = 0.0
                        aux[K.AUX_MREF_N] += x[_KREF] * (cn - aux[K.AUX_MREF_N])
                        aux[K.AUX_MREF_DIP] += x[_KREF] * (cd - aux[K.AUX_MREF_DIP])
                else:
                    x[_MUND_T] = 0.0
                    x[_MDIST] = 1.0
                if abs(cn - aux[K.AUX_MCAND_N]) < gn and abs(cd - aux[K.AUX_MCAND_DIP]) < gd:
                    if rate >= prm[_M_NEW_RATE]:
                        aux[K.AUX_MCAND_T] += dt
                        aux[K.AUX_MCAND_N] += x[_KREF] * (cn - aux[K.AUX_MCAND_N])
                        aux[K.AUX_MCAND_DIP] += x[_KREF] * (cd - aux[K.AUX_MCAND_DIP])
                        if x[_MDIST] > 0.5 and (
                                aux[K.AUX_MCAND_T] >= prm[K.PRM_MAG_NEW_S]
                                or (x[_MFIRST] > 0.5
                                    and aux[K.AUX_MCAND_T] >= prm[_M_NEW_FIRST])):
                            aux[K.AUX_MREF_N] = aux[K.AUX_MCAND_N]
                            aux[K.AUX_MREF_DIP] = aux[K.AUX_MCAND_DIP]
                            x[_MUND_T] = prm[_M_UNDIST]
                            x[_MDIST] = 0.0
                            x[_MFIRST] = 0.0
                else:
                    aux[K.AUX_MCAND_N] = cn
                    aux[K.AUX_MCAND_DIP] = cd
                    aux[K.AUX_MCAND_T] = 0.0
                k_head = x[_KMAG]
                if x[_MINIT] > 0.5:
                    k_head = max(k_head, 1.0 / x[_MINIT])
                if x[_MDIST] > 0.5:
                    if x[_MREJ_T] <= prm[_M_MAX_REJ]:
                        x[_MREJ_T] += dt
                        k_head = 0.0
                    else:
                        k_head /= prm[_M_REJ_FACTOR]
                else:
                    x[_MREJ_T] = max(x[_MREJ_T] - prm[_M_REJ_FACTOR] * dt, 0.0)
                hn = m0 * m0 + m1 * m1
                if k_head > 0.0 and hn > 1e-12:
                    # wrap(delta* - delta) is the angle from the field turned by delta to
                    # north: atan2(h_x, h_y) with h = R_z(delta) m
                    c_d = hc * hc - hs * hs
                    s_d = 2.0 * hc * hs
                    err = math.atan2(c_d * m0 - s_d * m1, s_d * m0 + c_d * m1)
                    # delta += k err, on the half-angle pair
                    c, sc = K.cos_sinc(0.5 * k_head * err)
                    si = sc * 0.5 * k_head * err
                    hc, hs = hc * c - hs * si, hs * c + hc * si
                    hn = math.sqrt(hc * hc + hs * hs)
                    hc /= hn
                    hs /= hn
                    x[_HC] = hc
                    x[_HS] = hs
                    use_m = True
                    if x[_MINIT] > 0.5:
                        x[_MINIT] += 1.0
                        if 1.0 / x[_MINIT] < x[_KMAG]:
                            x[_MINIT] = 0.0
                else:
                    k_head = 0.0
        flags = K.count_used(aux, flags, use_a, use_m, has_mag)
        # ---- variances (module text)
        x[_VTILT] = min((1.0 - k_tilt) * x[_VTILT] + k_tilt * r_tilt + walk2 * dt, math.pi ** 2)
        x[_VHEAD] = min((1.0 - k_head) * x[_VHEAD] + k_head * r_head + walk2 * dt, math.pi ** 2)
        K.set_q(x, _QG, gw, gx, gy, gz)
        K.set_q(x, _QA, aw, ax, ay, az)
        # ---- output q = R_z(delta) * q_acc * q_gyr
        w, qx, qy, qz = K.qmul(hc, 0.0, 0.0, hs, sw, sx, sy, sz)
        qn = math.sqrt(w * w + qx * qx + qy * qy + qz * qz)
        if w < 0.0:
            qn = -qn
        K.write_q(out_q, i, w / qn, qx / qn, qy / qn, qz / qn)
        out_var[i, 0] = x[_VTILT]
        out_var[i, 1] = x[_VTILT]
        out_var[i, 2] = x[_VHEAD]
        out_flags[i] = flags
        out_extra[i, 0] = x[_MDIST]


class InertialLowpass(AttitudeFilter):
    """Inclination from the specific force low-passed in an almost-inertial frame (after VQF).

    Heading with magnetic-disturbance rejection, gyro bias at rest and in motion.

    Examples
    --------
    >>> f = InertialLowpass(InertialLowpassParams(tau_acc_s=3.0))
    >>> result = f.run(imu)  # doctest: +SKIP
    """

    name: ClassVar[str] = "inertial-lp"
    params_type: ClassVar[type[CommonParams]] = InertialLowpassParams
    extra_outputs: ClassVar[tuple[str, ...]] = ("mag_disturbed",)

    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        x = np.zeros(_NX)
        x[_QG] = 1.0
        x[_QA] = 1.0
        x[_HC] = 1.0
        return x, np.zeros((3, 3))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        inertial_lowpass_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux,
                                out_q, out_var, out_flags, out_extra)
