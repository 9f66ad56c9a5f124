"""Sensor streams: one sensor, the IMU, pressure, and an orientation the device computed.

All samples are in the *device* frame (see :mod:`hrtls.frames`); the accelerometer measures
specific force in m/s^2, the gyroscope angular rate in rad/s, the magnetometer the field in uT.
Each sensor keeps its own timestamps (float64 s, strictly increasing).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.validation import (
    FloatArray,
    as_float_matrix,
    as_float_vector,
    check_finite,
    check_time,
    drop_non_finite,
    repair_time_order,
)
from hrtls.errors import InputError, UnitError
from hrtls.frames import quat_normalize
from hrtls.units import (
    suspect_accelerometer_unit,
    suspect_gyroscope_unit,
    suspect_magnetometer_unit,
)


@dataclass(frozen=True, slots=True, eq=False)
class SensorSeries:
    """Time-stamped samples of one sensor.

    Attributes
    ----------
    t:
        Sample times, s, shape (N,), strictly increasing.
    values:
        Samples, shape (N, K) (K = 3 for vector sensors, 1 for scalars, 4 for quaternions).
    name:
        Stream name used in error messages (``"accelerometer"``, ``"imu.csv"`` ...).
    """

    t: FloatArray
    values: FloatArray
    name: str = "sensor"

    def __post_init__(self) -> None:
        t = as_float_vector(self.t, where=f"{self.name} time")
        values = np.asarray(self.values, dtype=np.float64)
        if values.ndim == 1:
            values = values[:, None]
        values = as_float_matrix(values, where=self.name, columns=values.shape[1], length=len(t))
        check_time(t, where=self.name)
        check_finite(values, where=self.name)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "values", values)

    @classmethod
    def from_raw(cls, t: ArrayLike, values: ArrayLike, *, name: str, repair: bool = False
                 ) -> SensorSeries:
        """Build a series; ``repair`` drops non-finite rows, sorts and merges duplicates (warns)."""
        if not repair:
            return cls(np.asarray(t, dtype=np.float64), np.asarray(values, dtype=np.float64), name)
        tt = as_float_vector(t, where=f"{name} time")
        vv = np.asarray(values, dtype=np.float64)
        if vv.ndim == 1:
            vv = vv[:, None]
        vv = as_float_matrix(vv, where=name, columns=vv.shape[1], length=len(tt))
        tt, (vv,) = drop_non_finite(tt, [vv], where=name)
        tt, (vv,) = repair_time_order(tt, [vv], where=name)
        return cls(tt, vv, name)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample, s."""
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def rate_hz(self) -> float:
        """Nominal rate from the median sample spacing, Hz (0 for fewer than 2 samples)."""
        if len(self.t) < 2:
            return 0.0
        return float(1.0 / np.median(np.diff(self.t)))

    def gaps(self, *, factor: float = 3.0) -> list[tuple[float, float]]:
        """Intervals ``(t_before, t_after)`` where spacing exceeds ``factor`` x median spacing."""
        if len(self.t) < 3:
            return []
        dt = np.diff(self.t)
        idx = np.flatnonzero(dt > factor * np.median(dt))
        return [(float(self.t[i]), float(self.t[i + 1])) for i in idx]

    def interpolate(self, t_new: ArrayLike) -> FloatArray:
        """Linear interpolation onto ``t_new`` (held constant outside the recorded span)."""
        from hrtls.data._interp_kernel import interp_columns_kernel  # numba: on first use

        if not len(self.t):   # as np.interp: nothing to interpolate from
            raise ValueError("array of sample points is empty")
        tq = np.ascontiguousarray(t_new, dtype=np.float64)
        out = np.empty((tq.shape[0], self.values.shape[1]))
        interp_columns_kernel(tq, np.ascontiguousarray(self.t, dtype=np.float64),
                              np.ascontiguousarray(self.values, dtype=np.float64), out)
        return out

    def between(self, t_start_s: float, t_end_s: float) -> SensorSeries:
        """Samples with ``t_start_s <= t < t_end_s``."""
        i0, i1 = np.searchsorted(self.t, [t_start_s, t_end_s], side="left")
        return SensorSeries(self.t[i0:i1], self.values[i0:i1], self.name)


@dataclass(frozen=True, slots=True, eq=False)
class ImuStream:
    """Accelerometer plus optional gyroscope and magnetometer of one device, device frame.

    Units are checked at construction: an accelerometer in g, a gyroscope in deg/s or a
    magnetometer in gauss/nT raises :class:`~hrtls.errors.UnitError` with the fix. Pass
    ``check_units=False`` only for data known to be SI (e.g. free-fall or centrifuge tests).
    """

    accel: SensorSeries
    gyro: SensorSeries | None = None
    mag: SensorSeries | None = None
    check_units: bool = field(default=True, repr=False)

    def __post_init__(self) -> None:
        for label, series in (("accelerometer", self.accel), ("gyroscope", self.gyro),
                              ("magnetometer", self.mag)):
            if series is not None and series.values.shape[1] != 3:
                raise InputError(f"{series.values.shape[1]} axes", where=label,
                                 expected="3 axes (x, y, z)")
        if not self.check_units:
            return
        checks = ((self.accel, suspect_accelerometer_unit), (self.gyro, suspect_gyroscope_unit),
                  (self.mag, suspect_magnetometer_unit))
        for series, check in checks:
            if series is not None:
                message = check(series.values)
                if message:
                    raise UnitError(message, where=series.name,
                                    expected="SI units (m/s^2, rad/s, uT)")

    @property
    def sensors(self) -> list[str]:
        """Names of the sensors present: a subset of accelerometer, gyroscope, magnetometer."""
        present = ["accelerometer"]
        if self.gyro is not None:
            present.append("gyroscope")
        if self.mag is not None:
            present.append("magnetometer")
        return present

    def shares_time(self, other: SensorSeries | None) -> bool:
        """True when ``other`` has exactly the accelerometer's timestamps."""
        return other is not None and len(other.t) == len(self.accel.t) and bool(
            np.array_equal(other.t, self.accel.t))

    def aligned(self) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray | None]:
        """``(t, acc, gyr, mag)`` on the accelerometer's timestamps (others interpolated)."""
        t = self.accel.t
        gyr = None if self.gyro is None else (
            self.gyro.values if self.shares_time(self.gyro) else self.gyro.interpolate(t))
        mag = None if self.mag is None else (
            self.mag.values if self.shares_time(self.mag) else self.mag.interpolate(t))
        return t, self.accel.values, gyr, mag

    def in_device_frame(self, r_new_old: ArrayLike) -> ImuStream:
        """The same stream in another device frame (units not re-checked).

        ``r_new_old`` (3, 3) maps old device axes to new: ``v_new = r_new_old @ v_old`` for
        every sensor's vectors.
        """
        r = np.asarray(r_new_old, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9):
            raise InputError(f"shape {r.shape}", where="r_new_old",
                             expected="a 3x3 rotation matrix")

        def rot(series: SensorSeries | None) -> SensorSeries | None:
            return None if series is None else SensorSeries(series.t, series.values @ r.T,
                                                            series.name)

        accel = rot(self.accel)
        assert accel is not None
        return ImuStream(accel, rot(self.gyro), rot(self.mag), check_units=False)

    def between(self, t_start_s: float, t_end_s: float) -> ImuStream:
        """The part of the stream with ``t_start_s <= t < t_end_s`` (units not re-checked)."""
        return ImuStream(
            self.accel.between(t_start_s, t_end_s),
            None if self.gyro is None else self.gyro.between(t_start_s, t_end_s),
            None if self.mag is None else self.mag.between(t_start_s, t_end_s),
            check_units=False,
        )


@dataclass(frozen=True, slots=True, eq=False)
class OrientationSeries:
    """Orientation the device computed itself, as ``q_nd`` (device -> ENU), scalar first.

    Readers convert the device's own reference frame to ENU before building this.
    """

    t: FloatArray
    q: FloatArray
    name: str = "orientation"

    def __post_init__(self) -> None:
        t = as_float_vector(self.t, where=f"{self.name} time")
        q = as_float_matrix(self.q, where=self.name, columns=4, length=len(t))
        check_time(t, where=self.name)
        check_finite(q, where=self.name)
        norms = np.linalg.norm(q, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-3):
            idx = int(np.flatnonzero(np.abs(norms - 1.0) > 1e-3)[0])
            raise InputError(f"quaternion norm {norms[idx]:.6g}", where=f"{self.name} index {idx}",
                             expected="unit quaternions [w, x, y, z]")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", quat_normalize(q))
