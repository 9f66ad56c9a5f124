"""Vertical and horizontal acceleration in a levelled frame.

Two ways to level the accelerometer (specific force ``f``, device frame, m/s^2):

* :func:`from_orientation`: with an attitude quaternion series ``q_nd`` (device -> ENU, e.g. from
  an attitude filter or the device's own AHRS, Basso Sec. II-A), ``f_n = q_nd * f_d * conj(q_nd)``;
  the vertical linear acceleration is ``f_n,z - g`` and the horizontal part ``f_n,xy`` is in ENU.
* :class:`GravityLevelling` (accelerometer-only degraded mode, e.g. a step counter without a
  gyroscope): gravity is estimated by a first-order low-pass of ``f`` per axis; the vertical
  acceleration is ``f . u - |g_hat|`` with ``u = g_hat / |g_hat|`` and the horizontal part is
  expressed on two axes orthogonal to ``u`` that turn with the device (yaw is unobservable, so
  headings computed from it are relative to the device).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2
from hrtls.gait._state import (
    FloatArray,
    as_matrix,
    as_time,
    check_positive,
    state_from_dict,
    state_to_dict,
)
from hrtls.kernels import njit

UNIT_QUAT_TOL = 2e-3
"""Largest ``| |q|^2 - 1 |`` of an attitude quaternion accepted as unit."""


@dataclass(frozen=True, slots=True, eq=False)
class LevelledAcceleration:
    """Acceleration split into a vertical and a horizontal part.

    Attributes
    ----------
    t: sample times, s.
    vertical_m_s2: vertical linear acceleration (up positive, gravity removed), m/s^2.
    horizontal_m_s2: horizontal acceleration (N, 2), m/s^2: ENU east/north when ``frame`` is
        ``"enu"``, device-fixed levelled axes when ``frame`` is ``"levelled"``.
    frame: ``"enu"`` or ``"levelled"``.
    """

    t: FloatArray
    vertical_m_s2: FloatArray
    horizontal_m_s2: FloatArray
    frame: str


@njit(cache=True, inline="always")
def _rotated(w: float, x: float, y: float, z: float, vx: float, vy: float,
             vz: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """``q v conj(q)`` of one unit quaternion ``[w, x, y, z]`` and vector ``v``."""
    # t = 2 q_vec x v ; v' = v + w t + q_vec x t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


@njit(cache=True)
def rotate_kernel(q: FloatArray, v: FloatArray, out: FloatArray) -> None:  # pragma: no cover
    """``out[i] = q[i] * v[i] * conj(q[i])`` for unit quaternions [w, x, y, z] (row-wise).

    ``v`` may have one row (a constant vector) or as many rows as ``q``.
    """
    const = v.shape[0] == 1
    for i in range(q.shape[0]):
        j = 0 if const else i
        out[i, 0], out[i, 1], out[i, 2] = _rotated(q[i, 0], q[i, 1], q[i, 2], q[i, 3],
                                                   v[j, 0], v[j, 1], v[j, 2])


@njit(cache=True)
def level_kernel(q: FloatArray, acc: FloatArray, gravity_m_s2: float, vertical: FloatArray,
                 horizontal: FloatArray) -> int:  # pragma: no cover - compiled
    """:func:`from_orientation` in one pass: first row whose quaternion is not unit, or -1.

    ``vertical[i] = (q f conj(q))_z - g``, ``horizontal[i] = (q f conj(q))_xy``.
    """
    for i in range(q.shape[0]):
        w, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        if abs(w * w + x * x + y * y + z * z - 1.0) > UNIT_QUAT_TOL:
            return i
        fx, fy, fz = _rotated(w, x, y, z, acc[i, 0], acc[i, 1], acc[i, 2])
        horizontal[i, 0] = fx
        horizontal[i, 1] = fy
        vertical[i] = fz - gravity_m_s2
    return -1


def rotate(q: FloatArray, v: FloatArray) -> FloatArray:
    """Rotate rows ``v`` (N, 3) or one vector (3,) by quaternions ``q`` (N, 4) (compiled)."""
    qq = np.ascontiguousarray(q, dtype=np.float64)
    vv = np.ascontiguousarray(np.atleast_2d(v), dtype=np.float64)
    out = np.empty((qq.shape[0], 3))
    rotate_kernel(qq, vv, out)
    return out


@njit(cache=True)
def heading_kernel(q: FloatArray, v: FloatArray, out: FloatArray) -> None:  # pragma: no cover
    """Unwrapped ENU heading (rad, CCW from east) of ``v`` (3,) rotated by each ``q[i]``.

    One pass for ``np.unwrap(arctan2(y, x))`` of :func:`rotate`: a jump of more than pi
    between samples is taken as a wrap, as ``np.unwrap`` does.
    """
    vx, vy, vz = v[0], v[1], v[2]
    off = 0.0
    prev = 0.0
    for i in range(q.shape[0]):
        ex, ey, _ = _rotated(q[i, 0], q[i, 1], q[i, 2], q[i, 3], vx, vy, vz)
        a = math.atan2(ey, ex)
        if i > 0:
            d = a - prev
            if d > math.pi:
                off -= 2.0 * math.pi
            elif d < -math.pi:
                off += 2.0 * math.pi
        prev = a
        out[i] = a + off


def heading_of(q: FloatArray, v: FloatArray) -> FloatArray:
    """Unwrapped heading (rad) of the device-frame vector ``v`` (3,) in ENU per ``q`` (N, 4)."""
    qq = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty(qq.shape[0])
    heading_kernel(qq, np.ascontiguousarray(v, dtype=np.float64).reshape(3), out)
    return out


def from_orientation(t: FloatArray, acc_d_m_s2: FloatArray, q_nd: FloatArray, *,
                     gravity_m_s2: float = GRAVITY_M_S2) -> LevelledAcceleration:
    """Rotate device-frame specific force into ENU with an attitude quaternion series.

    Parameters
    ----------
    t: sample times, s (N,).
    acc_d_m_s2: specific force in the device frame, m/s^2 (N, 3).
    q_nd: unit quaternions [w, x, y, z] rotating device vectors into ENU (N, 4).
    gravity_m_s2: local gravity removed from the vertical axis, m/s^2.
    """
    tt = as_time(t, where="acceleration time")
    acc = as_matrix(acc_d_m_s2, where="accelerometer", columns=3, length=tt.shape[0])
    q = as_matrix(q_nd, where="orientation q_nd", columns=4, length=tt.shape[0])
    return levelled(tt, acc, q, gravity_m_s2=gravity_m_s2)


def levelled(t: FloatArray, acc: FloatArray, q: FloatArray, *,
             gravity_m_s2: float = GRAVITY_M_S2) -> LevelledAcceleration:
    """:func:`from_orientation` of inputs already checked (contiguous, finite, N rows)."""
    vert = np.empty(t.shape[0])
    horiz = np.empty((t.shape[0], 2))
    bad = level_kernel(q, acc, float(gravity_m_s2), vert, horiz)
    if bad >= 0:
        n2 = float(q[bad] @ q[bad])
        raise InputError(f"quaternion norm {math.sqrt(n2):.4f}",
                         where=f"orientation q_nd row {bad}", expected="unit quaternions")
    return LevelledAcceleration(t, vert, horiz, "enu")


@njit(cache=True)
def _levelling_kernel(t: FloatArray, acc: FloatArray, cutoff_hz: float, g: FloatArray,
                      ref: FloatArray, vert: FloatArray,
                      horiz: FloatArray) -> None:  # pragma: no cover
    """Low-pass gravity per axis (state ``g``), project onto it; ``ref[3]`` is the last time.

    ``ref[0:3]`` holds the device axis whose horizontal projection defines the first levelled
    axis; it switches to the most horizontal device axis when the projection gets too short.
    """
    n = t.shape[0]
    for i in range(n):
        if not np.isfinite(ref[3]):
            g[0] = acc[i, 0]
            g[1] = acc[i, 1]
            g[2] = acc[i, 2]
            dt = 0.0
        else:
            dt = t[i] - ref[3]
        ref[3] = t[i]
        alpha = 1.0 - np.exp(-2.0 * np.pi * cutoff_hz * dt)
        for k in range(3):
            g[k] += alpha * (acc[i, k] - g[k])
        gn = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        if gn < 1e-9:
            vert[i] = 0.0
            horiz[i, 0] = 0.0
            horiz[i, 1] = 0.0
            continue
        u0 = g[0] / gn
        u1 = g[1] / gn
        u2 = g[2] / gn
        # first horizontal axis: projection of the reference device axis
        d = ref[0] * u0 + ref[1] * u1 + ref[2] * u2
        e0 = ref[0] - d * u0
        e1 = ref[1] - d * u1
        e2 = ref[2] - d * u2
        en = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if en < 0.5:
            # pick the device axis most orthogonal to gravity
            best = 0
            if abs(u1) < abs(u0) and abs(u1) <= abs(u2):
                best = 1
            elif abs(u2) < abs(u0) and abs(u2) < abs(u1):
                best = 2
            ref[0] = 1.0 if best == 0 else 0.0
            ref[1] = 1.0 if best == 1 else 0.0
            ref[2] = 1.0 if best == 2 else 0.0
            d = ref[0] * u0 + ref[1] * u1 + ref[2] * u2
            e0 = ref[0] - d * u0
            e1 = ref[1] - d * u1
            e2 = ref[2] - d * u2
            en = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        e0 /= en
        e1 /= en
        e2 /= en
        # second horizontal axis: u x e (right-handed with u up)
        f0 = u1 * e2 - u2 * e1
        f1 = u2 * e0 - u0 * e2
        f2 = u0 * e1 - u1 * e0
        a0 = acc[i, 0]
        a1 = acc[i, 1]
        a2 = acc[i, 2]
        vert[i] = a0 * u0 + a1 * u1 + a2 * u2 - gn
        horiz[i, 0] = a0 * e0 + a1 * e1 + a2 * e2
        horiz[i, 1] = a0 * f0 + a1 * f1 + a2 * f2


@dataclass
class LevellingState:
    """Gravity estimate (m/s^2, device frame), reference axis and last time (NaN: none yet)."""

    gravity: FloatArray = field(default_factory=lambda: np.zeros(3))
    ref: FloatArray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, np.nan]))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (NaN written as None)."""
        d = state_to_dict(self)
        d["ref"] = [None if not np.isfinite(v) else v for v in d["ref"]]
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LevellingState:
        """Inverse of :meth:`to_dict`."""
        d = dict(data)
        d["ref"] = [np.nan if v is None else v for v in d["ref"]]
        return state_from_dict(cls, d)


@dataclass(frozen=True, kw_only=True, slots=True)
class LevellingParams:
    """Parameters of :class:`GravityLevelling`.

    Attributes
    ----------
    cutoff_hz: corner frequency of the first-order gravity low-pass, Hz.
    """

    cutoff_hz: float = 0.25


class GravityLevelling:
    """Accelerometer-only levelling by a low-passed gravity estimate (degraded mode)."""

    def __init__(self, params: LevellingParams | None = None) -> None:
        self.params = params or LevellingParams()
        check_positive(self.params.cutoff_hz, "cutoff_hz")
        self.state = LevellingState()

    def reset(self) -> None:
        """Forget the gravity estimate."""
        self.state = LevellingState()

    def update(self, t: FloatArray, acc_d_m_s2: FloatArray) -> LevelledAcceleration:
        """Process a chunk of device-frame specific force (m/s^2, (N, 3))."""
        last = self.state.ref[3]
        tt = as_time(t, where="acceleration time", after=last if np.isfinite(last) else -np.inf)
        acc = as_matrix(acc_d_m_s2, where="acceleration", columns=3, length=tt.shape[0])
        vert = np.empty(tt.shape[0])
        horiz = np.empty((tt.shape[0], 2))
        _levelling_kernel(tt, acc, self.params.cutoff_hz, self.state.gravity, self.state.ref,
                          vert, horiz)
        return LevelledAcceleration(tt, vert, horiz, "levelled")

    def process(self, t: FloatArray, acc_d_m_s2: FloatArray) -> LevelledAcceleration:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(t, acc_d_m_s2)
