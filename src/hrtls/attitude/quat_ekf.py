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

import numba
import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _kernels as K
from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.errors import InputError
from hrtls.frames import FloatArray

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
_SIZE = K.PRM_SPECIFIC + 9


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
    rate_ref_rad_s:
        The accelerometer variance grows as ``acc_noise^2 (1 + (|w| / rate_ref)^2)`` with the
        rate of turn ``|w|`` (our extension: centripetal acceleration makes the specific force
        a worse gravity reference while turning; ``inf`` gives the constant variance of the
        thesis).
    """

    gyro_noise_rad_s: float = 0.005
    acc_noise: float = 0.1
    mag_noise: float = 0.5
    mag_mode: Literal["vector", "horizontal"] = "horizontal"
    p0_var: float = 1e-3
    bias_in_state: bool = True
    bias_sigma_rad_s: float = 0.01
    bias_walk_rad_s2: float = 1e-5
    rate_ref_rad_s: float = 2.0

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        for name in ("gyro_noise_rad_s", "acc_noise", "mag_noise", "p0_var", "bias_sigma_rad_s",
                     "bias_walk_rad_s2", "rate_ref_rad_s"):
            value = float(getattr(self, name))
            if not (value > 0.0 and (np.isfinite(value) or name == "rate_ref_rad_s")):
                raise InputError(f"{name} = {value}", where="QuatEkfParams",
                                 expected="a finite positive number")
        if self.mag_mode not in ("vector", "horizontal"):
            raise InputError(f"mag_mode = {self.mag_mode!r}", where="QuatEkfParams",
                             expected="'vector' or 'horizontal'")

    def kernel_array(self) -> FloatArray:
        """Kernel parameter array."""
        p = np.zeros(_SIZE)
        p[: K.PRM_SPECIFIC] = self.common_array()
        p[_GYR_NOISE] = self.gyro_noise_rad_s
        p[_ACC_NOISE] = self.acc_noise
        p[_MAG_NOISE] = self.mag_noise
        p[_MAG_MODE] = 0.0 if self.mag_mode == "vector" else 1.0
        p[_P0] = self.p0_var
        p[_BIAS_STATE] = 1.0 if self.bias_in_state else 0.0
        p[_BIAS_P0] = self.bias_sigma_rad_s**2 if self.bias_in_state else 0.0
        p[_BIAS_WALK] = self.bias_walk_rad_s2**2 if self.bias_in_state else 0.0
        p[_RATE_REF] = self.rate_ref_rad_s
        return p


@numba.njit(**K.JIT)
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
    for c in range(4, P.shape[0]):
        d = x[0] * P[0, c] + x[1] * P[1, c] + x[2] * P[2, c] + x[3] * P[3, c]
        for a in range(4):
            val = P[a, c] - x[a] * d
            P[a, c] = val
            P[c, a] = val


@numba.njit(**K.JIT)
def _normalize(x: FloatArray, P: FloatArray) -> None:
    """Unit norm with ``w >= 0``; a sign flip of ``q`` also flips its covariance with the bias."""
    n = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
    if x[0] < 0.0:
        n = -n
        for a in range(4):
            for c in range(4, P.shape[0]):
                P[a, c] = -P[a, c]
                P[c, a] = -P[c, a]
    x[0] /= n
    x[1] /= n
    x[2] /= n
    x[3] /= n


@numba.njit(**K.JIT)
def quat_ekf_kernel(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, has_gyr: bool,
    has_mag: bool, prm: FloatArray, x: FloatArray, P: FloatArray, aux: FloatArray,
    out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
) -> None:
    """Quaternion EKF over one chunk (Inderst eq. 4.10-4.19); mutates ``x``, ``P``, ``aux``."""
    n = t.shape[0]
    ns = P.shape[0]  # 7: [q, b]
    phi = np.empty((4, 4))
    bm = np.empty((4, 3))
    tmp = np.empty((4, 4))
    cross = np.empty((4, 3))
    jac = np.zeros((3, ns))
    dx = np.empty(ns)
    ph = np.empty((ns, 3))
    xs = np.empty(4)
    bias_state = prm[_BIAS_STATE] > 0.5
    g = prm[K.PRM_GRAVITY]
    sg = prm[_GYR_NOISE]
    va = prm[_ACC_NOISE] ** 2
    acc_rate_k = 1.0 / prm[_RATE_REF] ** 2
    vm = prm[_MAG_NOISE] ** 2
    horizontal = prm[_MAG_MODE] > 0.5
    for i in range(n):
        ti = t[i]
        tp = aux[K.AUX_T_PREV]
        dt = ti - tp if math.isfinite(tp) else 0.0
        aux[K.AUX_T_PREV] = ti
        aux[K.AUX_N] += 1.0
        a0 = acc[i, 0]
        a1 = acc[i, 1]
        a2 = acc[i, 2]
        an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        acc_fin = math.isfinite(an) and 1e-6 < an < prm[K.PRM_ACC_RANGE]
        g0 = gyr[i, 0]
        g1 = gyr[i, 1]
        g2 = gyr[i, 2]
        gyr_fin = has_gyr and K.gyro_ok(prm, g0, g1, g2)
        m0 = mag[i, 0]
        m1 = mag[i, 1]
        m2 = mag[i, 2]
        mag_fin = has_mag and K.finite3(m0, m1, m2)
        if (not acc_fin) or (has_gyr and not gyr_fin) or (has_mag and not mag_fin):
            aux[K.AUX_N_BAD] += 1.0
        acc_dev = abs(an - g) if acc_fin else math.inf
        flags = 0
        rate2 = 0.0
        if aux[K.AUX_INIT] < 0.5:
            # eq. 4.13: initialise at the first sample that looks static
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                w, qx, qy, qz = K.init_attitude(prm, a0, a1, a2, m0, m1, m2, mag_fin)
                x[0] = w
                x[1] = qx
                x[2] = qy
                x[3] = qz
                for r in range(ns):
                    for c in range(ns):
                        P[r, c] = 0.0
                    P[r, r] = prm[_P0] if r < 4 else prm[_BIAS_P0]
                _project(x, P)
                aux[K.AUX_INIT] = 1.0
                K.init_rest(aux, g0, g1, g2, a0, a1, a2, gyr_fin)
                flags = K.FLAG_VALID | K.FLAG_ACC
                if mag_fin:
                    ux, uy, uz = K.rot_t(w, qx, qy, qz, 0.0, 0.0, 1.0)
                    if K.mag_gate(aux, prm, m0, m1, m2, ux, uy, uz, 0.0):
                        flags |= K.FLAG_MAG
                    else:
                        aux[K.AUX_N_MAG_REJ] += 1.0
                elif has_mag:
                    aux[K.AUX_N_MAG_REJ] += 1.0
            else:
                aux[K.AUX_N_ACC_REJ] += 1.0
                if has_mag:
                    aux[K.AUX_N_MAG_REJ] += 1.0
                out_q[i, 0] = 1.0
                out_q[i, 1] = 0.0
                out_q[i, 2] = 0.0
                out_q[i, 3] = 0.0
                out_var[i, 0] = math.pi ** 2
                out_var[i, 1] = math.pi ** 2
                out_var[i, 2] = math.pi ** 2
                out_flags[i] = 0
                continue
        else:
            flags = K.FLAG_VALID
            # ---- prediction, eq. 4.12 and 4.14
            if gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]:
                if acc_fin and K.rest_and_bias(aux, prm, g0, g1, g2, a0, a1, a2, dt):
                    flags |= K.FLAG_REST
                wx = g0 - aux[K.AUX_BIAS]
                wy = g1 - aux[K.AUX_BIAS + 1]
                wz = g2 - aux[K.AUX_BIAS + 2]
                rate2 = wx * wx + wy * wy + wz * wz
                K.transition(wx, wy, wz, dt, phi)
                # d(q_k)/d(b) = -dt/2 Xi(q_{k-1}) (first order), Xi(q) w = q * [0, w]
                hd = -0.5 * dt
                bm[0, 0] = -x[1] * hd
                bm[0, 1] = -x[2] * hd
                bm[0, 2] = -x[3] * hd
                bm[1, 0] = x[0] * hd
                bm[1, 1] = -x[3] * hd
                bm[1, 2] = x[2] * hd
                bm[2, 0] = x[3] * hd
                bm[2, 1] = x[0] * hd
                bm[2, 2] = -x[1] * hd
                bm[3, 0] = -x[2] * hd
                bm[3, 1] = x[1] * hd
                bm[3, 2] = x[0] * hd
                for r in range(4):
                    xs[r] = phi[r, 0] * x[0] + phi[r, 1] * x[1] + phi[r, 2] * x[2] \
                        + phi[r, 3] * x[3]
                # tmp = Phi P_qq + B P_bq ; cross = Phi P_qb + B P_bb (the new P_qb)
                for r in range(4):
                    for c in range(4):
                        val = phi[r, 0] * P[0, c] + phi[r, 1] * P[1, c] \
                            + phi[r, 2] * P[2, c] + phi[r, 3] * P[3, c]
                        if bias_state:
                            val += bm[r, 0] * P[4, c] + bm[r, 1] * P[5, c] + bm[r, 2] * P[6, c]
                        tmp[r, c] = val
                    if bias_state:
                        for c in range(3):
                            cross[r, c] = phi[r, 0] * P[0, 4 + c] + phi[r, 1] * P[1, 4 + c] \
                                + phi[r, 2] * P[2, 4 + c] + phi[r, 3] * P[3, 4 + c] \
                                + bm[r, 0] * P[4, 4 + c] + bm[r, 1] * P[5, 4 + c] \
                                + bm[r, 2] * P[6, 4 + c]
                nq = math.sqrt(xs[0] * xs[0] + xs[1] * xs[1] + xs[2] * xs[2] + xs[3] * xs[3])
                for r in range(4):
                    x[r] = xs[r] / nq
                qv = (0.5 * dt * sg) ** 2
                # P_qq = tmp Phi^T + cross B^T + Q  (eq. 4.14 with the bias block)
                for r in range(4):
                    for c in range(r, 4):
                        val = tmp[r, 0] * phi[c, 0] + tmp[r, 1] * phi[c, 1] \
                            + tmp[r, 2] * phi[c, 2] + tmp[r, 3] * phi[c, 3]
                        if bias_state:
                            val += cross[r, 0] * bm[c, 0] + cross[r, 1] * bm[c, 1] \
                                + cross[r, 2] * bm[c, 2]
                        val += qv * ((1.0 if r == c else 0.0) - x[r] * x[c])
                        P[r, c] = val
                        P[c, r] = val
                if bias_state:
                    for r in range(4):
                        for c in range(3):
                            P[r, 4 + c] = cross[r, c]
                            P[4 + c, r] = cross[r, c]
                    bw = prm[_BIAS_WALK] * dt
                    P[4, 4] += bw
                    P[5, 5] += bw
                    P[6, 6] += bw
                _normalize(x, P)
                flags |= K.FLAG_GYR
            elif has_gyr:
                aux[K.AUX_N_GYR_REJ] += 1.0
            # ---- gates and stacked measurement, eq. 4.15-4.18
            w = x[0]
            qx = x[1]
            qy = x[2]
            qz = x[3]
            ux, uy, uz = K.rot_t(w, qx, qy, qz, 0.0, 0.0, 1.0)
            use_a = acc_fin and acc_dev < prm[K.PRM_ACC_GATE]
            use_m = False
            if mag_fin and K.mag_gate(aux, prm, m0, m1, m2, ux, uy, uz, dt):
                if horizontal:
                    md = m0 * ux + m1 * uy + m2 * uz
                    z0 = m0 - md * ux
                    z1 = m1 - md * uy
                    z2 = m2 - md * uz
                    v0, v1, v2 = 0.0, 1.0, 0.0
                else:
                    z0 = m0
                    z1 = m1
                    z2 = m2
                    dip = aux[K.AUX_MREF_DIP]
                    v0, v1, v2 = 0.0, math.cos(dip), -math.sin(dip)
                zn = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
                use_m = zn > 1e-9
            if use_a or use_m:
                # ---- update, eq. 4.19: blocks share the linearisation at the prediction
                for r in range(ns):
                    dx[r] = 0.0
                if use_a:
                    K.rot_t_jacobian(w, qx, qy, qz, 0.0, 0.0, 1.0, jac)
                    use_a = K.block3_update7(P, dx, jac, a0 / an - ux, a1 / an - uy,
                                             a2 / an - uz,
                                             va * (1.0 + rate2 * acc_rate_k), ph)
                if use_m:
                    h0, h1, h2 = K.rot_t(w, qx, qy, qz, v0, v1, v2)
                    K.rot_t_jacobian(w, qx, qy, qz, v0, v1, v2, jac)
                    use_m = K.block3_update7(P, dx, jac, z0 / zn - h0, z1 / zn - h1,
                                             z2 / zn - h2, vm, ph)
                ok = True
                for r in range(ns):
                    ok = ok and math.isfinite(dx[r]) and math.isfinite(P[r, r])
                if ok:
                    for r in range(4):
                        x[r] += dx[r]
                    if bias_state:
                        for r in range(3):
                            aux[K.AUX_BIAS + r] += dx[4 + r]
                    _normalize(x, P)
                    _project(x, P)
                else:
                    # numerical failure: keep the prediction, restart the covariance
                    use_a = False
                    use_m = False
                    for r in range(ns):
                        for c in range(ns):
                            P[r, c] = 0.0
                        P[r, r] = prm[_P0] if r < 4 else prm[_BIAS_P0]
                    _project(x, P)
            if use_a:
                flags |= K.FLAG_ACC
            else:
                aux[K.AUX_N_ACC_REJ] += 1.0
            if use_m:
                flags |= K.FLAG_MAG
            elif has_mag:
                aux[K.AUX_N_MAG_REJ] += 1.0
        out_q[i, 0] = x[0]
        out_q[i, 1] = x[1]
        out_q[i, 2] = x[2]
        out_q[i, 3] = x[3]
        K.nav_rotation_var(x[0], x[1], x[2], x[3], P, out_var, i)
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
        if inputs:
            raise InputError(f"unexpected inputs {sorted(inputs)}", where=self.name,
                             expected="t, acc, gyr, mag only")
        quat_ekf_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux, out_q,
                        out_var, out_flags)
