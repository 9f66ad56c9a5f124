"""Attitude (orientation) estimation: EKFs, complementary and inertial low-pass filters, device.

All sensor-fusion filters share one interface (:class:`AttitudeFilter`): typed parameters, a
saveable state, ``update`` on chunks and ``run`` on a whole stream. Pick one by name with
:func:`make_filter` (``euler-ekf``, ``quat-ekf``, ``complementary``, ``inertial-lp``);
``device`` passes through an orientation the phone computed (:class:`DeviceOrientation`).
"""

from typing import TYPE_CHECKING, Any

from hrtls.attitude.base import AttitudeFilter, AttitudeResult, AttitudeState, CommonParams
from hrtls.attitude.bias import GyroBiasEstimate, estimate_gyro_bias, rest_mask
from hrtls.attitude.complementary import ComplementaryFilter, ComplementaryParams
from hrtls.attitude.device import DeviceOrientation, DeviceParams, frame_to_enu
from hrtls.attitude.euler_ekf import EulerEkf, EulerEkfParams
from hrtls.attitude.fqa import fqa, fqa_quaternion
from hrtls.attitude.inertial_lowpass import InertialLowpass, InertialLowpassParams
from hrtls.attitude.quat_ekf import QuatEkf, QuatEkfParams
from hrtls.attitude.registry import FILTERS, METHODS, make_filter

if TYPE_CHECKING:
    from hrtls.evaluate.orientation import OrientationErrors, orientation_errors

__all__ = [
    "FILTERS",
    "METHODS",
    "AttitudeFilter",
    "AttitudeResult",
    "AttitudeState",
    "CommonParams",
    "ComplementaryFilter",
    "ComplementaryParams",
    "DeviceOrientation",
    "DeviceParams",
    "EulerEkf",
    "EulerEkfParams",
    "GyroBiasEstimate",
    "InertialLowpass",
    "InertialLowpassParams",
    "OrientationErrors",
    "QuatEkf",
    "QuatEkfParams",
    "estimate_gyro_bias",
    "fqa",
    "fqa_quaternion",
    "frame_to_enu",
    "make_filter",
    "orientation_errors",
    "rest_mask",
]


def __getattr__(name: str) -> Any:
    """The orientation scores, imported when first asked for (tracking does not use them)."""
    if name in ("OrientationErrors", "orientation_errors"):
        from hrtls.evaluate import orientation

        return getattr(orientation, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
