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
the paper). Our extensions against the centripetal acceleration of tight turns (Colombo's
Case A circle: r ~ 1 m at ~1.5-1.9 m/s, 2-4 m/s^2 sideways, which the paper's constant ``Q_g``
turns into several degrees of tilt and a biased forward acceleration for the velocity
automaton): ``Q_g`` grows with the rate of turn, ``Q_g (1 + (|w| / rate_ref_rad_s)^2)``, and
the ``| |a| - g |`` gate is 0.5 m/s^2 instead of the common 1.0. ``rate_ref_rad_s=inf`` and
``acc_gate_m_s2=inf`` give the paper's filter. A second extension, against the accelerations of
walking itself (the paper's ``Q_g`` with its large ``Q_w`` tilts the estimate towards a
start-up acceleration within ~0.5 s, so that the levelled forward acceleration the velocity
automaton integrates came out at about half its value): the running variance ``s^2`` of the
specific force in ENU (window ``dyn_acc_window_s``) is read as a coloured disturbance of
correlation time ``dyn_acc_corr_s`` and added as its white-noise equivalent,
``Q_g' = Q_g (1 + (|w| / rate_ref)^2) + 2 s^2 tau / T`` (``dyn_acc_corr_s=0`` for the paper).
Near pitch +-90 deg the Euler rates are
singular: ``cos(pitch)`` is clamped to ``1e-3``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

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

__all__ = ["EulerEkf", "EulerEkfParams"]

_QW = K.PRM_SPECIFIC
_QG = K.PRM_SPECIFIC + 1
_QN = K.PRM_SPECIFIC + 2
_QETA = K.PRM_SPECIFIC + 3
_P0 = K.PRM_SPECIFIC + 4
_EXACT = K.PRM_SPECIFIC + 5
_RATE_REF = K.PRM_SPECIFIC + 6
_DYN_TAU = K.PRM_SPECIFIC + 7
_DYN_CORR = K.PRM_SPECIFIC + 8

_COS_MIN = 1e-3


@dataclass(frozen=True, kw_only=True)
class EulerEkfParams(CommonParams):
    """Parameters of the Euler-angle EKF (Colombo Sec. V-1 defaults).

    Attributes
    ----------
    acc_gate_m_s2:
        The shared ``| |a| - g |`` gate, tighter here than the common 1.0 m/s^2: the Euler EKF
        has no other defence against the centripetal acceleration of tight turns (``inf`` for
        the paper, which has no gate).
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
    rate_ref_rad_s:
        Rate-of-turn scale of the accelerometer variance: ``Q_g (1 + (|w| / rate_ref)^2)``
        with ``|w|`` the bias-corrected gyro rate (our extension, as in
        :mod:`~hrtls.attitude.quat_ekf`: while turning, the centripetal acceleration makes the
        specific force a biased gravity reference and tilts the estimate; on a 1 m circle at
        walking speed it is ~3 m/s^2, ~15 deg). ``inf`` gives the constant ``Q_g`` of the
        paper.
    dyn_acc_window_s:
        Time constant of the running variance of the body's acceleration (the specific force
        rotated into ENU with the predicted attitude), s.
    dyn_acc_corr_s:
        Correlation time ``tau`` of the body's acceleration, s (our extension; 0 gives the
        paper's ``Q_g``). While walking, the specific force is gravity plus an acceleration
        of ~1 m/s^2 that stays on one side for a large part of a step or, when starting or
        stopping, for seconds; with the paper's ``Q_g`` it tilts the estimate (the levelled
        forward acceleration of a start from rest came out at half its value). A disturbance
        of variance ``s^2`` and correlation time ``tau`` acts on a slower filter like white
        noise of density ``2 s^2 tau``, i.e. a per-sample variance ``2 s^2 tau / T``, which
        is added to ``Q_g``: at rest it vanishes, while walking it makes the tilt follow the
        gyroscope over several seconds.
    exact_propagation:
        Propagate the angles by composing rotations, ``R+ = R(theta) exp([w]x T)``, instead of
        the first-order step of eq. 5 (of which it is the exact form); the covariance still
        follows eq. 6. This keeps the state right through fast rotations and near pitch
        +-90 deg, where eq. 5 diverges.
    """

    acc_gate_m_s2: float = 0.5
    gyro_var_rad2_s2: float = 0.01
    acc_var_m2_s4: float = 0.24
    north_var: float = 7.3e-10 / (50e-6) ** 2
    yaw_var_rad2: float = 0.32
    p0_var_rad2: float = 0.001
    exact_propagation: bool = True
    rate_ref_rad_s: float = 0.5
    dyn_acc_window_s: float = 1.0
    dyn_acc_corr_s: float = 0.1

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        self._require_positive(("gyro_var_rad2_s2", "acc_var_m2_s4", "north_var",
                                "yaw_var_rad2", "p0_var_rad2", "rate_ref_rad_s",
                                "dyn_acc_window_s"),
                               inf_ok=("rate_ref_rad_s",))
        if not (math.isfinite(self.dyn_acc_corr_s) and self.dyn_acc_corr_s >= 0.0):
            raise InputError(f"dyn_acc_corr_s = {self.dyn_acc_corr_s}", where="EulerEkfParams",
                             expected="a finite value >= 0 s (0: the paper's constant Q_g)")

    def specific_values(self) -> tuple[float, ...]:
        """Kernel parameters ``_QW`` .. ``_DYN_CORR``."""
        return (self.gyro_var_rad2_s2, self.acc_var_m2_s4, self.north_var, self.yaw_var_rad2,
                self.p0_var_rad2, 1.0 if self.exact_propagation else 0.0,
                self.rate_ref_rad_s, self.dyn_acc_window_s, self.dyn_acc_corr_s)


@njit(**JIT)
def _wrap(a: float) -> float:
    """Wrap to (-pi, pi]."""
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(**JIT)
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


@njit(**JIT)
def _quat_to_euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    sp = max(-1.0, min(1.0, 2.0 * (w * y - z * x)))
    pitch = math.asin(sp)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


@njit(**JIT)
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


@njit(**JIT)
def _reset_cov(P: FloatArray, prm: FloatArray) -> None:
    """``P(0) = p0 I``."""
    for r in range(3):
        for c in range(3):
            P[r, c] = prm[_P0] if r == c else 0.0


@njit(**JIT)
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
    acc_rate_k = 1.0 / prm[_RATE_REF] ** 2
    dyn_tau = prm[_DYN_TAU]
    dyn_k = 2.0 * prm[_DYN_CORR]  # Q_dyn = 2 s^2 tau / T
    for i in range(n):
        s = K.read_sample(t, acc, gyr, mag, i, has_gyr, has_mag, prm, aux)
        dt = s.dt
        if aux[K.AUX_INIT] < 0.5:
            flags, w, qx, qy, qz = K.try_init(aux, prm, s, has_mag)
            if flags == 0:
                K.write_uninit(out_q, out_var, out_flags, i)
                continue
            x[0], x[1], x[2] = _quat_to_euler(w, qx, qy, qz)
            x[3], x[4], x[5], x[6] = _euler_to_quat(x[0], x[1], x[2])
            _reset_cov(P, prm)
        else:
            flags = K.FLAG_VALID
            # quaternion of the current angles (kept in x[3:7])
            cw = x[3]
            cx = x[4]
            cy_ = x[5]
            cz = x[6]
            moved = False
            rate2 = 0.0
            # ---- prediction, eq. 5-6
            gflags = K.gyro_step(aux, prm, s, has_gyr)
            if gflags:
                flags |= gflags
                wx, wy, wz = K.unbiased_rate(aux, s)
                rate2 = wx * wx + wy * wy + wz * wz
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
                    cw, cx, cy_, cz = Q.gyro_quat_step(cw, cx, cy_, cz, wx, wy, wz, dt)
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
            # ---- measurements, eq. 3-4 and 7, at the prediction
            sr, cr, sp, cp, sy, cy = _sincos(cw, cx, cy_, cz)
            ux = -sp
            uy = cp * sr
            uz = cp * cr
            use_a = s.acc_fin and s.acc_dev < prm[K.PRM_ACC_GATE]
            q_dyn = 0.0
            if s.acc_fin and dyn_k > 0.0:
                var_dyn = K.dynamic_acc_var(aux, s, cw, cx, cy_, cz, dyn_tau)
                if dt > 0.0:
                    q_dyn = dyn_k * var_dyn / dt
            use_m = False
            if s.mag_fin and K.mag_gate(aux, prm, s.m0, s.m1, s.m2, ux, uy, uz, dt):
                z0, z1, z2, zn = K.horizontal_unit(s.m0, s.m1, s.m2, ux, uy, uz)
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
                    use_a = EK.block3_update(P, dx, jac, s.a0 - g * ux, s.a1 - g * uy,
                                            s.a2 - g * uz,
                                            prm[_QG] * (1.0 + rate2 * acc_rate_k) + q_dyn,
                                            ph)
                if use_m:
                    # h = R^T [0, 1, 0] (north)
                    h0 = sy * cp
                    h1 = sy * sp * sr + cy * cr
                    h2 = sy * sp * cr - cy * sr
                    jac = ((0.0, -sy * sp, cy * cp),
                           (sy * sp * cr - cy * sr, sy * cp * sr, cy * sp * sr - sy * cr),
                           (-sy * sp * sr - cy * cr, sy * cp * cr, cy * sp * cr + sy * sr))
                    use_m = EK.block3_update(P, dx, jac, z0 / zn - h0, z1 / zn - h1,
                                            z2 / zn - h2, prm[_QN], ph)
                if use_y:
                    # eta_z = C theta, C = [0, 0, 1] (eq. 1, 10)
                    s_eta = P[2, 2] + prm[_QETA]
                    innov = _wrap(yv - x[2]) - dx[2]
                    k0 = P[0, 2] / s_eta
                    k1 = P[1, 2] / s_eta
                    k2 = P[2, 2] / s_eta
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
                if EK.update_finite(dx, P):
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
                    _reset_cov(P, prm)
            flags = K.count_used(aux, flags, use_a, use_m, has_mag)
            if moved:
                Q.set_q(x, 3, cw, cx, cy_, cz)
        Q.write_q(out_q, i, x[3], x[4], x[5], x[6])
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
    extra_inputs: ClassVar[tuple[str, ...]] = ("yaw_rad",)

    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        # roll, pitch, yaw and their quaternion
        return np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), np.zeros((3, 3))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        yaw = inputs.get("yaw_rad", np.empty(0))
        euler_ekf_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux, yaw, out_q,
                         out_var, out_flags)
