"""Quaternion EKF with accelerometer and magnetometer gates (Inderst thesis, Sec. 4.2.1).

State ``q = q_nd`` (device -> ENU, ``[w, x, y, z]``) with a 4 x 4 covariance.

* Prediction (eq. 4.10-4.12, 4.14): ``q_k = exp(Omega_k dt) q_{k-1}`` with the gyro rate minus
  the current bias estimate; ``P = Phi P Phi^T + Q``. The thesis only says that ``Q`` is "the
  accuracy of the gyroscopes"; we map a white gyro noise of standard deviation ``sigma_g`` through
  ``dq = dt/2 Xi(q) dw``, which gives ``Q = (dt sigma_g / 2)^2 (I - q q^T)`` for a unit ``q``.
* Initial attitude (eq. 4.13): the shortest rotation taking the measured specific-force direction
  to the vertical, then turned about the vertical so the magnetometer points north. (The printed
  eq. 4.13 is garbled; this is the rotation it describes in our ENU, z-up frame.)
* Accelerometer update (eq. 4.16): measurement ``a / |a|`` against ``R(q)^T e_z`` (the unit
  "up" seen by a device at rest), only when ``| |a| - g | < eps_a``; its variance grows with
  the rate of turn (``rate_ref_rad_s``, our extension).
* Magnetometer update (eq. 4.18): ``m / |m|`` against ``R(q)^T d_m`` with the reference field
  direction ``d_m = [0, cos(dip), -sin(dip)]`` (north, dipping down), only when the norm matches,
  the dip matches (our addition) and the field did not jump (``mag_mode="vector"``). The
  default ``mag_mode="horizontal"`` compares only the horizontal part of the field (the field
  minus its component along the predicted vertical) with north, so that magnetic errors cannot
  tilt the estimate (the reading we use for the Euler EKF as well).
* Update (eq. 4.19): the stacked measurement is processed as two 3-row blocks (accelerometer,
  magnetometer), both linearised at the predicted state; with a block-diagonal ``V`` this equals
  the stacked update exactly.
  ``q`` is normalised after predict and update; the covariance is projected with
  ``J = I - q q^T`` after the normalisation (our addition, it keeps ``P`` consistent with a unit
  quaternion).

Scale-factor matrices ``K_a``, ``K_m`` of eq. 4.16/4.18 are the identity here: calibrate the
sensors first (:mod:`hrtls.calibration`).

Gyro bias (our extension, on by default): the state is augmented to ``[q, b]`` (7 states,
``dq/db = -dt/2 Xi(q)``, bias random walk); ``bias_in_state=False`` gives the thesis' 4-state
filter. The thesis gives no numerical values for ``Q``, ``V`` or the gates; the defaults were
chosen on ``benchmarks/attitude.py`` (simulated walks with magnetic anomalies and the BROAD
trials).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _ekf_update as EK
from hrtls.attitude import _kernels as K
from hrtls.attitude import _quaternion as Q
from hrtls.attitude._jit import JIT
from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.errors import InputError
from hrtls.frames import FloatArray
from hrtls.kernels import njit

__all__ = ["QuatEkf", "QuatEkfParams"]

_GYR_NOISE = K.PRM_SPECIFIC
_ACC_NOISE = K.PRM_SPECIFIC + 1
_MAG_NOISE = K.PRM_SPECIFIC + 2
_MAG_MODE = K.PRM_SPECIFIC + 3
_P0 = K.PRM_SPECIFIC + 4
_BIAS_STATE = K.PRM_SPECIFIC + 5
_BIAS_P0 = K.PRM_SPECIFIC + 6
_BIAS_WALK = K.PRM_SPECIFIC + 7
_RATE_REF = K.PRM_SPECIFIC + 8
_DYN_TAU = K.PRM_SPECIFIC + 9
_DYN_CORR = K.PRM_SPECIFIC + 10
_REST_VAR = K.PRM_SPECIFIC + 11
_NS = 7  # states: quaternion and gyro bias (zero bias blocks for the 4-state filter)


@dataclass(frozen=True, kw_only=True)
class QuatEkfParams(CommonParams):
    """Parameters of the quaternion EKF (see :class:`CommonParams` for the gates).

    Attributes
    ----------
    gyro_noise_rad_s:
        Gyro white-noise standard deviation ``sigma_g`` driving ``Q`` (eq. 4.14), rad/s.
    acc_noise:
        Standard deviation of the normalised specific-force direction (``V`` of eq. 4.19,
        accelerometer rows), dimensionless (about rad).
    mag_noise:
        Standard deviation of the normalised field direction (magnetometer rows), dimensionless.
    mag_mode:
        ``"vector"``: the full field direction (eq. 4.18); ``"horizontal"``: its horizontal part
        against north only.
    p0_var:
        Initial variance of each quaternion component.
    bias_in_state:
        Augment the state with the gyro bias (``[q, b]``, 7 states; our extension). With
        ``False`` the filter is the thesis' 4-state EKF and the bias is only learnt at rest.
    bias_sigma_rad_s:
        Initial standard deviation of the gyro bias, rad/s.
    bias_walk_rad_s2:
        Random-walk density of the gyro bias, rad/s per sqrt(s).
    bias_var_at_rest:
        While the rest detector updates the gyro bias (:class:`CommonParams` ``rest_*``,
        ``bias_tau_s``), shrink the variance of the bias states to that of the rest average,
        ``sigma_g^2 k / (2 - k)`` with the averaging weight ``k`` of the rest update (about
        ``sigma_g^2 dt / (2 bias_tau_s)``), keeping their correlations (``P <- D P D``, ``D``
        diagonal). Our extension: the rest update changes the bias outside the EKF, so
        without it the bias states keep their initial variance after a rest and, when the
        walk begins, take up the tilt that the start-up acceleration suggests (the tilt then
        drifts: the levelled forward acceleration of Colombo's start came out at ~0.65 of the
        truth, ~0.9 with this option). Needs ``bias_in_state`` and ``estimate_bias``. Off by
        default: it improves the tilt and heading of ``benchmarks/attitude.py`` (simulated
        walks) and leaves BROAD unchanged, but the locked bias no longer soaks up the gyro
        scale error of steady turns, and the default preset's position on Colombo's circles
        and squares got 0.01-0.06 m worse.
    rate_ref_rad_s:
        The accelerometer variance grows as ``acc_noise^2 (1 + (|w| / rate_ref)^2)`` with the
        rate of turn ``|w|`` (our extension: centripetal acceleration makes the specific force
        a worse gravity reference while turning; ``inf`` gives the constant variance of the
        thesis).
    dyn_acc_window_s:
        Time constant of the running variance of the body's acceleration (the specific force
        rotated into ENU with the predicted attitude), s.
    dyn_acc_corr_s:
        Correlation time ``tau`` of the body's acceleration, s (our extension; 0 gives the
        thesis' constant variance). The acceleration of a walking body (and the seconds-long
        forward acceleration of a start or stop) is read as white noise of density
        ``2 s^2 tau`` added to the specific force, ``s^2`` its running variance: the
        direction variance gains ``2 s^2 tau / (T g^2)`` per sample of period ``T``. At rest
        it vanishes; while walking the tilt follows the gyroscope over several seconds
        instead of the accelerations of the walk. Off by default: this filter's small gyro
        noise already makes its tilt loop slow (tens of seconds once converged), and on
        ``benchmarks/attitude.py`` the term made the BROAD and simulated-walk tilt worse
        (the gyro-bias states then carry the tilt longer); the Euler EKF, whose paper ``Q_w``
        is large, needs it.
    """

    gyro_noise_rad_s: float = 0.005
    acc_noise: float = 0.1
    mag_noise: float = 0.5
    mag_mode: Literal["vector", "horizontal"] = "horizontal"
    p0_var: float = 1e-3
    bias_in_state: bool = True
    bias_sigma_rad_s: float = 0.01
    bias_walk_rad_s2: float = 1e-5
    bias_var_at_rest: bool = False
    rate_ref_rad_s: float = 2.0
    dyn_acc_window_s: float = 1.0
    dyn_acc_corr_s: float = 0.0

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        self._require_positive(("gyro_noise_rad_s", "acc_noise", "mag_noise", "p0_var",
                                "bias_sigma_rad_s", "bias_walk_rad_s2", "rate_ref_rad_s",
                                "dyn_acc_window_s"),
                               inf_ok=("rate_ref_rad_s",))
        if not (math.isfinite(self.dyn_acc_corr_s) and self.dyn_acc_corr_s >= 0.0):
            raise InputError(f"dyn_acc_corr_s = {self.dyn_acc_corr_s}", where="QuatEkfParams",
                             expected="a finite value >= 0 s (0: the thesis' constant variance)")
        if self.mag_mode not in ("vector", "horizontal"):
            raise InputError(f"mag_mode = {self.mag_mode!r}", where="QuatEkfParams",
                             expected="'vector' or 'horizontal'")

    def specific_values(self) -> tuple[float, ...]:
        """Kernel parameters ``_GYR_NOISE`` .. ``_REST_VAR``."""
        b = self.bias_in_state
        return (self.gyro_noise_rad_s, self.acc_noise, self.mag_noise,
                0.0 if self.mag_mode == "vector" else 1.0, self.p0_var, 1.0 if b else 0.0,
                self.bias_sigma_rad_s**2 if b else 0.0, self.bias_walk_rad_s2**2 if b else 0.0,
                self.rate_ref_rad_s, self.dyn_acc_window_s, self.dyn_acc_corr_s,
                1.0 if (b and self.bias_var_at_rest and self.estimate_bias) else 0.0)


@njit(inline="always", **JIT)
def _project(x: FloatArray, P: FloatArray) -> None:
    """``P <- J P J^T`` with ``J = diag(I - q q^T, I)`` (covariance of the unit quaternion)."""
    v0 = P[0, 0] * x[0] + P[0, 1] * x[1] + P[0, 2] * x[2] + P[0, 3] * x[3]
    v1 = P[1, 0] * x[0] + P[1, 1] * x[1] + P[1, 2] * x[2] + P[1, 3] * x[3]
    v2 = P[2, 0] * x[0] + P[2, 1] * x[1] + P[2, 2] * x[2] + P[2, 3] * x[3]
    v3 = P[3, 0] * x[0] + P[3, 1] * x[1] + P[3, 2] * x[2] + P[3, 3] * x[3]
    s = v0 * x[0] + v1 * x[1] + v2 * x[2] + v3 * x[3]
    v = (v0, v1, v2, v3)
    for a in range(4):
        for b in range(a, 4):
            val = P[a, b] - x[a] * v[b] - v[a] * x[b] + x[a] * x[b] * s
            P[a, b] = val
            P[b, a] = val
    # cross covariance with the bias: (I - q q^T) P_qb
    for c in range(4, _NS):
        d = x[0] * P[0, c] + x[1] * P[1, c] + x[2] * P[2, c] + x[3] * P[3, c]
        for a in range(4):
            val = P[a, c] - x[a] * d
            P[a, c] = val
            P[c, a] = val


@njit(inline="always", **JIT)
def _normalize(x: FloatArray, P: FloatArray) -> None:
    """Unit norm with ``w >= 0``; a sign flip of ``q`` also flips its covariance with the bias."""
    n = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    if x[0] < 0.0:
        n = -n
        for a in range(4):
            for c in range(4, _NS):
                P[a, c] = -P[a, c]
                P[c, a] = -P[c, a]
    x[0] /= n
    x[1] /= n
    x[2] /= n
    x[3] /= n


@njit(inline="always", **JIT)
def _apply_f(
    f: tuple[float, float, float, float, float, float, float, float],
    v0: float, v1: float, v2: float, v3: float, v4: float, v5: float, v6: float,
) -> tuple[float, float, float, float]:
    """Quaternion rows of ``F v`` with ``F = [[Phi, B], [0, I]]``.

    ``f = (c, s wx, s wy, s wz, p0, p1, p2, p3)``: ``Phi = c I + s Omega'`` (eq. 4.12) and
    ``B = -dt/2 Xi(q_{k-1})`` with ``p = -dt/2 q_{k-1}``.
    """
    c, sx, sy, sz, p0, p1, p2, p3 = f
    return (
        c * v0 - sx * v1 - sy * v2 - sz * v3 - p1 * v4 - p2 * v5 - p3 * v6,
        sx * v0 + c * v1 + sz * v2 - sy * v3 + p0 * v4 - p3 * v5 + p2 * v6,
        sy * v0 - sz * v1 + c * v2 + sx * v3 + p3 * v4 + p0 * v5 - p1 * v6,
        sz * v0 + sy * v1 - sx * v2 + c * v3 - p2 * v4 + p1 * v5 + p0 * v6,
    )


@njit(inline="always", **JIT)
def _predict(
    x: FloatArray, P: FloatArray, work: FloatArray, wx: float, wy: float, wz: float, dt: float,
    qv: float, bw: float,
) -> None:
    """Eq. 4.12 and 4.14 with the bias block: ``q <- Phi q / |Phi q|``, ``P <- F P F^T + Q``.

    ``F = [[Phi, B], [0, I]]`` with ``B = d(q_k)/d(b) = -dt/2 Xi(q_{k-1})`` (first order,
    ``Xi(q) w = q * [0, w]``); ``Q = qv (I - q q^T)`` on the quaternion block and ``bw I`` on
    the bias block. ``Phi`` is ``c I`` plus a skew matrix, so ``F`` is applied row by row
    without forming it. ``work`` is a (4, 7) array (it receives the quaternion rows of
    ``F P``). With a 4-state filter the bias blocks of ``P`` are zero and stay zero.
    """
    n = math.sqrt(wx * wx + wy * wy + wz * wz)
    c, sc = Q.cos_sinc(0.5 * n * dt)
    s = sc * 0.5 * dt  # sin(|w| dt / 2) / |w|
    hd = -0.5 * dt
    q0 = x[0]
    q1 = x[1]
    q2 = x[2]
    q3 = x[3]
    f = (c, s * wx, s * wy, s * wz, hd * q0, hd * q1, hd * q2, hd * q3)
    # work = quaternion rows of F P (column by column)
    for k in range(_NS):
        u0, u1, u2, u3 = _apply_f(f, P[0, k], P[1, k], P[2, k], P[3, k], P[4, k], P[5, k],
                                  P[6, k])
        work[0, k] = u0
        work[1, k] = u1
        work[2, k] = u2
        work[3, k] = u3
    xs0, xs1, xs2, xs3 = _apply_f(f, q0, q1, q2, q3, 0.0, 0.0, 0.0)
    nq = math.sqrt(xs0 * xs0 + xs1 * xs1 + xs2 * xs2 + xs3 * xs3)
    xs0 /= nq
    xs1 /= nq
    xs2 /= nq
    xs3 /= nq
    x[0] = xs0
    x[1] = xs1
    x[2] = xs2
    x[3] = xs3
    xn = (xs0, xs1, xs2, xs3)
    # P_qq = (F P F^T)_qq + Q: row r is F applied to row r of work; P_qb = work[:, 4:]
    for r in range(4):
        u = _apply_f(f, work[r, 0], work[r, 1], work[r, 2], work[r, 3], work[r, 4],
                     work[r, 5], work[r, 6])
        for c2 in range(r, 4):
            val = u[c2] + qv * ((1.0 if r == c2 else 0.0) - xn[r] * xn[c2])
            P[r, c2] = val
            P[c2, r] = val
        for c2 in range(4, _NS):
            P[r, c2] = work[r, c2]
            P[c2, r] = work[r, c2]
    P[4, 4] += bw
    P[5, 5] += bw
    P[6, 6] += bw


@njit(inline="always", **JIT)
def _shrink_bias_var(P: FloatArray, v: float) -> None:
    """Bias variances above ``v`` down to ``v``: ``P <- D P D``.

    ``D = diag(1, 1, 1, 1, d4, d5, d6)`` with ``d = min(1, sqrt(v / P_ii))``: the correlations
    are kept and ``P`` stays positive semidefinite.
    """
    for r in range(4, _NS):
        if P[r, r] > v:
            f = math.sqrt(v / P[r, r])
            for c in range(_NS):
                P[r, c] *= f
            for c in range(_NS):
                P[c, r] *= f


@njit(**JIT)
def _reset_cov(x: FloatArray, P: FloatArray, prm: FloatArray) -> None:
    """Initial covariance: ``p0`` per quaternion component, the bias variance, projected."""
    for r in range(_NS):
        for c in range(_NS):
            P[r, c] = 0.0
        P[r, r] = prm[_P0] if r < 4 else prm[_BIAS_P0]
    _project(x, P)


@njit(**JIT)
def quat_ekf_kernel(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, has_gyr: bool,
    has_mag: bool, prm: FloatArray, x: FloatArray, P: FloatArray, aux: FloatArray,
    out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
) -> None:
    """Quaternion EKF over one chunk (Inderst eq. 4.10-4.19); mutates ``x``, ``P``, ``aux``."""
    n = t.shape[0]
    work = np.empty((4, _NS))
    dx = np.empty(_NS)
    ph = np.empty((_NS, 3))
    qv_k = (0.5 * prm[_GYR_NOISE]) ** 2  # Q = qv_k dt^2 (I - q q^T), eq. 4.14 reading
    va = prm[_ACC_NOISE] ** 2
    acc_rate_k = 1.0 / prm[_RATE_REF] ** 2
    dyn_tau = prm[_DYN_TAU]
    dyn_k = 2.0 * prm[_DYN_CORR] / prm[K.PRM_GRAVITY] ** 2  # 2 s^2 tau / (T g^2)
    vm = prm[_MAG_NOISE] ** 2
    horizontal = prm[_MAG_MODE] > 0.5
    rest_var = prm[_REST_VAR] > 0.5
    gyr_var = prm[_GYR_NOISE] ** 2
    for i in range(n):
        s = K.read_sample(t, acc, gyr, mag, i, has_gyr, has_mag, prm, aux)
        if aux[K.AUX_INIT] < 0.5:
            # eq. 4.13: initialise at the first sample that looks static
            flags, w, qx, qy, qz = K.try_init(aux, prm, s, has_mag)
            if flags == 0:
                K.write_uninit(out_q, out_var, out_flags, i)
                continue
            Q.set_q(x, 0, w, qx, qy, qz)
            _reset_cov(x, P, prm)
        else:
            flags = K.FLAG_VALID
            # ---- prediction, eq. 4.12 and 4.14
            # (K.gyro_step spelt out: through the helper this kernel ran ~5 % slower)
            rate2 = 0.0
            if s.gyr_fin and 0.0 < s.dt <= prm[K.PRM_MAX_DT]:
                if s.acc_fin and K.rest_and_bias(aux, prm, s.g0, s.g1, s.g2, s.a0, s.a1, s.a2,
                                                 s.dt):
                    flags |= K.FLAG_REST
                flags |= K.FLAG_GYR
                wx, wy, wz = K.unbiased_rate(aux, s)
                rate2 = wx * wx + wy * wy + wz * wz
                _predict(x, P, work, wx, wy, wz, s.dt, qv_k * s.dt * s.dt,
                         prm[_BIAS_WALK] * s.dt)
                _normalize(x, P)
                if rest_var and (flags & K.FLAG_REST) != 0:
                    # the rest update's averaging weight (K.rest_and_bias)
                    kb = s.dt / min(prm[K.PRM_BIAS_TAU_S] + s.dt,
                                    aux[K.AUX_REST_T] - prm[K.PRM_REST_S] + s.dt)
                    _shrink_bias_var(P, gyr_var * kb / (2.0 - kb))
            elif has_gyr:
                aux[K.AUX_N_GYR_REJ] += 1.0
            # ---- gates and stacked measurement, eq. 4.15-4.18
            w = x[0]
            qx = x[1]
            qy = x[2]
            qz = x[3]
            ux, uy, uz = Q.rot_t(w, qx, qy, qz, 0.0, 0.0, 1.0)
            use_a = s.acc_fin and s.acc_dev < prm[K.PRM_ACC_GATE]
            v_dyn = 0.0
            if s.acc_fin and dyn_k > 0.0:
                var_dyn = K.dynamic_acc_var(aux, s, w, qx, qy, qz, dyn_tau)
                if s.dt > 0.0:
                    v_dyn = dyn_k * var_dyn / s.dt
            use_m = False
            if s.mag_fin and K.mag_gate(aux, prm, s.m0, s.m1, s.m2, ux, uy, uz, s.dt):
                if horizontal:
                    z0, z1, z2, zn = K.horizontal_unit(s.m0, s.m1, s.m2, ux, uy, uz)
                    v0, v1, v2 = 0.0, 1.0, 0.0
                else:
                    z0 = s.m0
                    z1 = s.m1
                    z2 = s.m2
                    zn = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
                    dip = aux[K.AUX_MREF_DIP]
                    v0, v1, v2 = 0.0, math.cos(dip), -math.sin(dip)
                use_m = zn > 1e-9
            if use_a or use_m:
                # ---- update, eq. 4.19: blocks share the linearisation at the prediction
                for r in range(_NS):
                    dx[r] = 0.0
                if use_a:
                    jac = Q.rot_t_jac(w, qx, qy, qz, 0.0, 0.0, 1.0)
                    an = s.an
                    use_a = EK.block3_update7(P, dx, jac, s.a0 / an - ux, s.a1 / an - uy,
                                             s.a2 / an - uz,
                                             va * (1.0 + rate2 * acc_rate_k) + v_dyn, ph)
                if use_m:
                    h0, h1, h2 = Q.rot_t(w, qx, qy, qz, v0, v1, v2)
                    jac = Q.rot_t_jac(w, qx, qy, qz, v0, v1, v2)
                    use_m = EK.block3_update7(P, dx, jac, z0 / zn - h0, z1 / zn - h1,
                                             z2 / zn - h2, vm, ph)
                if EK.update_finite(dx, P):
                    for r in range(4):
                        x[r] += dx[r]
                    for r in range(3):  # zero for the 4-state filter
                        aux[K.AUX_BIAS + r] += dx[4 + r]
                    _normalize(x, P)
                    _project(x, P)
                else:
                    # numerical failure: keep the prediction, restart the covariance
                    use_a = False
                    use_m = False
                    _reset_cov(x, P, prm)
            flags = K.count_used(aux, flags, use_a, use_m, has_mag)
        Q.write_q(out_q, i, x[0], x[1], x[2], x[3])
        EK.nav_rotation_var(x[0], x[1], x[2], x[3], P, out_var, i)
        out_flags[i] = flags


class QuatEkf(AttitudeFilter):
    """Quaternion EKF with accelerometer / magnetometer gates (Inderst Sec. 4.2.1).

    Examples
    --------
    >>> f = QuatEkf(QuatEkfParams(acc_gate_m_s2=0.8))
    >>> result = f.run(imu)  # doctest: +SKIP
    """

    name: ClassVar[str] = "quat-ekf"
    params_type: ClassVar[type[CommonParams]] = QuatEkfParams

    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        return np.array([1.0, 0.0, 0.0, 0.0]), np.zeros((7, 7))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        quat_ekf_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux, out_q,
                        out_var, out_flags)
