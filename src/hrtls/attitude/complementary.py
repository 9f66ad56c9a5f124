"""Complementary attitude filter with the FQA static quaternion (Inderst Sec. 4.2.2, eq. 4.20).

Per sample:

1. Dynamic quaternion ``q_delta = exp(Omega dt) q_{k-1}`` from the bias-corrected gyro rate
   (eq. 4.10-4.12).
2. Static quaternions from the FQA (:mod:`hrtls.attitude.fqa`). We blend in two steps, each an
   instance of eq. 4.20 ``q = gamma q_sigma + (1 - gamma) q_delta``:

   * tilt: ``q_sigma`` = FQA(measured ``a``, field predicted by ``q_delta``), gain ``gamma_a``;
   * heading: ``q_sigma`` = FQA(vertical of the tilt-corrected ``q``, measured ``m``), gain
     ``gamma_m``.

   Substituting the prediction for the sensor that is not blended keeps a magnetic disturbance
   from tilting the estimate and an acceleration from turning it (the thesis blends one static
   quaternion; it does not say how an untrustworthy sensor is left out).
3. Adaptive gains (the thesis: "set according to the reliability of the measurements"):
   ``gamma = (1 - exp(-dt / tau)) * w`` with the trust weight
   ``w = 1 / (1 + (|w| / w_ref)^2) * (1 - dev / gate)``, where ``dev`` is ``| |a| - g |`` for
   the accelerometer and ``| |m| - |m_ref| |`` for the magnetometer; ``w = 0`` when the sample
   fails the gates of :class:`~hrtls.attitude.base.CommonParams` (norm, dip, jump).
4. Sign: ``q_sigma`` is negated when ``q_sigma . q_delta < 0`` before blending; the blend is
   normalised.
5. Gyro bias in motion (our extension): the blends' corrections (device frame; the tilt one
   fully, the heading one only about the vertical) feed an integral term
   ``b <- b - delta / tau_bias``, so a constant bias is removed with time constant
   ``tau_bias`` (plus the rest estimator of :mod:`hrtls.attitude.bias`).

There is no covariance: ``var_rpy`` is ``None``; ``extra`` holds ``gain_acc`` and ``gain_mag``
(the per-sample blending gains, a measure of how much the static sensors were trusted). The
thesis gives no gain values; the defaults were chosen on ``benchmarks/attitude.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _kernels as K
from hrtls.attitude import _quaternion as Q
from hrtls.attitude._jit import JIT
from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.attitude.fqa import fqa_quaternion
from hrtls.frames import FloatArray
from hrtls.kernels import njit

__all__ = ["ComplementaryFilter", "ComplementaryParams"]

_TAU_A = K.PRM_SPECIFIC
_TAU_M = K.PRM_SPECIFIC + 1
_W_REF = K.PRM_SPECIFIC + 2
_TAU_B = K.PRM_SPECIFIC + 3
_B_MAX = K.PRM_SPECIFIC + 4


@dataclass(frozen=True, kw_only=True)
class ComplementaryParams(CommonParams):
    """Parameters of the complementary filter.

    Attributes
    ----------
    tau_acc_s:
        Time constant of the tilt correction at full trust, s.
    tau_mag_s:
        Time constant of the heading correction at full trust, s.
    rate_ref_rad_s:
        Rate of turn at which the static sensors' trust halves, rad/s.
    tau_bias_s:
        Time constant of the in-motion gyro-bias integral term, s (``inf`` disables it).
    bias_max_rad_s:
        Bound on each bias component, rad/s.
    """

    tau_acc_s: float = 3.0
    tau_mag_s: float = 9.0
    rate_ref_rad_s: float = 2.0
    tau_bias_s: float = 100.0
    bias_max_rad_s: float = 0.1

    def __post_init__(self) -> None:
        CommonParams.__post_init__(self)
        names = ("tau_acc_s", "tau_mag_s", "rate_ref_rad_s", "tau_bias_s", "bias_max_rad_s")
        self._require_positive(names, inf_ok=names, expected="a positive number")

    def specific_values(self) -> tuple[float, ...]:
        """Kernel parameters ``_TAU_A`` .. ``_B_MAX``."""
        return (self.tau_acc_s, self.tau_mag_s, self.rate_ref_rad_s, self.tau_bias_s,
                self.bias_max_rad_s)


@njit(inline="always", **JIT)
def _blend(
    gam: float, sw: float, sx: float, sy: float, sz: float,
    dw: float, dx: float, dy: float, dz: float,
) -> tuple[float, float, float, float]:
    """Eq. 4.20 with the sign of ``q_sigma`` aligned to ``q_delta``, normalised."""
    if sw * dw + sx * dx + sy * dy + sz * dz < 0.0:
        sw, sx, sy, sz = -sw, -sx, -sy, -sz
    w = gam * sw + (1.0 - gam) * dw
    x = gam * sx + (1.0 - gam) * dx
    y = gam * sy + (1.0 - gam) * dy
    z = gam * sz + (1.0 - gam) * dz
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


@njit(**JIT)
def complementary_kernel(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray, has_gyr: bool,
    has_mag: bool, prm: FloatArray, x: FloatArray, aux: FloatArray, out_q: FloatArray,
    out_flags: NDArray[np.uint8], out_extra: FloatArray,
) -> None:
    """Complementary filter over one chunk (Inderst eq. 4.20); mutates ``x`` and ``aux``."""
    n = t.shape[0]
    no_var = np.empty((0, 3))
    for i in range(n):
        s = K.read_sample(t, acc, gyr, mag, i, has_gyr, has_mag, prm, aux)
        dt = s.dt
        gam_a = 0.0
        gam_m = 0.0
        if aux[K.AUX_INIT] < 0.5:
            flags, w, qx, qy, qz = K.try_init(aux, prm, s, has_mag)
            if flags == 0:
                K.write_uninit(out_q, no_var, out_flags, i)
                out_extra[i, 0] = 0.0
                out_extra[i, 1] = 0.0
                continue
            Q.set_q(x, 0, w, qx, qy, qz)
            gam_a = 1.0
            gam_m = 1.0 if flags & K.FLAG_MAG else 0.0
        else:
            flags = K.FLAG_VALID
            rate = 0.0
            # ---- dynamic quaternion, eq. 4.10-4.12
            gflags = K.gyro_step(aux, prm, s, has_gyr)
            if gflags:
                flags |= gflags
                wx, wy, wz = K.unbiased_rate(aux, s)
                rate = math.sqrt(wx * wx + wy * wy + wz * wz)
                dw, dxx, dy, dz = Q.gyro_quat_step(x[0], x[1], x[2], x[3], wx, wy, wz, dt)
            else:
                dw = x[0]
                dxx = x[1]
                dy = x[2]
                dz = x[3]
            trust = 1.0 / (1.0 + (rate / prm[_W_REF]) ** 2)
            step = dt if dt > 0.0 else 0.0
            # ---- tilt blend: FQA(a, predicted field) vs q_delta
            w, qx, qy, qz = dw, dxx, dy, dz
            use_a = s.acc_fin and s.acc_dev < prm[K.PRM_ACC_GATE]
            if use_a:
                gam_a = (1.0 - math.exp(-step / prm[_TAU_A])) * trust \
                    * (1.0 - s.acc_dev / prm[K.PRM_ACC_GATE])
                pn0, pn1, pn2 = Q.rot_t(w, qx, qy, qz, 0.0, 1.0, 0.0)
                sw, sx, sy, sz = fqa_quaternion(s.a0, s.a1, s.a2, pn0, pn1, pn2)
                w, qx, qy, qz = _blend(gam_a, sw, sx, sy, sz, w, qx, qy, qz)
            # ---- heading blend: FQA(vertical of q, m) vs q
            tw, tx, ty, tz = w, qx, qy, qz
            ux, uy, uz = Q.rot_t(w, qx, qy, qz, 0.0, 0.0, 1.0)
            use_m = s.mag_fin and K.mag_gate(aux, prm, s.m0, s.m1, s.m2, ux, uy, uz, dt)
            if use_m:
                m0 = s.m0
                m1 = s.m1
                m2 = s.m2
                mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
                dev = abs(mn - aux[K.AUX_MREF_N])
                gam_m = (1.0 - math.exp(-step / prm[_TAU_M])) * trust \
                    * max(0.0, 1.0 - dev / prm[K.PRM_MAG_NORM_GATE])
                sw, sx, sy, sz = fqa_quaternion(ux, uy, uz, m0, m1, m2)
                w, qx, qy, qz = _blend(gam_m, sw, sx, sy, sz, w, qx, qy, qz)
            flags = K.count_used(aux, flags, use_a, use_m, has_mag)
            # ---- in-motion bias: integral of the corrections (device frame); of the heading
            # correction only the part about the vertical counts (a magnetic error must not
            # leak into the tilt through the bias)
            if (flags & K.FLAG_GYR) and (gam_a > 0.0 or gam_m > 0.0) \
                    and prm[K.PRM_BIAS_EST] > 0.5:
                ew, ex, ey, ez = Q.qmul(dw, -dxx, -dy, -dz, tw, tx, ty, tz)
                sgn = 2.0 if ew >= 0.0 else -2.0
                c0 = sgn * ex
                c1 = sgn * ey
                c2 = sgn * ez
                ew, ex, ey, ez = Q.qmul(tw, -tx, -ty, -tz, w, qx, qy, qz)
                sgn = 2.0 if ew >= 0.0 else -2.0
                hv = sgn * (ex * ux + ey * uy + ez * uz)
                c0 += hv * ux
                c1 += hv * uy
                c2 += hv * uz
                bmax = prm[_B_MAX]
                kb = 1.0 / prm[_TAU_B]
                aux[K.AUX_BIAS] = min(bmax, max(-bmax, aux[K.AUX_BIAS] - c0 * kb))
                aux[K.AUX_BIAS + 1] = min(bmax, max(-bmax, aux[K.AUX_BIAS + 1] - c1 * kb))
                aux[K.AUX_BIAS + 2] = min(bmax, max(-bmax, aux[K.AUX_BIAS + 2] - c2 * kb))
            if w < 0.0:
                w, qx, qy, qz = -w, -qx, -qy, -qz
            Q.set_q(x, 0, w, qx, qy, qz)
        Q.write_q(out_q, i, x[0], x[1], x[2], x[3])
        out_flags[i] = flags
        out_extra[i, 0] = gam_a
        out_extra[i, 1] = gam_m


class ComplementaryFilter(AttitudeFilter):
    """Complementary filter with FQA static quaternion and adaptive gain (Inderst 4.2.2)."""

    name: ClassVar[str] = "complementary"
    params_type: ClassVar[type[CommonParams]] = ComplementaryParams
    has_covariance: ClassVar[bool] = False
    extra_outputs: ClassVar[tuple[str, ...]] = ("gain_acc", "gain_mag")

    def _new_xp(self) -> tuple[FloatArray, FloatArray]:
        return np.array([1.0, 0.0, 0.0, 0.0]), np.zeros((0, 0))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        complementary_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, aux, out_q,
                             out_flags, out_extra)
