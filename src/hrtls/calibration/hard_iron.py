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
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.calibration._running_fit_kernel import (
    FIT_FAILED,
    FIT_NARROW,
    FIT_OK,
    FIT_SHORT_ARC,
    GATE_PASSES,
)
from hrtls.data import ImuStream
from hrtls.errors import InputError
from hrtls.frames import FloatArray

__all__ = ["HardIronFit", "checked_fit", "fit_hard_iron", "plane_basis"]


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


def _sequential_sum(x: FloatArray) -> FloatArray:
    """Sums over the first axis added in row order, from the first row.

    ``np.sum`` adds in pairs (other rounding); the fit's sums keep this order at any length.
    """
    return np.cumsum(x, axis=0)[-1]


def _solve(p: FloatArray, keep: np.ndarray) -> tuple[FloatArray, float]:
    """Least-squares circle (sphere) through the rows ``keep`` of ``p``: ``(centre, r^2)``.

    ``|u|^2 = 2 c.u + k`` for ``u = p - mean``, by the normal equations of its (k+1) unknowns
    (Gaussian elimination with partial pivoting); ``r^2 = k + |c|^2``.
    """
    q = p[keep]
    mean = _sequential_sum(q) / len(q)
    u = q - mean
    rows = np.empty((len(q), q.shape[1] + 1))      # A = [2u, 1], b = |u|^2
    rows[:, :-1] = 2.0 * u
    rows[:, -1] = 1.0
    bb = u[:, 0] * u[:, 0]
    for a in range(1, q.shape[1]):
        bb = bb + u[:, a] * u[:, a]
    m = _sequential_sum(np.concatenate([rows[:, :, None] * rows[:, None, :],
                                        (rows * bb[:, None])[:, :, None]], axis=2))
    return _eliminate(m.tolist(), mean.tolist())


def _eliminate(m: list[list[float]], mean: list[float]) -> tuple[FloatArray, float]:
    """Centre and ``r^2`` from the normal equations ``m = [A^T A | A^T b]`` of the rows ``u``.

    Gaussian elimination with partial pivoting in Python floats (``m`` is overwritten; a
    singular system raises :class:`ZeroDivisionError`).
    """
    dim = len(mean)
    k = dim + 1
    for col in range(k):
        piv = col
        for r in range(col + 1, k):
            if abs(m[r][col]) > abs(m[piv][col]):
                piv = r
        m[col], m[piv] = m[piv], m[col]
        for r in range(col + 1, k):
            f = m[r][col] / m[col][col]
            for c in range(col, k + 1):
                m[r][c] -= f * m[col][c]
    x = [0.0] * k
    for r in range(k - 1, -1, -1):
        acc = m[r][k]
        for c in range(r + 1, k):
            acc -= m[r][c] * x[c]
        x[r] = acc / m[r][r]
    r2 = x[dim]
    for a in range(dim):
        r2 += x[a] * x[a]
    return np.array([mean[a] + x[a] for a in range(dim)]), r2


def _distance(p: FloatArray, c: FloatArray) -> FloatArray:
    """Distance of each row of ``p`` from ``c`` (squares added in axis order)."""
    d2 = (p[:, 0] - c[0]) * (p[:, 0] - c[0])
    for a in range(1, p.shape[1]):
        d2 = d2 + (p[:, a] - c[a]) * (p[:, a] - c[a])
    return np.sqrt(d2)


def _gated_fit(p: FloatArray, gate_fraction: float, min_samples: int, passes: int
               ) -> tuple[FloatArray, float, np.ndarray, bool]:
    """The fit, then up to ``passes`` refits on the samples within the gate of the latest.

    Each pass judges all samples (inliers a biased first fit dropped come back); it stops when
    fewer than ``min_samples`` would be kept or the kept set no longer changes in size. Returns
    ``(centre, r, kept rows, ok)``; ``ok`` false: a fit gave ``r^2 <= 0``.
    """
    n = p.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    c, r2 = _solve(p, keep)
    if not r2 > 0.0:
        return c, 0.0, keep, False
    r = math.sqrt(r2)
    n_used = n
    for k in range(passes):
        new = np.abs(_distance(p, c) - r) <= gate_fraction * r
        n_new = int(new.sum())
        if n_new < min_samples or (n_used == n_new and k > 0):
            break
        keep, n_used = new, n_new
        c, r2 = _solve(p, keep)
        if not r2 > 0.0:
            return c, 0.0, keep, False
        r = math.sqrt(r2)
    return c, r, keep, True


def _spread(d: FloatArray) -> tuple[float, float]:
    """Angle covered by the 2-D vectors ``d`` (N, 2) around the origin, deg; their extent.

    The angle is 360 deg less the widest gap between neighbouring directions, the wrap-around
    gap included. The extent is the largest range of one coordinate.
    """
    ang = np.sort(np.arctan2(d[:, 1], d[:, 0]))
    lo, hi = float(ang[0]), float(ang[-1])
    gap = lo + 2.0 * math.pi - hi
    if len(ang) > 1:
        gap = max(gap, float(np.diff(ang).max()))
    extent = float((d.max(axis=0) - d.min(axis=0)).max())
    return 360.0 - math.degrees(gap), extent


def _fit(m: FloatArray, basis: FloatArray, gate_fraction: float, min_samples: int,
         passes: int) -> tuple[bool, FloatArray, float, float, FloatArray]:
    """Samples ``m`` (N, 3) projected on the rows of ``basis``, gated fit, residual.

    Returns ``(ok, c, r, residual, d)`` with the centre ``c`` in the projected coordinates and
    ``d`` the kept samples about it (``n_used`` rows); ``ok`` false: a fit gave ``r^2 <= 0``
    (the rest is then unset).
    """
    p = np.stack([m[:, 0] * b[0] + m[:, 1] * b[1] + m[:, 2] * b[2] for b in basis], axis=1)
    c, r, keep, ok = _gated_fit(p, gate_fraction, min_samples, passes)
    if not ok:
        return False, c, 0.0, math.nan, np.empty((0, basis.shape[0]))
    d = p[keep] - c
    e = _distance(d, np.zeros(d.shape[1])) - r
    resid = math.sqrt(float(_sequential_sum(e * e)) / len(d))
    return True, c, r, resid, d


def _main_axes(d: FloatArray) -> FloatArray:
    """The 3-D vectors ``d`` in the plane of their two main axes (N, 2)."""
    _, _, vt = np.linalg.svd(d - d.sum(axis=0) / len(d), full_matrices=False)
    return np.ascontiguousarray(d @ np.ascontiguousarray(vt[:2].T))


def _plane_basis(up_d: ArrayLike | None) -> FloatArray:
    """Rows spanning the plane perpendicular to ``up_d`` (identity without ``up_d``)."""
    if up_d is None:
        return np.eye(3)
    up = np.asarray(up_d, dtype=np.float64)
    norm = math.sqrt(float(up @ up)) if up.shape == (3,) else math.nan
    if not (math.isfinite(norm) and norm > 0.0):
        raise InputError(f"up_d = {up_d!r}", where="hard-iron fit",
                         expected="a finite non-zero 3-vector")
    return plane_basis(up)


def plane_basis(up_d: FloatArray) -> FloatArray:
    """Rows (2, 3) spanning the plane perpendicular to ``up_d`` (finite, non-zero)."""
    u0, u1, u2 = (float(v) for v in up_d)
    norm = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    up = (u0 / norm, u1 / norm, u2 / norm)
    axis = [0.0, 0.0, 0.0]
    axis[int(np.argmin(np.abs(up)))] = 1.0
    e1 = _cross3(up, axis)            # up x its least aligned axis
    n1 = math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    e1 = [v / n1 for v in e1]
    return np.array([e1, _cross3(up, e1)])


def _cross3(a: Sequence[float], b: Sequence[float]) -> list[float]:
    """``a x b`` of two 3-vectors."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def checked_fit(m: FloatArray, basis: FloatArray, gate_fraction: float, min_samples: int,
                min_field_ut: float, min_arc_deg: float
                ) -> tuple[int, FloatArray, float, float, float, float, int]:
    """:func:`_fit` on a plane ``basis`` (2, 3) or the identity (a sphere), and its tests.

    Returns ``(code, c, r, residual, arc_deg, extent, n_used)``: ``code`` one of ``FIT_*``
    (the acceptance tests), ``c`` the offset in the device frame (``centre @ basis``, valid
    with ``FIT_OK``). For a sphere the coverage is measured in the plane of the two main axes
    of the kept samples.
    """
    ok, cp, r, resid, d = _fit(m, basis, gate_fraction, min_samples, GATE_PASSES)
    n_used = d.shape[0]
    c = np.zeros(3)
    if not ok:
        return FIT_FAILED, c, r, resid, math.nan, math.nan, n_used
    arc, extent = _spread(d if basis.shape[0] == 2 else _main_axes(d))
    for a in range(basis.shape[0]):
        c = c + cp[a] * basis[a]
    # samples that hardly move (no turning) fit a small circle around their own noise
    code = (FIT_NARROW if r < min_field_ut or extent < r
            else FIT_SHORT_ARC if arc < min_arc_deg else FIT_OK)
    return code, c, r, resid, arc, extent, n_used


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
    if not np.isfinite(m.sum()):
        m = m[np.all(np.isfinite(m), axis=1)]
    if len(m) > max_samples:  # evenly thinned: the offset needs the headings, not every sample
        m = m[:: -(-len(m) // max_samples)]
    if len(m) < min_samples:
        raise InputError(f"{len(m)} finite samples", where="hard-iron fit",
                         expected=f"at least {min_samples}")
    basis = _plane_basis(up_d)
    code, c, r, resid, arc, extent, n_used = checked_fit(
        np.ascontiguousarray(m), basis, float(gate_fraction), int(min_samples),
        float(min_field_ut), float(min_arc_deg))
    if code == FIT_FAILED:
        raise InputError("circle fit failed", where="hard-iron fit",
                         expected="field samples from a device that turned")
    if code == FIT_NARROW:
        raise InputError(f"the field samples span {extent:.1f} uT around a fitted "
                         f"{r:.1f} uT circle", where="hard-iron fit",
                         expected=f"a field of at least {min_field_ut:.0f} uT seen from many "
                                  "headings", hint="walk a loop or turn around")
    if code == FIT_SHORT_ARC:
        raise InputError(f"the field turned through {arc:.0f} deg", where="hard-iron fit",
                         expected=f"at least {min_arc_deg:.0f} deg of turning",
                         hint="walk a loop or turn around; or calibrate with a figure of eight")
    return HardIronFit(hard_iron_ut=c, field_ut=r, residual_ut=resid, arc_deg=arc,
                       n_used=n_used)


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
