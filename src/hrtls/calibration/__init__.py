"""Sensor calibration (Inderst App. B): six-position, rate test, magnetometer fit."""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hrtls.calibration.imu import (
        AXIS_POSITIONS,
        Calibration,
        MagnetometerFit,
        accelerometer_six_position,
        fit_magnetometer,
        gyroscope_rate_test,
        six_position_from_means,
    )

__all__ = [
    "AXIS_POSITIONS",
    "Calibration",
    "MagnetometerFit",
    "accelerometer_six_position",
    "fit_magnetometer",
    "gyroscope_rate_test",
    "six_position_from_means",
]


def __getattr__(name: str) -> Any:
    """The calibration procedures, imported when first asked for (not by their submodules)."""
    if name in __all__:
        from hrtls.calibration import imu

        return getattr(imu, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
