"""Device presets: the sensor units the papers used, with their error values.

Values come from the papers or are datasheet-class numbers.

Values marked *paper* are quoted from the papers; *datasheet* values are typical figures of
that sensor class (rounded); *assumed* values are residuals after the calibration the papers
describe (Inderst App. B) and are our choice. ``g = 9.80665 m/s^2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2
from hrtls.sim.errors import SensorErrorModel

DEG = np.pi / 180.0
UG = 1e-6 * GRAVITY_M_S2


@dataclass(frozen=True, slots=True, kw_only=True)
class DeviceModel:
    """A sensor unit: rates, clock jitter and one error model per sensor.

    Attributes
    ----------
    name: preset name.
    rate_hz: accelerometer / gyroscope rate, Hz.
    mag_rate_hz: magnetometer rate, Hz.
    baro_rate_hz: barometer rate, Hz.
    jitter_s: standard deviation of the sample-time jitter, s.
    accel, gyro, mag: error models (m/s^2, rad/s, uT).
    baro: barometer error model (Pa), or None when the unit has none.
    description: where the values come from.
    """

    name: str
    rate_hz: float
    mag_rate_hz: float
    baro_rate_hz: float = 10.0
    jitter_s: float = 0.0
    accel: SensorErrorModel
    gyro: SensorErrorModel
    mag: SensorErrorModel
    baro: SensorErrorModel | None = None
    description: str = ""

    def with_rate(self, rate_hz: float, mag_rate_hz: float | None = None) -> DeviceModel:
        """The same device sampled at another rate."""
        from dataclasses import replace

        return replace(self, rate_hz=rate_hz,
                       mag_rate_hz=min(self.mag_rate_hz, rate_hz) if mag_rate_hz is None
                       else mag_rate_hz)


def _colombo_platform() -> DeviceModel:
    # BMA180: 150 ug/sqrt(Hz), 14 bit (paper); +-2 g range (datasheet)
    # IMU-3000: 1.74e-4 rad/s/sqrt(Hz), 16 bit (paper); +-500 deg/s range (datasheet)
    # HMC5883: 12 bit (paper); 0.92 mG/LSB at +-1.3 G, ~2 mG noise (datasheet)
    return DeviceModel(
        name="bma180_imu3000", rate_hz=250.0, mag_rate_hz=75.0, jitter_s=2e-5,
        accel=SensorErrorModel(noise_density=150 * UG, bias_sigma=0.02, bias_walk_density=1e-4,
                               scale_sigma=0.005, misalignment_sigma_rad=0.3 * DEG,
                               resolution=4 * GRAVITY_M_S2 / 2**14,
                               full_scale=2 * GRAVITY_M_S2),
        gyro=SensorErrorModel(noise_density=1.74e-4, bias_sigma=0.05 * DEG,
                              bias_walk_density=2e-5, scale_sigma=0.01,
                              misalignment_sigma_rad=0.3 * DEG,
                              resolution=1000 * DEG / 2**16, full_scale=500 * DEG),
        mag=SensorErrorModel(noise_density=0.2 / np.sqrt(37.5), bias_sigma=1.0,
                             scale_sigma=0.01, resolution=0.092, full_scale=130.0),
        description="Colombo Sec. IV-A wearable platform: Bosch BMA180 + InvenSense IMU-3000 + "
                    "Honeywell HMC5883 at 250 Hz (noise densities from the paper)",
    )


def _smartphone_mpu6150() -> DeviceModel:
    # MPU-6150 in a Samsung Galaxy S5 Neo (Inderst Tab. 6.3): +-2 g, +-250 deg/s, +-1200 uT;
    # 100 Hz accelerometer / gyroscope, 50 Hz magnetometer (Inderst Sec. 6.3.1)
    return DeviceModel(
        name="mpu6150_phone", rate_hz=100.0, mag_rate_hz=50.0, jitter_s=1e-3,
        accel=SensorErrorModel(noise_density=400 * UG, bias_sigma=0.05, bias_walk_density=2e-4,
                               scale_sigma=0.01, misalignment_sigma_rad=0.5 * DEG,
                               resolution=4 * GRAVITY_M_S2 / 2**16,
                               full_scale=2 * GRAVITY_M_S2),
        gyro=SensorErrorModel(noise_density=0.005 * DEG, bias_sigma=0.3 * DEG,
                              bias_walk_density=5e-5, scale_sigma=0.01,
                              misalignment_sigma_rad=0.5 * DEG,
                              resolution=500 * DEG / 2**16, full_scale=250 * DEG),
        mag=SensorErrorModel(noise_density=0.4 / 5.0, bias_sigma=5.0, scale_sigma=0.02,
                             resolution=0.3, full_scale=1200.0),
        description="Smartphone MPU-6150 class (Inderst Tab. 6.3 ranges and rates; "
                    "noise from the MPU-6050/6150 datasheet class; residual biases assumed)",
    )


def _mpu9150_motionfit() -> DeviceModel:
    phone = _smartphone_mpu6150()
    from dataclasses import replace

    return replace(phone, name="mpu9150_motionfit", jitter_s=1e-4,
                   description="InvenSense MPU-9150 MotionFit (Inderst Tab. 6.2 ranges), "
                               "100 Hz; MPU-6150-class noise")


def _inemo() -> DeviceModel:
    # iNEMO STEVAL-MKI062V2 (Inderst Tab. 6.1): LSM303DLH +-2 g / magnetometer +-1.3 G,
    # LPR430AL + LY330ALH gyros +-300 deg/s, LPS001DL barometer; 100 Hz (Inderst Sec. 6.3.2)
    return DeviceModel(
        name="inemo", rate_hz=100.0, mag_rate_hz=100.0, baro_rate_hz=10.0, jitter_s=1e-4,
        accel=SensorErrorModel(noise_density=250 * UG, bias_sigma=0.04, bias_walk_density=2e-4,
                               scale_sigma=0.01, misalignment_sigma_rad=0.5 * DEG,
                               resolution=1e-3 * GRAVITY_M_S2, full_scale=2 * GRAVITY_M_S2),
        gyro=SensorErrorModel(noise_density=0.014 * DEG, bias_sigma=0.5 * DEG,
                              bias_walk_density=1e-4, scale_sigma=0.01,
                              misalignment_sigma_rad=0.5 * DEG,
                              resolution=600 * DEG / 2**12, full_scale=300 * DEG),
        mag=SensorErrorModel(noise_density=0.3 / np.sqrt(50.0), bias_sigma=2.0,
                             scale_sigma=0.02, resolution=0.09, full_scale=130.0),
        baro=SensorErrorModel(noise_density=8.0 / np.sqrt(5.0), bias_sigma=50.0,
                              bias_walk_density=0.5, resolution=6.5),
        description="STMicroelectronics iNEMO STEVAL-MKI062V2 (Inderst Tab. 6.1 sensors; "
                    "noise figures datasheet-class)",
    )


def _xsens_mti() -> DeviceModel:
    # Xsens MTi / MTi-G class (Basso Sec. IV): acc +-50 m/s^2, 0.002 m/s^2/sqrt(Hz);
    # gyro +-300 deg/s, 0.05 deg/s/sqrt(Hz), bias stability ~1 deg/s; mag 0.05 uT noise
    return DeviceModel(
        name="xsens_mti", rate_hz=100.0, mag_rate_hz=100.0, jitter_s=0.0,
        accel=SensorErrorModel(noise_density=0.002, bias_sigma=0.02, bias_walk_density=5e-5,
                               scale_sigma=0.003, misalignment_sigma_rad=0.1 * DEG,
                               resolution=1e-3, full_scale=50.0),
        gyro=SensorErrorModel(noise_density=0.05 * DEG, bias_sigma=0.2 * DEG,
                              bias_walk_density=3e-5, scale_sigma=0.003,
                              misalignment_sigma_rad=0.1 * DEG, resolution=1e-4,
                              full_scale=300 * DEG),
        mag=SensorErrorModel(noise_density=0.05 / np.sqrt(50.0), bias_sigma=0.5,
                             scale_sigma=0.005, resolution=0.01, full_scale=75.0),
        description="Xsens MTi / MTi-G class (datasheet-class values)",
    )


def _tarrio_sim() -> DeviceModel:
    # Tarrio Sec. IV: accelerometer noise sigma = 5.7575e-2 m/s^2 at 50 Hz, gyro bias 10 deg/h
    return DeviceModel(
        name="tarrio_sim", rate_hz=50.0, mag_rate_hz=50.0, jitter_s=0.0,
        accel=SensorErrorModel.from_sigma(5.7575e-2, 50.0),
        gyro=SensorErrorModel(bias_fixed=(10 * DEG / 3600,) * 3),
        mag=SensorErrorModel(noise_density=0.05),
        description="Tarrio Sec. IV simulation: white accelerometer noise of 5.7575e-2 m/s^2 "
                    "per sample at 50 Hz and a 10 deg/h gyroscope bias (paper values)",
    )


def _ideal() -> DeviceModel:
    none = SensorErrorModel()
    return DeviceModel(name="ideal", rate_hz=100.0, mag_rate_hz=100.0, accel=none, gyro=none,
                       mag=none, baro=none, description="no sensor errors (for tests)")


DEVICES = {
    "bma180_imu3000": _colombo_platform,
    "mpu6150_phone": _smartphone_mpu6150,
    "mpu9150_motionfit": _mpu9150_motionfit,
    "inemo": _inemo,
    "xsens_mti": _xsens_mti,
    "tarrio_sim": _tarrio_sim,
    "ideal": _ideal,
}


def get_device(name: str) -> DeviceModel:
    """A device preset by name (see :data:`DEVICES`)."""
    try:
        return DEVICES[name]()
    except KeyError:
        raise InputError(f"unknown device {name!r}", where="device",
                         expected="one of " + ", ".join(sorted(DEVICES))) from None
