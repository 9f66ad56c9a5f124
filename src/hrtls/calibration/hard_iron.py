"""Hard-iron offset of a magnetometer from an ordinary recording (our addition).

The thesis calibrates the magnetometer before use by swinging it through a figure of eight
(:func:`hrtls.calibration.fit_magnetometer`). A device worn at the waist and never calibrated
carries a hard-iron offset ``c`` (field of its own magnetised parts, fixed in the device frame)
of a few uT; against a horizontal Earth field of about 20 uT that is a heading error of up to
``asin(|c_h| / |h|)`` that changes with the heading (15 deg for 5 uT), which no tag or fix can
remove because it is not a drift.

While the wearer walks and turns, the device rotates about the vertical, so the raw field
samples projected on the device's horizontal plane (perpendicular to ``up_d``, the mean
direction of the specific force in the device frame) lie on a circle around the horizontal part
of ``c``; a least-squares circle fit (``|p|^2 = 2 c.p + k``) gives it. The part of ``c`` along
``up_d`` is not observed by a device that stays near one tilt and is left at zero: it does not
change the horizontal field direction at that tilt. Without ``up_d`` the samples are taken to
cover all orientations (a figure of eight) and a sphere is fitted in 3-D.

The samples are first averaged over blocks of about a second: the pelvis sways at the stride
frequency and tilts part of the vertical field into the horizontal plane, which biases a circle
fit to a short arc; block means remove that sway, so the fit and its coverage test stay true
down to half a turn.

Samples off the circle (sphere) by more than ``gate_fraction`` of its radius (magnetic
disturbances) are dropped and the fit is repeated, up to three times, each time judging all
samples against the latest fit. The fit is refused (:class:`InputError`) when the field
directions in the fitted plane leave a gap wider than ``360 - min_arc_deg`` degrees (180 by
default), when the fitted radius is below ``min_field_ut`` or when the samples span less than
one radius: with less turning the centre is not determined.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data import ImuStream
from hrtls.errors import InputError
from hrtls.frames import FloatArray

__all__ = ["HardIronFit", "fit_hard_iron"]

_GATE_PASSES = 3
"""Refits after dropping the samples off the circle (sphere)."""


@dataclass(frozen=True, slots=True)
class HardIronFit:
    """Result of :func:`fit_hard_iron`.

    hard_iron_ut: offset ``c`` to subtract from the raw field (device frame), uT.
    field_ut: radius of the fitted circle (horizontal field) or sphere (whole field), uT.
    residual_ut: RMS distance of the samples kept from the circle (sphere), uT.
    arc_deg: angle covered by the field directions around the centre, deg.
    n_used: samples kept after the disturbance gate.
    """

    hard_iron_ut: FloatArray
    field_ut: float
    residual_ut: float
    arc_deg: float
    n_used: int


def _solve(p: FloatArray) -> tuple[FloatArray, float]:
    """Least-squares circle (2 columns) or sphere (3 columns) fit; returns ``(centre, r)``."""
    mean = p.mean(axis=0)
    u = p - mean
    a = np.column_stack([2.0 * u, np.ones(len(u))])
    x, *_ = np.linalg.lstsq(a, np.sum(u * u, axis=1), rcond=None)
    k = p.shape[1]
    c_local = x[:k]
    r2 = float(x[k] + c_local @ c_local)
    if not r2 > 0.0:
        raise InputError("circle fit failed", where="hard-iron fit",
                         expected="field samples from a device that turned")
    return mean + c_local, math.sqrt(r2)


def _arc_deg(p: FloatArray) -> float:
    """Angle covered by the 2-D vectors ``p`` (N, 2) around the origin, deg."""
    ang = np.sort(np.arctan2(p[:, 1], p[:, 0]))
    gaps = np.diff(np.r_[ang, ang[0] + 2.0 * math.pi])
    return float(360.0 - math.degrees(float(gaps.max())))


def fit_hard_iron(mag_ut: ArrayLike, *, up_d: ArrayLike | None = None,
                  block_samples: int = 1, min_arc_deg: float = 180.0, gate_fraction: float = 0.15,
                  min_field_ut: float = 5.0, min_samples: int = 50,
                  max_samples: int = 20_000) -> HardIronFit:
    """Hard-iron offset from the raw field samples (N, 3) of a recording, uT.

    ``up_d``: the device's mean up direction in the device frame (e.g. the mean accelerometer
    reading of a waist-worn device); None for samples in all orientations. ``block_samples``:
    consecutive samples averaged before the fit (about one second of data averages out the
    sway of each stride). Longer inputs are thinned evenly to ``max_samples`` (after the
    averaging). See the module notes.
    """
    m = np.asarray(mag_ut, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 3:
        raise InputError(f"shape {m.shape}", where="hard-iron fit", expected="(N, 3) uT")
    if block_samples < 1:
        raise InputError(f"block_samples = {block_samples}", where="hard-iron fit",
                         expected="at least 1")
    if block_samples > 1:
        n = len(m) // block_samples * block_samples
        blocks = m[:n].reshape(-1, block_samples, 3)
        ok = np.all(np.isfinite(blocks), axis=(1, 2))  # a block with a gap is dropped
        m = blocks[ok].mean(axis=1)
    m = m[np.all(np.isfinite(m), axis=1)]
    if len(m) > max_samples:  # evenly thinned: the offset needs the headings, not every sample
        m = m[:: -(-len(m) // max_samples)]
    if len(m) < min_samples:
        raise InputError(f"{len(m)} finite samples", where="hard-iron fit",
                         expected=f"at least {min_samples}")
    if up_d is None:
        basis = np.eye(3)
    else:
        up = np.asarray(up_d, dtype=np.float64)
        if up.shape != (3,) or not np.all(np.isfinite(up)) or not np.linalg.norm(up) > 0:
            raise InputError(f"up_d = {up_d!r}", where="hard-iron fit",
                             expected="a finite non-zero 3-vector")
        up = up / np.linalg.norm(up)
        # two unit vectors spanning the plane perpendicular to up
        e1 = np.cross(up, np.eye(3)[int(np.argmin(np.abs(up)))])
        e1 /= np.linalg.norm(e1)
        basis = np.vstack([e1, np.cross(up, e1)])
    p_all = m @ basis.T
    p = p_all
    c, r = _solve(p)
    for _ in range(_GATE_PASSES):
        # judged on all samples, so that inliers a biased first fit dropped come back
        keep = np.abs(np.linalg.norm(p_all - c, axis=1) - r) <= gate_fraction * r
        if keep.sum() < min_samples or (len(p) == int(keep.sum()) and p is not p_all):
            break
        p = p_all[keep]
        c, r = _solve(p)
    d = p - c
    if d.shape[1] == 3:  # directions in the plane of their two main axes
        _, _, vt = np.linalg.svd(d - d.mean(axis=0), full_matrices=False)
        d = d @ vt[:2].T
    arc = _arc_deg(d)
    extent = float(np.max(np.ptp(d, axis=0)))
    if r < min_field_ut or extent < r:
        # samples that hardly move (no turning) fit a small circle around their own noise
        raise InputError(f"the field samples span {extent:.1f} uT around a fitted "
                         f"{r:.1f} uT circle", where="hard-iron fit",
                         expected=f"a field of at least {min_field_ut:.0f} uT seen from many "
                                  "headings", hint="walk a loop or turn around")
    if arc < min_arc_deg:
        raise InputError(f"the field turned through {arc:.0f} deg", where="hard-iron fit",
                         expected=f"at least {min_arc_deg:.0f} deg of turning",
                         hint="walk a loop or turn around; or calibrate with a figure of eight")
    resid = float(np.sqrt(np.mean((np.linalg.norm(p - c, axis=1) - r) ** 2)))
    return HardIronFit(hard_iron_ut=np.asarray(c @ basis, dtype=np.float64), field_ut=r,
                       residual_ut=resid, arc_deg=arc, n_used=len(p))


def hard_iron_samples(imu: ImuStream, window_s: float = 0.0
                      ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Magnetometer samples and mean up direction for the hard-iron fit of ``[offline] two_pass``.

    The first ``window_s`` of the magnetometer (0: all of it) and the mean accelerometer
    reading over the same time; ``(None, None)`` without a magnetometer.
    """
    if imu.mag is None or not len(imu.mag.t):
        return None, None
    tm = imu.mag.t
    n_mag = int(np.searchsorted(tm, tm[0] + window_s)) if window_s > 0 else len(tm)
    n_mag = max(n_mag, 1)
    ta = imu.accel.t
    a0, a1 = np.searchsorted(ta, [tm[0], tm[n_mag - 1]], side="left")
    acc = imu.accel.values[a0:a1 + 1] if a1 >= a0 else imu.accel.values
    up = acc.mean(axis=0)
    if not np.all(np.isfinite(up)):
        up = np.nanmean(acc, axis=0)
    return imu.mag.values[:n_mag], up
