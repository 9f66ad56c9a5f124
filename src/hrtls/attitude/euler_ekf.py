"""Euler-angle attitude EKF (Colombo et al. 2014, Sec. III-B, eq. 1-11).

State ``theta = [roll, pitch, yaw]`` (rad) of ``R_nd = Rz(yaw) Ry(pitch) Rx(roll)``
(:mod:`hrtls.frames`), covariance 3 x 3.

Frame conversion. The paper's world frame is x north, z down, with ``E(theta) = -D(theta)^-1``
(its eq. 2 and Appendix). In our ENU frame with body rates and ``R`` mapping device vectors to
ENU, the same kinematics read ``d(theta)/dt = D(theta)^-1 w`` with the usual z-y-x rate matrix
(no minus sign); gravity and north become ``g_n = [0, 0, g]`` (specific force at rest, z up)
and ``n_n = [0, 1, 0]``.

* Prediction (eq. 5-6): ``theta+ = theta + T E(theta) w``; ``P+ = F P F^T + G Q_w G^T`` with
  ``F = I + T d(E w)/d(theta)`` and ``G = T E(theta)``. By default the angles are propagated
  exactly (``R+ = R(theta) exp([w]x T)``, of which eq. 5 is the first-order form;
  ``exact_propagation=False`` gives eq. 5 itself): eq. 5 diverges in fast rotations.
* Measurements (eq. 3-4, 7): specific force ``R^T g_n`` (m/s^2) and the north direction
  ``R^T n_n``. The paper's magnetometer "works as a compass"; we read its north measurement as
  the horizontal part of the measured field (the field minus its component along the predicted
  vertical), normalised: it carries heading only.
* Yaw pseudo-measurement (eq. 1 ``eta_z = C theta``, eq. 10): an optional yaw input
  (``yaw_rad``, NaN where absent) from the fusion stage's trajectory stretching (Colombo
  III-E).
* Update (eq. 8-11): all rows linearised at the prediction, processed in blocks (equal to the
  stacked update of eq. 8-9 for the block-diagonal ``Q_o`` of eq. 10).

Defaults are the values of Sec. V-1: ``P(0) = 0.001 I rad^2``, ``Q_w = 0.01 I (rad/s)^2``,
``Q_g = 0.24 I (m/s^2)^2``, ``Q_eta = 0.32 rad^2``. The printed ``Q_n = 7.3e-10`` has no unit;
we read it as T^2 of the field and divide by the square of a 50 uT field to get the variance of
the unit north vector (0.29). The paper has no gates; the shared gates of
:class:`~hrtls.attitude.base.CommonParams` are on by default (set them to ``inf`` to reproduce
the paper). Near pitch +-90 deg the Euler rates are singular: ``cos(pitch)`` is clamped to
``1e-3``.
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

__all__ = ["EulerEkf", "EulerEkfParams"]

_QW = K.PRM_SPECIFIC
_QG = K.PRM_SPECIFIC + 1
_QN = K.PRM_SPECIFIC + 2
_QETA = K.PRM_SPECIFIC + 3
_P0 = K.PRM_SPECIFIC + 4
_EXACT = K.PRM_SPECIFIC + 5
_SIZE = K.PRM_SPECIFIC + 6

_COS_MIN = 1e-3


@dataclass(frozen=True, kw_only=True)
class EulerEkfParams(CommonParams):
    """Parameters of the Euler-angle EKF (Colombo Sec. V-1 defaults).

    Attributes
    ----------
    gyro_var_rad2_s2:
        ``Q_w``, variance of each gyro axis, (rad/s)^2.
    acc_var_m2_s4:
        ``Q_g``, variance of each accelerometer axis, (m/s^2)^2.
    north_var:
        ``Q_n``, variance of each component of the unit north vector (dimensionless).
    yaw_var_rad2:
        ``Q_eta``, variance of the yaw pseudo-measurement, rad^2.
    p0_var_rad2:
        ``P(0)``, initial variance of each angle, rad^2.
    exact_propagation:
        Propagate the angles by composing rotations, ``R+ = R(theta) exp([w]x T)``, instead of
        the first-order step of eq. 5 (of which it is the exact form); the covariance still
        follows eq. 6. This keeps the state right through fast rotations and near pitch
        +-90 deg, where eq. 5 diverges.
    """

    gyro_var_rad2_s2: float = 0.01
    acc_var_m2_s4: float = 0.24
    north_var: float = 7.3e-10 / (50e-6) ** 2
    yaw_var_rad2: float = 0.32
    p0_var_rad2: float = 0.001
    exact_propagation: bool = True

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        for name in ("gyro_var_rad2_s2", "acc_var_m2_s4", "north_var", "yaw_var_rad2",
                     "p0_var_rad2"):
            value = float(getattr(self, name))
            if not (np.isfinite(value) and value > 0.0):
                raise InputError(f"{name} = {value}", where="EulerEkfParams",
                                 expected="a finite positive number")

    def kernel_array(self) -> FloatArray:
        """Kernel parameter array."""
        p = np.zeros(_SIZE)
        p[: K.PRM_SPECIFIC] = self.common_array()
        p[_QW] = self.gyro_var_rad2_s2
        p[_QG] = self.acc_var_m2_s4
        p[_QN] = self.north_var
        p[_QETA] = self.yaw_var_rad2
        p[_P0] = self.p0_var_rad2
        p[_EXACT] = 1.0 if self.exact_propagation else 0.0
        return p


@numba.njit(**K.JIT)
def _wrap(a: float) -> float:
    """Wrap to (-pi, pi]."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@numba.njit(**K.JIT)
def _euler_to_quat(r: float, p: float, y: float) -> tuple[float, float, float, float]:
    cr = math.cos(0.5 * r)
    sr = math.sin(0.5 * r)
    cp = math.cos(0.5 * p)
    sp = math.sin(0.5 * p)
    cy = math.cos(0.5 * y)
    sy = math.sin(0.5 * y)
    w = cy * cp * cr + sy * sp * sr
    x = cy * cp * sr - sy * sp * cr
    yy = cy * sp * cr + sy * cp * sr
    z = sy * cp * cr - cy * sp * sr
    if w < 0.0:
        return -w, -x, -yy, -z
    return w, x, yy, z


@numba.njit(**K.JIT)
def _quat_to_euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    sp = max(-1.0, min(1.0, 2.0 * (w * y - z * x)))
    pitch = math.asin(sp)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


@numba.njit(**K.JIT)
def _sincos(w: float, x: float, y: float, z: float
            ) -> tuple[float, float, float, float, float, float]:
    """``sin/cos`` of roll, pitch, yaw of a unit quaternion, from its rotation matrix."""
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + w * z)
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    sp = max(-1.0, min(1.0, -r20))
    cp = math.sqrt(r21 * r21 + r22 * r22)
    if cp < _COS_MIN:  # gimbal lock: roll 0, the rotation is all yaw
        return 0.0, 1.0, sp, cp, 2.0 * (w * z - x * y), 1.0 - 2.0 * (x * x + z * z)
    return r21 / cp, r22 / cp, sp, cp, r10 / cp, r00 / cp


@numba.njit(**K.JIT)
def euler_ekf_kernel(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, has_gyr: bool,
    has_mag: bool, prm: FloatArray, x: FloatArray, P: FloatArray, aux: FloatArray,
    yaw_in: FloatArray, out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
) -> None:
    """Euler EKF over one chunk (Colombo eq. 5-11); mutates ``x``, ``P``, ``aux``.

    ``x = [roll, pitch, yaw, qw, qx, qy, qz]``: the angles and their quaternion (kept so that
    the exact propagation and the outputs need few trigonometric functions).
    """
    n = t.shape[0]
    has_yaw = yaw_in.shape[0] == n
    F = np.empty((3, 3))
    G = np.empty((3, 3))
    tmp = np.empty((3, 3))
    dx = np.empty(3)
    ph = np.empty((3, 3))
    g = prm[K.PRM_GRAVITY]
    qw = prm[_QW]
    exact = prm[_EXACT] > 0.5
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
        if aux[K.AUX_INIT] < 0.5:
            if acc_fin and acc_dev < prm[K.PRM_ACC_GATE]:
                w, qx, qy, qz = K.init_attitude(prm, a0, a1, a2, m0, m1, m2, mag_fin)
                x[0], x[1], x[2] = _quat_to_euler(w, qx, qy, qz)
                x[3], x[4], x[5], x[6] = _euler_to_quat(x[0], x[1], x[2])
                for r in range(3):
                    for c in range(3):
                        P[r, c] = prm[_P0] if r == c else 0.0
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
            # quaternion of the current angles (kept in x[3:7])
            cw = x[3]
            cx = x[4]
            cy_ = x[5]
            cz = x[6]
            moved = False
            # ---- prediction, eq. 5-6
            if gyr_fin and 0.0 < dt <= prm[K.PRM_MAX_DT]:
                if acc_fin and K.rest_and_bias(aux, prm, g0, g1, g2, a0, a1, a2, dt):
                    flags |= K.FLAG_REST
                wx = g0 - aux[K.AUX_BIAS]
                wy = g1 - aux[K.AUX_BIAS + 1]
                wz = g2 - aux[K.AUX_BIAS + 2]
                sr, cr, sp, cp, _, _ = _sincos(cw, cx, cy_, cz)
                if abs(cp) < _COS_MIN:
                    cp = _COS_MIN
                tp_ = sp / cp
                sec = 1.0 / cp
                u = sr * wy + cr * wz  # appears in the roll and yaw rates
                v = cr * wy - sr * wz
                # E(theta) (z-y-x rates), G = T E
                G[0, 0] = dt
                G[0, 1] = dt * sr * tp_
                G[0, 2] = dt * cr * tp_
                G[1, 0] = 0.0
                G[1, 1] = dt * cr
                G[1, 2] = -dt * sr
                G[2, 0] = 0.0
                G[2, 1] = dt * sr * sec
                G[2, 2] = dt * cr * sec
                # F = I + T d(E w)/d(theta)
                F[0, 0] = 1.0 + dt * tp_ * v
                F[0, 1] = dt * u * sec * sec
                F[0, 2] = 0.0
                F[1, 0] = -dt * u
                F[1, 1] = 1.0
                F[1, 2] = 0.0
                F[2, 0] = dt * v * sec
                F[2, 1] = dt * u * tp_ * sec
                F[2, 2] = 1.0
                if exact:
                    # R+ = R(theta) exp([w]x dt): quaternion step, back to angles
                    n_w = math.sqrt(wx * wx + wy * wy + wz * wz)
                    ch, sc = K.cos_sinc(0.5 * n_w * dt)
                    sk = 0.5 * dt * sc
                    cw, cx, cy_, cz = K.qmul(cw, cx, cy_, cz, ch, sk * wx, sk * wy, sk * wz)
                    nq = math.sqrt(cw * cw + cx * cx + cy_ * cy_ + cz * cz)
                    if cw < 0.0:
                        nq = -nq
                    cw /= nq
                    cx /= nq
                    cy_ /= nq
                    cz /= nq
                    x[0], x[1], x[2] = _quat_to_euler(cw, cx, cy_, cz)
                else:
                    # eq. 5
                    x[0] = _wrap(x[0] + dt * (wx + tp_ * u))
                    x[1] += dt * v
                    x[2] = _wrap(x[2] + dt * u * sec)
                    cw, cx, cy_, cz = _euler_to_quat(x[0], x[1], x[2])
                moved = True
                for r in range(3):
                    for c in range(3):
                        tmp[r, c] = F[r, 0] * P[0, c] + F[r, 1] * P[1, c] + F[r, 2] * P[2, c]
                for r in range(3):
                    for c in range(r, 3):
                        val = tmp[r, 0] * F[c, 0] + tmp[r, 1] * F[c, 1] + tmp[r, 2] * F[c, 2]
                        val += qw * (G[r, 0] * G[c, 0] + G[r, 1] * G[c, 1]
                                     + G[r, 2] * G[c, 2])
                        P[r, c] = val
                        P[c, r] = val
                flags |= K.FLAG_GYR
            elif has_gyr:
                aux[K.AUX_N_GYR_REJ] += 1.0
            # ---- measurements, eq. 3-4 and 7, at the prediction
            sr, cr, sp, cp, sy, cy = _sincos(cw, cx, cy_, cz)
            ux = -sp
            uy = cp * sr
            uz = cp * cr
            use_a = acc_fin and acc_dev < prm[K.PRM_ACC_GATE]
            use_m = False
            if mag_fin and K.mag_gate(aux, prm, m0, m1, m2, ux, uy, uz, dt):
                md = m0 * ux + m1 * uy + m2 * uz
                z0 = m0 - md * ux
                z1 = m1 - md * uy
                z2 = m2 - md * uz
                zn = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
                use_m = zn > 1e-9
            use_y = False
            if has_yaw:
                yv = yaw_in[i]
                use_y = math.isfinite(yv)
            if use_a or use_m or use_y:
                for r in range(3):
                    dx[r] = 0.0
                if use_a:
                    # h = R^T [0, 0, g]
                    jac = ((0.0, -g * cp, 0.0),
                           (g * cp * cr, -g * sp * sr, 0.0),
                           (-g * cp * sr, -g * sp * cr, 0.0))
                    use_a = K.block3_update(P, dx, jac, a0 - g * ux, a1 - g * uy, a2 - g * uz,
                                            prm[_QG], ph)
                if use_m:
                    # h = R^T [0, 1, 0] (north)
                    h0 = sy * cp
                    h1 = sy * sp * sr + cy * cr
                    h2 = sy * sp * cr - cy * sr
                    jac = ((0.0, -sy * sp, cy * cp),
                           (sy * sp * cr - cy * sr, sy * cp * sr, cy * sp * sr - sy * cr),
                           (-sy * sp * sr - cy * cr, sy * cp * cr, cy * sp * cr + sy * sr))
                    use_m = K.block3_update(P, dx, jac, z0 / zn - h0, z1 / zn - h1,
                                            z2 / zn - h2, prm[_QN], ph)
                if use_y:
                    # eta_z = C theta, C = [0, 0, 1] (eq. 1, 10)
                    s = P[2, 2] + prm[_QETA]
                    innov = _wrap(yv - x[2]) - dx[2]
                    k0 = P[0, 2] / s
                    k1 = P[1, 2] / s
                    k2 = P[2, 2] / s
                    dx[0] += k0 * innov
                    dx[1] += k1 * innov
                    dx[2] += k2 * innov
                    kk = (k0, k1, k2)
                    pp = (P[0, 2], P[1, 2], P[2, 2])
                    for r in range(3):
                        for c in range(r, 3):
                            val = P[r, c] - kk[r] * pp[c]
                            P[r, c] = val
                            P[c, r] = val
                ok = True
                for r in range(3):
                    ok = ok and math.isfinite(dx[r]) and math.isfinite(P[r, r])
                if ok:
                    x[0] = _wrap(x[0] + dx[0])
                    x[1] += dx[1]
                    x[2] = _wrap(x[2] + dx[2])
                    if x[1] > 0.5 * math.pi or x[1] < -0.5 * math.pi:
                        # pitch left its range: the same attitude with pitch folded back
                        x[1] = math.copysign(math.pi, x[1]) - x[1]
                        x[0] = _wrap(x[0] + math.pi)
                        x[2] = _wrap(x[2] + math.pi)
                    moved = True
                    cw, cx, cy_, cz = _euler_to_quat(x[0], x[1], x[2])
                else:
                    # numerical failure: keep the prediction, restart the covariance
                    use_a = False
                    use_m = False
                    for r in range(3):
                        for c in range(3):
                            P[r, c] = prm[_P0] if r == c else 0.0
            if use_a:
                flags |= K.FLAG_ACC
            else:
                aux[K.AUX_N_ACC_REJ] += 1.0
            if use_m:
                flags |= K.FLAG_MAG
            elif has_mag:
                aux[K.AUX_N_MAG_REJ] += 1.0
            if moved:
                x[3] = cw
                x[4] = cx
                x[5] = cy_
                x[6] = cz
        out_q[i, 0] = x[3]
        out_q[i, 1] = x[4]
        out_q[i, 2] = x[5]
        out_q[i, 3] = x[6]
        out_var[i, 0] = P[0, 0]
        out_var[i, 1] = P[1, 1]
        out_var[i, 2] = P[2, 2]
        out_flags[i] = flags


class EulerEkf(AttitudeFilter):
    """Euler-angle EKF (Colombo Sec. III-B) with an optional yaw pseudo-measurement.

    ``update(t, acc, gyr, mag, yaw_rad=...)`` takes the yaw input of eq. 10 as an (N,) array,
    NaN where no yaw measurement exists.
    """

    name: ClassVar[str] = "euler-ekf"
    params_type: ClassVar[type[CommonParams]] = EulerEkfParams

    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        # roll, pitch, yaw and their quaternion
        return np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), np.zeros((3, 3))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        unknown = set(inputs) - {"yaw_rad"}
        if unknown:
            raise InputError(f"unexpected inputs {sorted(unknown)}", where=self.name,
                             expected="optional yaw_rad only")
        yaw = inputs.get("yaw_rad", np.empty(0))
        euler_ekf_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux, yaw, out_q,
                         out_var, out_flags)
