"""Frames, rotations and angles: the conventions every part of hrtls uses.

Conventions (see ``docs/conventions.md``):

* Navigation frame ``n``: local East-North-Up (x east, y north, z up), metres.
* Body frame ``b`` of a waist-worn unit: x forward, y left, z up. A device's own axes ``d`` map to
  the body frame by a fixed mounting rotation ``q_bd``.
* Quaternions are scalar first ``[w, x, y, z]``, Hamilton product. ``q_nb`` rotates body vectors
  into the navigation frame: ``v_n = q_nb * v_b * conj(q_nb)``.
* Euler angles are ``roll, pitch, yaw`` of the z-y'-x'' (yaw, then pitch, then roll) sequence:
  ``R_nb = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Yaw (heading) is measured from +x (east)
  counter-clockwise and wrapped to ``(-pi, pi]``.
* Compass bearings (clockwise from north) appear only at the boundary and are converted with
  :func:`heading_from_bearing` / :func:`bearing_from_heading`.
* Accelerometers measure specific force ``f = a - g`` with ``g = [0, 0, -9.80665]`` in ENU, so a
  unit at rest with z up reads about ``+9.81`` on z.

scipy's :class:`~scipy.spatial.transform.Rotation` uses scalar-last quaternions: always go through
:func:`quat_to_rotation` and :func:`quat_from_rotation`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.errors import InputError

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation

GRAVITY_M_S2 = 9.80665
"""Standard gravity, m/s^2 (used for unit conversion from g and as the default local gravity)."""

UNIFORM_ANGLE_VAR_RAD2 = float(np.pi**2 / 3.0)
"""Variance of an angle uniform on [-pi, pi), rad^2 (a heading nothing observes)."""

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------------------------
# Angles
# --------------------------------------------------------------------------------------------
def wrap_angle(angle_rad: ArrayLike) -> FloatArray:
    """Wrap angles to ``(-pi, pi]`` (radians in, radians out)."""
    a = np.asarray(angle_rad, dtype=np.float64)
    wrapped = np.pi - np.mod(np.pi - a, 2.0 * np.pi)
    return np.asarray(wrapped, dtype=np.float64)


def angle_difference(a_rad: ArrayLike, b_rad: ArrayLike) -> FloatArray:
    """Smallest signed difference ``a - b`` wrapped to ``(-pi, pi]``."""
    return wrap_angle(np.asarray(a_rad, dtype=np.float64) - np.asarray(b_rad, dtype=np.float64))


def heading_from_bearing(bearing_rad: ArrayLike) -> FloatArray:
    """Convert a compass bearing (clockwise from north) to an ENU heading (CCW from east)."""
    return wrap_angle(np.pi / 2.0 - np.asarray(bearing_rad, dtype=np.float64))


def bearing_from_heading(heading_rad: ArrayLike) -> FloatArray:
    """Convert an ENU heading (CCW from east) to a compass bearing in ``[0, 2 pi)``."""
    return np.mod(np.pi / 2.0 - np.asarray(heading_rad, dtype=np.float64), 2.0 * np.pi)


# --------------------------------------------------------------------------------------------
# Quaternions, scalar first [w, x, y, z], stacks along the first axes
# --------------------------------------------------------------------------------------------
def as_quat_array(q: ArrayLike, *, name: str = "quaternion") -> FloatArray:
    """Return ``q`` as a float array of shape ``(..., 4)`` or raise :class:`InputError`."""
    arr = np.asarray(q, dtype=np.float64)
    if arr.shape[-1:] != (4,):
        raise InputError(
            f"shape {arr.shape}", where=name, expected="last axis of length 4 ([w, x, y, z])"
        )
    return arr


def quat_normalize(q: ArrayLike) -> FloatArray:
    """Scale quaternions to unit norm and make ``w >= 0`` (the same rotation)."""
    arr = as_quat_array(q)
    norm = np.linalg.norm(arr, axis=-1, keepdims=True)
    if np.any(norm == 0.0) or not np.all(np.isfinite(norm)):
        raise InputError("zero or non-finite quaternion", expected="a non-zero finite quaternion")
    out = arr / norm
    sign = np.where(out[..., :1] < 0.0, -1.0, 1.0)
    return np.asarray(out * sign, dtype=np.float64)


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate ``[w, -x, -y, -z]`` (the inverse of a unit quaternion)."""
    arr = as_quat_array(q)
    return np.asarray(arr * np.array([1.0, -1.0, -1.0, -1.0]), dtype=np.float64)


def quat_multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Hamilton product ``p * q`` (broadcast over leading axes)."""
    a = as_quat_array(p, name="p")
    b = as_quat_array(q, name="q")
    pw, px, py, pz = np.moveaxis(a, -1, 0)
    qw, qx, qy, qz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_to_matrix(q: ArrayLike) -> FloatArray:
    """Rotation matrices ``R`` (..., 3, 3) of unit quaternions, so that ``v_n = R @ v_b``."""
    arr = as_quat_array(q)
    w, x, y, z = np.moveaxis(arr, -1, 0)
    m = np.empty((*arr.shape[:-1], 3, 3))
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - w * z)
    m[..., 0, 2] = 2 * (x * z + w * y)
    m[..., 1, 0] = 2 * (x * y + w * z)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - w * x)
    m[..., 2, 0] = 2 * (x * z - w * y)
    m[..., 2, 1] = 2 * (y * z + w * x)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def quat_rotate(q: ArrayLike, v: ArrayLike) -> FloatArray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4): ``q * v * conj(q)``."""
    vec = np.asarray(v, dtype=np.float64)
    arr = as_quat_array(q)
    qv = arr[..., 1:]
    w = arr[..., :1]
    t = 2.0 * np.cross(qv, vec)
    return np.asarray(vec + w * t + np.cross(qv, t), dtype=np.float64)


def quat_to_rotation(q: ArrayLike) -> Rotation:
    """Convert scalar-first quaternions to a scipy :class:`Rotation` (which is scalar last)."""
    from scipy.spatial.transform import Rotation  # imported when used: it is slow to import

    arr = as_quat_array(q)
    return Rotation.from_quat(arr[..., [1, 2, 3, 0]])


def quat_from_rotation(rotation: Rotation) -> FloatArray:
    """Convert a scipy :class:`Rotation` to scalar-first quaternions with ``w >= 0``."""
    xyzw = rotation.as_quat()
    return quat_normalize(xyzw[..., [3, 0, 1, 2]])


def quat_from_euler(roll_rad: ArrayLike, pitch_rad: ArrayLike, yaw_rad: ArrayLike) -> FloatArray:
    """Quaternion ``q_nb`` of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (angles in radians)."""
    r = np.asarray(roll_rad, dtype=np.float64) / 2.0
    p = np.asarray(pitch_rad, dtype=np.float64) / 2.0
    y = np.asarray(yaw_rad, dtype=np.float64) / 2.0
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    q = np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )
    return quat_normalize(q)


def euler_from_quat(q: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Roll, pitch, yaw (radians) of the z-y'-x'' sequence; yaw wrapped to ``(-pi, pi]``."""
    arr = as_quat_array(q)
    w, x, y, z = np.moveaxis(arr, -1, 0)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.asarray(roll), np.asarray(pitch), wrap_angle(yaw)


def quat_from_rotvec(rotvec: ArrayLike) -> FloatArray:
    """Quaternion of a rotation vector (axis times angle, radians): ``exp(rotvec / 2)``."""
    v = np.asarray(rotvec, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(half)/angle, with its Taylor series near zero
    with np.errstate(invalid="ignore", divide="ignore"):
        safe = np.where(angle > 0, angle, 1.0)
        k = np.where(angle > 1e-8, np.sin(half) / safe, 0.5 - angle**2 / 48)
    return np.concatenate([np.cos(half), k * v], axis=-1)


def quat_angle_between(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Rotation angle (radians, in ``[0, pi]``) of ``p * conj(q)`` for unit quaternions."""
    d = np.abs(np.sum(as_quat_array(p) * as_quat_array(q), axis=-1))
    return np.asarray(2.0 * np.arccos(np.clip(d, 0.0, 1.0)), dtype=np.float64)


def heading_from_quat(q: ArrayLike) -> FloatArray:
    """Heading of the body x axis projected on the horizontal plane (radians, CCW from east)."""
    forward = quat_rotate(q, np.array([1.0, 0.0, 0.0]))
    return wrap_angle(np.arctan2(forward[..., 1], forward[..., 0]))


# --------------------------------------------------------------------------------------------
# Georeference: local ENU <-> WGS-84
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Georeference:
    """Anchor of the local navigation frame on the WGS-84 ellipsoid.

    The local frame's origin is at ``(lat_deg, lon_deg, height_m)``. Its x axis points
    ``rotation_rad`` counter-clockwise from true east (0 means the local frame *is* ENU), z up.
    Heights are ellipsoidal, metres.
    """

    lat_deg: float
    lon_deg: float
    height_m: float = 0.0
    rotation_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lat_deg) and -90.0 <= self.lat_deg <= 90.0):
            raise InputError(f"latitude {self.lat_deg}", where="georeference.lat_deg",
                             expected="degrees in [-90, 90]")
        if not (np.isfinite(self.lon_deg) and -180.0 <= self.lon_deg <= 360.0):
            raise InputError(f"longitude {self.lon_deg}", where="georeference.lon_deg",
                             expected="degrees in [-180, 360]")
        if not (np.isfinite(self.height_m) and np.isfinite(self.rotation_rad)):
            raise InputError("non-finite height or rotation", where="georeference",
                             expected="finite numbers")

    def _rotate(self, x: FloatArray, y: FloatArray, angle: float) -> tuple[FloatArray, FloatArray]:
        c, s = np.cos(angle), np.sin(angle)
        return c * x - s * y, s * x + c * y

    def to_wgs84(self, xyz: ArrayLike) -> FloatArray:
        """Local positions (N, 2 or 3) in m to ``[lat_deg, lon_deg, height_m]`` rows."""
        p = np.atleast_2d(np.asarray(xyz, dtype=np.float64))
        z = p[:, 2] if p.shape[1] > 2 else np.zeros(len(p))
        e, n = self._rotate(p[:, 0], p[:, 1], self.rotation_rad)
        import pymap3d  # imported for a georeference only

        lat, lon, h = pymap3d.enu2geodetic(e, n, z, self.lat_deg, self.lon_deg, self.height_m)
        return np.column_stack([lat, lon, h])

    def from_wgs84(self, lat_deg: ArrayLike, lon_deg: ArrayLike,
                   height_m: ArrayLike | None = None) -> FloatArray:
        """WGS-84 coordinates (degrees, m) to local ``[x, y, z]`` rows in m."""
        lat = np.atleast_1d(np.asarray(lat_deg, dtype=np.float64))
        lon = np.atleast_1d(np.asarray(lon_deg, dtype=np.float64))
        h = (np.full_like(lat, self.height_m) if height_m is None
             else np.atleast_1d(np.asarray(height_m, dtype=np.float64)))
        import pymap3d  # imported for a georeference only

        e, n, u = pymap3d.geodetic2enu(lat, lon, h, self.lat_deg, self.lon_deg, self.height_m)
        x, y = self._rotate(np.asarray(e), np.asarray(n), -self.rotation_rad)
        return np.column_stack([x, y, u])
