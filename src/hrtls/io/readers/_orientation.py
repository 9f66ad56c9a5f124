"""Device orientations from phone apps, converted to ``q_nd`` (device -> ENU) and checked.

Apps report orientation in their own conventions (reference frame east-north-up or
north-west-up, quaternion device->world or world->device, Euler sign rules). A reader states
the documented reading of its app and a few alternatives; :func:`choose_orientation` keeps the
documented one when the recording agrees with it and otherwise picks the alternative the data
supports, saying so in the session notes:

* gravity test: the accelerometer's specific force rotated into the navigation frame must
  point up, ``mean(R f / |f|)_z`` close to 1 (passes above 0.8);
* north test (when a magnetometer exists): the horizontal part of the rotated field must point
  north, ``mean((R m)_xy / |(R m)_xy|)_y`` above 0.5. Phones derive their heading from the same
  magnetometer, so this holds indoors too unless the field is badly disturbed.

The gravity test cannot see a rotation about the vertical and the north test needs a
magnetometer, so without one the yaw reference stays the documented, unverified one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hrtls.data.series import SensorSeries
from hrtls.data.validation import FloatArray
from hrtls.frames import (
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)

GRAVITY_PASS = 0.8
"""Least mean vertical component of the rotated unit specific force for a pass."""
NORTH_PASS = 0.5
"""Least mean north component of the rotated unit horizontal field for a pass."""
_MAX_CHECK_SAMPLES = 5000

FRAME_TO_ENU: dict[str, FloatArray] = {
    "enu": np.array([1.0, 0.0, 0.0, 0.0]),
    # x north, y west, z up: a quarter turn about z takes north to +y (ENU north)
    "nwu": np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]),
    # x north, y east, z down: a half turn about the (1, 1, 0) diagonal swaps x/y and flips z
    "ned": np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0]),
}
"""``q_n,ref``: rotation from an app's reference frame into ENU."""


def quat_axis(axis: str, angle_rad: FloatArray) -> FloatArray:
    """Quaternions of rotations by ``angle_rad`` about the x, y or z axis."""
    vec = np.zeros((len(angle_rad), 3))
    vec[:, "xyz".index(axis)] = angle_rad
    return quat_from_rotvec(vec)


def reference_to_enu(q_ref_d: FloatArray, frame: str, *, inverse: bool = False) -> FloatArray:
    """``q_nd`` from quaternions relating the device to an app's reference frame.

    ``inverse=False`` reads ``q`` as device -> reference, ``True`` as reference -> device.
    """
    q = quat_conjugate(q_ref_d) if inverse else q_ref_d
    return quat_normalize(quat_multiply(FRAME_TO_ENU[frame][None, :], q))


@dataclass(frozen=True, slots=True)
class OrientationScore:
    """Agreement of an orientation with gravity and the magnetic field (None: not tested)."""

    gravity: float | None
    north: float | None

    @property
    def passes(self) -> bool:
        """True when every available test passes (and at least one was possible)."""
        if self.gravity is None and self.north is None:
            return False
        return ((self.gravity is None or self.gravity >= GRAVITY_PASS)
                and (self.north is None or self.north >= NORTH_PASS))

    def describe(self) -> str:
        """E.g. ``"gravity 0.97, north 0.95"``."""
        parts = []
        if self.gravity is not None:
            parts.append(f"gravity {self.gravity:.2f}")
        if self.north is not None:
            parts.append(f"north {self.north:.2f}")
        return ", ".join(parts) if parts else "no test possible"


def _overlap(t_q: FloatArray, series: SensorSeries | None
             ) -> tuple[np.ndarray, FloatArray]:
    """Indices of orientation samples inside the series' span and the series there."""
    if series is None or len(series.t) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    idx = np.flatnonzero((t_q >= series.t[0]) & (t_q <= series.t[-1]))
    if len(idx) > _MAX_CHECK_SAMPLES:
        idx = idx[np.linspace(0, len(idx) - 1, _MAX_CHECK_SAMPLES).astype(np.int64)]
    return idx, series.interpolate(t_q[idx])


def score_orientation(t_q: FloatArray, q_nd: FloatArray, *, accel: SensorSeries | None,
                      mag: SensorSeries | None) -> OrientationScore:
    """Gravity and north scores of ``q_nd`` (see the module docstring)."""
    gravity = north = None
    idx, f = _overlap(t_q, accel)
    norm = np.linalg.norm(f, axis=1)
    ok = norm > 1e-6
    if np.count_nonzero(ok) >= 10:
        up = quat_rotate(q_nd[idx[ok]], f[ok] / norm[ok, None])
        gravity = float(np.mean(up[:, 2]))
    idx, m = _overlap(t_q, mag)
    if len(idx) >= 10:
        mn = quat_rotate(q_nd[idx], m)
        h = mn[:, :2]
        hn = np.linalg.norm(h, axis=1)
        ok = hn > 1e-6
        if np.count_nonzero(ok) >= 10:
            north = float(np.mean(h[ok, 1] / hn[ok]))
    return OrientationScore(gravity, north)


def choose_orientation(t_q: FloatArray, candidates: Sequence[tuple[str, Callable[[], FloatArray]]],
                       *, accel: SensorSeries | None, mag: SensorSeries | None, where: str,
                       notes: list[str], verify_only: bool = False) -> tuple[str, FloatArray]:
    """Pick the reading of an app's orientation that the recording supports.

    Parameters
    ----------
    t_q:
        Orientation times, s.
    candidates:
        ``(name, make_q_nd)`` pairs; the first is the documented reading.
    accel, mag:
        Device-frame specific force (m/s^2) and field (uT) for the tests, or None.
    where:
        The file, for the notes.
    notes:
        Session notes; the choice and its scores are appended.
    verify_only:
        Keep the first candidate whatever the scores (an explicit user choice); only report.

    Returns
    -------
    The chosen candidate's name and ``q_nd`` (N, 4).
    """
    name0, make0 = candidates[0]
    q0 = make0()
    s0 = score_orientation(t_q, q0, accel=accel, mag=mag)
    if verify_only or s0.passes:
        verdict = ("agrees with the recording" if s0.passes else
                   "NOT confirmed by the recording" if s0.gravity is not None or
                   s0.north is not None else "unverified (no accelerometer to test it)")
        yaw = "" if s0.north is not None else "; yaw reference unverified (no magnetometer)"
        notes.append(f"{where}: orientation read as {name0!r}, {verdict} ({s0.describe()}){yaw}")
        return name0, q0
    best: tuple[str, FloatArray, OrientationScore] | None = None
    for name, make in candidates[1:]:
        q = make()
        s = score_orientation(t_q, q, accel=accel, mag=mag)
        if s.passes and (best is None or _rank(s) > _rank(best[2])):
            best = (name, q, s)
    if best is None:
        notes.append(f"{where}: orientation read as {name0!r} (documented reading), but the "
                     f"recording does not confirm it ({s0.describe()}) and no alternative fits; "
                     "treat the orientation as unverified")
        return name0, q0
    name, q, s = best
    yaw = "" if s.north is not None else "; yaw reference unverified (no magnetometer)"
    notes.append(f"{where}: documented orientation reading {name0!r} disagrees with the "
                 f"recording ({s0.describe()}); using {name!r} instead ({s.describe()}){yaw}")
    return name, q


def _rank(score: OrientationScore) -> float:
    return (score.gravity or 0.0) + (score.north or 0.0)
