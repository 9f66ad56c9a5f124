"""Sensor calibration (Inderst App. B): six-position, rate test, magnetometer fit."""

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
