"""Ideal inertial signals derived from the motion, and the simulated device streams.

Everything the device measures is derived from one sampled pose history, never drawn
independently:

* the waist position is the nominal path plus the gait displacement (rotated by the heading);
  the body attitude is ``q_nb = q(roll, pitch, heading + yaw oscillation)``;
* the device sits at ``lever_arm_b`` (body frame) and is rotated by the mounting ``q_bd``
  (device -> body): ``q_nd = q_nb q_bd``;
* acceleration is the second central difference of the device position, specific force is
  ``f = a - g`` with ``g = [0, 0, -9.80665]`` ENU, rotated into the device frame;
* angular rate is the mean of the rotation vectors of ``conj(q_k-1) q_k`` and ``conj(q_k) q_k+1``
  divided by ``dt`` (body rate at sample ``k``), rotated into the device frame.

So integrating the noiseless specific force with the true attitude reproduces the sampled
positions (exactly with the Stormer-Verlet rule), and the gyroscope integrates to the attitude.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from hrtls.data import ImuStream, OrientationSeries, SensorSeries
from hrtls.errors import InputError
from hrtls.frames import (
    GRAVITY_M_S2,
    quat_conjugate,
    quat_from_euler,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)
from hrtls.sim.devices import DeviceModel
from hrtls.sim.errors import ErrorRealization, apply_sensor_errors, realize_errors, sample_times
from hrtls.sim.gait_model import GaitResult
from hrtls.sim.magnetic import MagneticEnvironment
from hrtls.sim.motion_truth import MotionTruth

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BodyKinematics:
    """Pose history of the waist on the simulation grid.

    Attributes
    ----------
    t: uniform times, s.
    position: waist position including the gait oscillation, m (N, 3).
    q_nb: body attitude, scalar-first quaternions (N, 4).
    """

    t: FloatArray
    position: FloatArray
    q_nb: FloatArray


@dataclass(frozen=True, slots=True)
class IdealImu:
    """Noiseless device signals on the simulation grid.

    Attributes
    ----------
    t: times, s.
    specific_force: device-frame specific force, m/s^2 (N, 3).
    angular_rate: device-frame angular rate, rad/s (N, 3).
    q_nd: device attitude (device -> ENU) (N, 4).
    device_position: device position, m (N, 3).
    accel_n: device acceleration in ENU, m/s^2 (N, 3).
    """

    t: FloatArray
    specific_force: FloatArray
    angular_rate: FloatArray
    q_nd: FloatArray
    device_position: FloatArray
    accel_n: FloatArray


def body_kinematics(motion: MotionTruth, gait: GaitResult) -> BodyKinematics:
    """Combine the nominal motion and the gait oscillation into a waist pose history."""
    c, s = np.cos(motion.heading), np.sin(motion.heading)
    off = gait.offset_body
    dx = c * off[:, 0] - s * off[:, 1]
    dy = s * off[:, 0] + c * off[:, 1]
    position = motion.xyz + np.column_stack([dx, dy, off[:, 2]])
    roll, pitch, yaw = gait.euler_osc.T
    q_nb = quat_from_euler(roll, pitch, motion.heading + yaw)
    return BodyKinematics(t=motion.t, position=position, q_nb=q_nb)


def _rotvec(q: FloatArray) -> FloatArray:
    """Rotation vectors of unit quaternions (w made non-negative first)."""
    q = np.where(q[:, :1] < 0, -q, q)
    vn = np.linalg.norm(q[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(vn, q[:, 0])
    k = np.where(vn > 1e-15, angle / np.where(vn > 1e-15, vn, 1.0), 2.0)
    return q[:, 1:] * k[:, None]


def body_rate(t: FloatArray, q_nb: FloatArray) -> FloatArray:
    """Body-frame angular rate (rad/s) of a uniformly sampled attitude history."""
    if len(t) < 2:
        return np.zeros((len(t), 3))
    dt = float(t[1] - t[0])
    rel = quat_multiply(quat_conjugate(q_nb[:-1]), q_nb[1:])
    half = _rotvec(rel) / dt  # rate over each interval, body frame at its start
    w = np.empty((len(t), 3))
    w[1:-1] = 0.5 * (half[:-1] + half[1:])
    w[0] = half[0]
    w[-1] = half[-1]
    return w


def second_difference(t: FloatArray, x: FloatArray) -> FloatArray:
    """Second time derivative by central differences on a uniform grid (ends copied)."""
    if len(t) < 3:
        return np.zeros_like(x)
    dt = float(t[1] - t[0])
    a = np.empty_like(x)
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / (dt * dt)
    a[0] = a[1]
    a[-1] = a[-2]
    return a


def ideal_imu(kin: BodyKinematics, *, q_bd: ArrayLike = (1.0, 0.0, 0.0, 0.0),
              lever_arm_b: ArrayLike = (0.0, 0.0, 0.0),
              gravity_m_s2: float = GRAVITY_M_S2) -> IdealImu:
    """Noiseless device-frame specific force and angular rate of a device on the waist.

    Parameters
    ----------
    kin:
        Waist pose history (uniform time grid).
    q_bd:
        Mounting rotation, device -> body, scalar first.
    lever_arm_b:
        Device position relative to the waist centre in the body frame, m.
    gravity_m_s2:
        Local gravity magnitude, m/s^2.
    """
    qbd = quat_normalize(np.asarray(q_bd, dtype=np.float64))
    arm = np.asarray(lever_arm_b, dtype=np.float64)
    if arm.shape != (3,) or not np.all(np.isfinite(arm)):
        raise InputError(f"lever arm {arm}", where="lever_arm_b", expected="3 finite numbers, m")
    p_dev = kin.position + quat_rotate(kin.q_nb, arm) if np.any(arm) else kin.position
    acc_n = second_difference(kin.t, p_dev)
    f_n = acc_n + np.array([0.0, 0.0, gravity_m_s2])
    q_nd = quat_multiply(kin.q_nb, qbd)
    f_d = quat_rotate(quat_conjugate(q_nd), f_n)
    w_b = body_rate(kin.t, kin.q_nb)
    w_d = quat_rotate(quat_conjugate(qbd), w_b)
    return IdealImu(t=kin.t, specific_force=f_d, angular_rate=w_d, q_nd=q_nd,
                    device_position=p_dev, accel_n=acc_n)


def interp_rows(t_new: FloatArray, t: FloatArray, x: FloatArray) -> FloatArray:
    """Each column of ``x`` (sampled at ``t``) linearly interpolated at ``t_new``."""
    return np.column_stack([np.interp(t_new, t, c) for c in x.T])


def interp_quat(t_new: FloatArray, t: FloatArray, q: FloatArray) -> FloatArray:
    """Quaternions at ``t_new`` by normalized linear interpolation (sign-continuous)."""
    qq = q.copy()
    flip = np.cumsum(np.concatenate([[0], (np.sum(qq[1:] * qq[:-1], axis=1) < 0)]) % 2) % 2
    qq[flip.astype(bool)] *= -1
    return quat_normalize(interp_rows(t_new, t, qq))


@dataclass(frozen=True, slots=True)
class SimulatedImu:
    """Device streams and what made them.

    Attributes
    ----------
    imu: accelerometer (+ gyroscope, magnetometer) stream, device frame, SI units.
    orientation: the device's own attitude estimate (true attitude plus a slow heading error),
        or None.
    pressure: barometer, Pa, or None.
    ideal: the noiseless signals on the simulation grid.
    realizations: the drawn bias / scale / misalignment per sensor.
    """

    imu: ImuStream
    orientation: OrientationSeries | None
    pressure: SensorSeries | None
    ideal: IdealImu
    realizations: dict[str, ErrorRealization]


def simulate_imu(kin: BodyKinematics, device: DeviceModel, rng: np.random.Generator, *,
                 q_bd: ArrayLike = (1.0, 0.0, 0.0, 0.0),
                 lever_arm_b: ArrayLike = (0.0, 0.0, 0.0),
                 magnetic: MagneticEnvironment | None = None, with_gyro: bool = True,
                 with_mag: bool = True, with_orientation: bool = False,
                 orientation_heading_error_rad: float = 0.05, with_pressure: bool = False,
                 sea_level_pa: float = 101325.0, noiseless: bool = False
                 ) -> SimulatedImu:
    """Sample the device's sensors with their error models on their own clocks.

    The accelerometer and gyroscope share the device's sample times (rate and jitter of the
    device); the magnetometer has its own rate. Values at jittered times are interpolated
    linearly from the simulation grid. ``noiseless`` turns off all errors and jitter (for tests).
    """
    ideal = ideal_imu(kin, q_bd=q_bd, lever_arm_b=lever_arm_b)
    t_grid = kin.t
    t0, t1 = float(t_grid[0]), float(t_grid[-1])
    jitter = 0.0 if noiseless else device.jitter_s
    t_acc = sample_times(t0, t1, device.rate_hz, jitter, rng)
    same_grid = len(t_acc) == len(t_grid) and np.allclose(t_acc, t_grid, atol=1e-12, rtol=0)
    f = ideal.specific_force if same_grid else interp_rows(t_acc, t_grid, ideal.specific_force)
    w = ideal.angular_rate if same_grid else interp_rows(t_acc, t_grid, ideal.angular_rate)
    realizations: dict[str, ErrorRealization] = {}
    if not noiseless:
        realizations["accelerometer"] = realize_errors(device.accel, rng)
        f = apply_sensor_errors(f, t_acc, device.accel, realizations["accelerometer"], rng)
    accel = SensorSeries(t_acc, f, "accelerometer")
    gyro = None
    if with_gyro:
        if not noiseless:
            realizations["gyroscope"] = realize_errors(device.gyro, rng)
            w = apply_sensor_errors(w, t_acc, device.gyro, realizations["gyroscope"], rng)
        gyro = SensorSeries(t_acc, w, "gyroscope")
    mag = None
    if with_mag and magnetic is not None:
        rate = device.mag_rate_hz or device.rate_hz
        t_mag = t_acc if rate == device.rate_hz else sample_times(t0, t1, rate, jitter, rng)
        q_nd = interp_quat(t_mag, t_grid, ideal.q_nd)
        pos = interp_rows(t_mag, t_grid, ideal.device_position)
        m_n = magnetic.field_at(pos)
        m_d = quat_rotate(quat_conjugate(q_nd), m_n)
        if not noiseless:
            realizations["magnetometer"] = realize_errors(device.mag, rng)
            m_d = apply_sensor_errors(m_d, t_mag, device.mag, realizations["magnetometer"], rng)
        mag = SensorSeries(t_mag, m_d, "magnetometer")
    imu = ImuStream(accel, gyro, mag, check_units=False)
    orientation = None
    if with_orientation:
        q = interp_quat(t_acc, t_grid, ideal.q_nd)
        if not noiseless and orientation_heading_error_rad > 0:
            # slowly wandering heading error of the device's own AHRS (Basso Sec. IV)
            dt = 1.0 / device.rate_hz
            a = float(np.exp(-dt / 60.0))
            u = rng.standard_normal(len(q)) * np.sqrt(1 - a * a)
            u[0] = rng.standard_normal()
            err = lfilter([1.0], [1.0, -a], u) * orientation_heading_error_rad
            dq = quat_from_rotvec(np.column_stack([np.zeros(len(q)), np.zeros(len(q)), err]))
            q = quat_normalize(quat_multiply(dq, q))
        orientation = OrientationSeries(t_acc, q, "orientation")
    pressure = None
    if with_pressure and device.baro is not None:
        rate = device.baro_rate_hz
        t_p = sample_times(t0, t1, rate, 0.0, rng)
        z = np.interp(t_p, t_grid, ideal.device_position[:, 2])
        p = sea_level_pa * (1.0 - 2.25577e-5 * z) ** 5.25588  # standard atmosphere
        if not noiseless:
            real = realize_errors(device.baro, rng)
            realizations["barometer"] = real
            p = apply_sensor_errors(p[:, None].repeat(3, axis=1), t_p, device.baro, real,
                                    rng)[:, 0]
        pressure = SensorSeries(t_p, p, "pressure")
    return SimulatedImu(imu=imu, orientation=orientation, pressure=pressure, ideal=ideal,
                        realizations=realizations)
