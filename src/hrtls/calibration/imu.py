"""IMU calibration (Inderst thesis, App. B) and the calibration file the readers apply.

Accelerometer six-position test, gyroscope rate test, magnetometer hard/soft-iron fit.

Sensor model per axis ``i`` (device frame): ``raw_i = (1 + S_i) true_i + b_i``, so
``true_i = (raw_i - b_i) / (1 + S_i)``.

* Six-position test (eq. 7.10-7.11): with ``l_up`` / ``l_down`` the mean reading of an axis
  pointing up / down and ``K`` the local gravity, ``b = (l_up + l_down) / 2`` and
  ``S = (l_up - l_down - 2K) / (2K)``. The printed eq. 7.11 has ``l_up + l_down``; with
  ``l_up = K(1+S) + b`` and ``l_down = -K(1+S) + b`` the scale needs the difference, which is
  what we implement.
* Rate test (eq. 7.12): turntable rate ``w`` about an axis, counter-clockwise (positive about the
  axis) and clockwise. The printed formula is garbled the same way; we use
  ``S = (w_ccw - w_cw - 2w) / (2w)`` and ``b = (w_ccw + w_cw) / 2``.
* Magnetometer: the thesis fits a sphere to samples taken while the unit is swung through a
  figure of eight. :func:`fit_magnetometer` fits a sphere (hard iron only) or a general ellipsoid
  (hard and soft iron): ``m_true = W (m_raw - c)`` with ``W`` symmetric positive definite,
  scaled so that the corrected field keeps the fitted mean radius.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from hrtls.data import ImuStream, SensorSeries
from hrtls.errors import FormatError, InputError
from hrtls.frames import GRAVITY_M_S2, FloatArray

__all__ = [
    "AXIS_POSITIONS",
    "Calibration",
    "MagnetometerFit",
    "accelerometer_six_position",
    "fit_magnetometer",
    "gyroscope_rate_test",
    "six_position_from_means",
]

AXIS_POSITIONS = ("+x", "-x", "+y", "-y", "+z", "-z")
"""Names of the six positions: which device axis points up."""

Vec3 = tuple[float, float, float]


def _vec3(v: ArrayLike, where: str) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"value {v!r}", where=where, expected="three finite numbers")
    return a


def six_position_from_means(l_up: ArrayLike, l_down: ArrayLike,
                            reference: float = GRAVITY_M_S2) -> tuple[FloatArray, FloatArray]:
    """Bias and scale-factor error per axis (eq. 7.10-7.11) from the up/down mean readings."""
    up = _vec3(l_up, "l_up")
    down = _vec3(l_down, "l_down")
    if not (np.isfinite(reference) and reference > 0):
        raise InputError(f"reference {reference}", where="six_position_from_means",
                         expected="a positive reference signal")
    if np.any(up <= down):
        i = int(np.flatnonzero(up <= down)[0])
        raise InputError(f"axis {'xyz'[i]} reads {up[i]:.4g} up and {down[i]:.4g} down",
                         where="six-position test",
                         expected="a larger reading with the axis up than down")
    bias = 0.5 * (up + down)
    scale = (up - down - 2.0 * reference) / (2.0 * reference)
    return bias, scale


def accelerometer_six_position(segments: Mapping[str, ArrayLike], *,
                               gravity_m_s2: float = GRAVITY_M_S2
                               ) -> tuple[FloatArray, FloatArray]:
    """Six-position test from static recordings, one per position.

    Parameters
    ----------
    segments:
        ``{"+x": samples, "-x": ..., "+z": ...}``: accelerometer samples (M, 3) in m/s^2 taken
        while the named axis pointed up (``+``) or down (``-``).
    gravity_m_s2:
        Local gravity, the reference ``K``.

    Returns
    -------
    bias_m_s2, scale
        Per-axis bias (m/s^2) and scale-factor error (dimensionless).
    """
    missing = [p for p in AXIS_POSITIONS if p not in segments]
    if missing:
        raise InputError(f"positions {missing} missing", where="six-position test",
                         expected=f"all of {list(AXIS_POSITIONS)}")
    up = np.empty(3)
    down = np.empty(3)
    for i, axis in enumerate("xyz"):
        for sign, target in (("+", up), ("-", down)):
            s = np.asarray(segments[sign + axis], dtype=np.float64)
            if s.ndim != 2 or s.shape[1] != 3 or len(s) == 0:
                raise InputError(f"shape {s.shape}", where=f"six-position segment {sign}{axis}",
                                 expected="(M, 3) accelerometer samples, M >= 1")
            s = s[np.all(np.isfinite(s), axis=1)]
            if len(s) == 0:
                raise InputError("no finite samples", where=f"six-position segment {sign}{axis}",
                                 expected="finite accelerometer samples")
            target[i] = float(np.mean(s[:, i]))
    return six_position_from_means(up, down, gravity_m_s2)


def gyroscope_rate_test(rate_rad_s: float, ccw_rad_s: ArrayLike, cw_rad_s: ArrayLike
                        ) -> tuple[FloatArray, FloatArray]:
    """Rate test (eq. 7.12): bias and scale-factor error from turntable runs about each axis.

    Parameters
    ----------
    rate_rad_s:
        Turntable rate magnitude, rad/s.
    ccw_rad_s, cw_rad_s:
        Mean reading of each axis while turned about that axis counter-clockwise (positive) and
        clockwise, rad/s, shape (3,).
    """
    if not (np.isfinite(rate_rad_s) and rate_rad_s > 0):
        raise InputError(f"rate {rate_rad_s}", where="gyroscope rate test",
                         expected="a positive turntable rate in rad/s")
    return six_position_from_means(ccw_rad_s, cw_rad_s, rate_rad_s)


class MagnetometerFit(BaseModel):
    """Hard/soft-iron correction ``m = W (m_raw - c)`` of a magnetometer (uT)."""

    model_config = ConfigDict(frozen=True)

    hard_iron_uT: Vec3
    soft_iron: tuple[Vec3, Vec3, Vec3]
    field_uT: float
    residual_uT: float
    model: Literal["sphere", "ellipsoid"]


def fit_magnetometer(mag: ArrayLike, *, model: Literal["sphere", "ellipsoid"] = "ellipsoid"
                     ) -> MagnetometerFit:
    """Fit a sphere or an ellipsoid to raw field samples (uT) taken in many orientations.

    Raises :class:`InputError` when there are too few samples or they do not cover enough
    orientations for the model (the fitted quadric is not an ellipsoid).
    """
    m = np.asarray(mag, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 3:
        raise InputError(f"shape {m.shape}", where="magnetometer samples", expected="(N, 3)")
    m = m[np.all(np.isfinite(m), axis=1)]
    need = 4 if model == "sphere" else 9
    if len(m) < 3 * need:
        raise InputError(f"{len(m)} finite samples", where="magnetometer fit",
                         expected=f"at least {3 * need} samples in many orientations")
    center0 = m.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((m - center0) ** 2, axis=1))))
    if not scale > 0:
        raise InputError("all samples equal", where="magnetometer fit",
                         expected="samples in many orientations")
    u = (m - center0) / scale  # centred and scaled for conditioning
    if model == "sphere":
        # |u|^2 = 2 c.u + k
        A = np.column_stack([2.0 * u, np.ones(len(u))])
        sol, *_ = np.linalg.lstsq(A, np.sum(u * u, axis=1), rcond=None)
        c = sol[:3]
        r2 = sol[3] + c @ c
        if not r2 > 0:
            raise InputError("sphere fit failed", where="magnetometer fit",
                             expected="samples in many orientations")
        radius = float(np.sqrt(r2))
        W = np.eye(3)
        center = center0 + scale * c
        field = radius * scale
    elif model == "ellipsoid":
        x, y, z = u.T
        D = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z,
                             2 * x, 2 * y, 2 * z])
        v, *_ = np.linalg.lstsq(D, np.ones(len(u)), rcond=None)
        Q = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
        try:
            c = -np.linalg.solve(Q, v[6:9])
        except np.linalg.LinAlgError:
            raise InputError("ellipsoid fit is singular", where="magnetometer fit",
                             expected="samples covering all orientations",
                             hint="swing the device through a figure of eight") from None
        k = 1.0 + c @ Q @ c
        M = Q / k
        evals, evecs = np.linalg.eigh(M)
        if not np.all(evals > 0):
            raise InputError("fitted surface is not an ellipsoid", where="magnetometer fit",
                             expected="samples covering all orientations",
                             hint="swing the device through a figure of eight, or use "
                                  "model='sphere'")
        radius = float(np.prod(evals) ** (-1.0 / 6.0))  # radius of the equal-volume sphere
        W = radius * (evecs @ np.diag(np.sqrt(evals)) @ evecs.T)
        center = center0 + scale * c
        field = radius * scale
    else:
        raise InputError(f"model {model!r}", where="fit_magnetometer",
                         expected="'sphere' or 'ellipsoid'")
    corrected = (m - center) @ W.T
    resid = float(np.sqrt(np.mean((np.linalg.norm(corrected, axis=1) - field) ** 2)))
    return MagnetometerFit(
        hard_iron_uT=tuple(float(e) for e in center),  # type: ignore[arg-type]
        soft_iron=tuple(tuple(float(e) for e in row) for row in W),  # type: ignore[arg-type]
        field_uT=field, residual_uT=resid, model=model)


class Calibration(BaseModel):
    """Calibration of one IMU, stored as JSON and applied by :meth:`apply`.

    ``true = (raw - bias) / (1 + scale)`` per axis for the accelerometer and gyroscope,
    ``m = soft_iron @ (raw - hard_iron)`` for the magnetometer. Missing parts are identity.
    """

    model_config = ConfigDict(extra="forbid")

    format: Literal["hrtls-imu-calibration"] = "hrtls-imu-calibration"
    version: int = 1
    accel_bias_m_s2: Vec3 = (0.0, 0.0, 0.0)
    accel_scale: Vec3 = (0.0, 0.0, 0.0)
    gyro_bias_rad_s: Vec3 = (0.0, 0.0, 0.0)
    gyro_scale: Vec3 = (0.0, 0.0, 0.0)
    mag_hard_iron_uT: Vec3 = (0.0, 0.0, 0.0)
    mag_soft_iron: tuple[Vec3, Vec3, Vec3] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    mag_field_uT: float | None = None
    notes: list[str] = Field(default_factory=list)

    @field_validator("accel_bias_m_s2", "accel_scale", "gyro_bias_rad_s", "gyro_scale",
                     "mag_hard_iron_uT")
    @classmethod
    def _finite(cls, v: Vec3) -> Vec3:
        if not np.all(np.isfinite(v)):
            raise ValueError("values must be finite")
        return v

    @field_validator("accel_scale", "gyro_scale")
    @classmethod
    def _scale(cls, v: Vec3) -> Vec3:
        if np.any(np.asarray(v) <= -0.5):
            raise ValueError("scale-factor errors must be > -0.5")
        return v

    @field_validator("mag_soft_iron")
    @classmethod
    def _soft(cls, v: tuple[Vec3, Vec3, Vec3]) -> tuple[Vec3, Vec3, Vec3]:
        w = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(w)) or abs(np.linalg.det(w)) < 1e-9:
            raise ValueError("soft-iron matrix must be finite and invertible")
        return v

    def correct_accel(self, raw: ArrayLike) -> FloatArray:
        """Calibrated specific force (N, 3), m/s^2."""
        return ((np.asarray(raw, dtype=np.float64) - np.asarray(self.accel_bias_m_s2))
                / (1.0 + np.asarray(self.accel_scale)))

    def correct_gyro(self, raw: ArrayLike) -> FloatArray:
        """Calibrated angular rate (N, 3), rad/s."""
        return ((np.asarray(raw, dtype=np.float64) - np.asarray(self.gyro_bias_rad_s))
                / (1.0 + np.asarray(self.gyro_scale)))

    def correct_mag(self, raw: ArrayLike) -> FloatArray:
        """Calibrated magnetic field (N, 3), uT."""
        W = np.asarray(self.mag_soft_iron, dtype=np.float64)
        return (np.asarray(raw, dtype=np.float64) - np.asarray(self.mag_hard_iron_uT)) @ W.T

    def apply(self, imu: ImuStream) -> ImuStream:
        """A calibrated copy of an IMU stream (timestamps unchanged)."""
        acc = SensorSeries(imu.accel.t, self.correct_accel(imu.accel.values), imu.accel.name)
        gyr = None if imu.gyro is None else SensorSeries(
            imu.gyro.t, self.correct_gyro(imu.gyro.values), imu.gyro.name)
        mag = None if imu.mag is None else SensorSeries(
            imu.mag.t, self.correct_mag(imu.mag.values), imu.mag.name)
        return ImuStream(acc, gyr, mag, check_units=imu.check_units)

    def with_magnetometer(self, fit: MagnetometerFit) -> Calibration:
        """A copy with the magnetometer part replaced by a fit."""
        return self.model_copy(update={
            "mag_hard_iron_uT": fit.hard_iron_uT, "mag_soft_iron": fit.soft_iron,
            "mag_field_uT": fit.field_uT,
            "notes": [*self.notes, f"magnetometer {fit.model} fit, residual "
                                   f"{fit.residual_uT:.3g} uT"]})

    def save(self, path: Path | str) -> Path:
        """Write the calibration as JSON."""
        p = Path(path)
        p.write_text(self.model_dump_json(indent=2) + "\n")
        return p

    @classmethod
    def load(cls, path: Path | str) -> Calibration:
        """Read a calibration JSON file (raises :class:`FormatError` naming the problem)."""
        p = Path(path)
        try:
            data = json.loads(p.read_text())
        except OSError as exc:
            raise FormatError(str(exc), where=str(p), expected="a readable JSON file") from None
        except json.JSONDecodeError as exc:
            raise FormatError(f"invalid JSON: {exc.msg}", where=f"{p} line {exc.lineno}",
                              expected="a calibration JSON file") from None
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            err = exc.errors()[0]
            loc = ".".join(str(e) for e in err["loc"])
            raise FormatError(err["msg"], where=f"{p} field {loc}",
                              expected="an hrtls IMU calibration") from None
