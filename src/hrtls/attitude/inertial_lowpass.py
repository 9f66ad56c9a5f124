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

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from hrtls.attitude import _inertial_lowpass_kernel as ILK
from hrtls.attitude import _kernels as K
from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.errors import InputError
from hrtls.frames import FloatArray

__all__ = ["InertialLowpass", "InertialLowpassParams"]

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
        """Shared part; the rest detector runs without its own bias update (see ``BIAS_EST``)."""
        p = CommonParams.common_array(self)
        p[K.PRM_BIAS_EST] = 0.0
        return p

    def specific_values(self) -> tuple[float, ...]:
        """Kernel parameters ``TAU_ACC`` .. ``WALK`` (see the kernel module)."""
        return (self.tau_acc_s, self.tau_mag_s, 1.0 if self.estimate_bias else 0.0,
                self.bias_sigma_init_rad_s, self.bias_forgetting_s, self.bias_clip_rad_s,
                self.bias_sigma_motion_rad_s, self.bias_vertical_forgetting,
                self.bias_sigma_rest_rad_s, self.mag_current_tau_s, self.mag_ref_tau_s,
                self.mag_new_first_s, self.mag_new_min_rate_rad_s, self.mag_min_undisturbed_s,
                self.mag_max_rejection_s, self.mag_rejection_factor, self.tilt_sigma_rad,
                self.heading_sigma_rad, self.attitude_walk_rad_s)


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
        x = np.zeros(ILK.NX)
        x[ILK.QG] = 1.0
        x[ILK.QA] = 1.0
        x[ILK.HC] = 1.0
        return x, np.zeros((3, 3))

    def _kernel(self, t: FloatArray, acc: FloatArray, gyr: FloatArray, mag: FloatArray,
                has_gyr: bool, has_mag: bool, x: FloatArray, P: FloatArray, aux: FloatArray,
                out_q: FloatArray, out_var: FloatArray, out_flags: NDArray[np.uint8],
                out_extra: FloatArray, **inputs: FloatArray) -> None:
        ILK.inertial_lowpass_kernel(t, acc, gyr, mag, has_gyr, has_mag, self._prm, x, P, aux,
                                out_q, out_var, out_flags, out_extra)
