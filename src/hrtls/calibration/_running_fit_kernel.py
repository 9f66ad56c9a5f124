"""The refit of :mod:`hrtls.calibration.hard_iron_running` as one compiled pass.

:func:`~hrtls.calibration.hard_iron.checked_fit` on the plane perpendicular to ``up``, with the
same operations in the same order (the same result to the last bit, tested), in plain loops
over scalars: a few small kernels, quick to compile on a first run, and no numpy call per
step of the fit (a long recording refits every ten seconds).
"""

from __future__ import annotations

import math

import numpy as np

from hrtls.frames import FloatArray
from hrtls.kernels import njit

GATE_PASSES = 3
"""Refits after dropping the samples off the circle (sphere)."""
FIT_OK, FIT_FAILED, FIT_NARROW, FIT_SHORT_ARC = 0, 1, 2, 3
"""Outcomes of a fit: accepted; a fit gave ``r^2 <= 0``; radius below ``min_field_ut`` or
samples spanning less than one radius; too little turning."""


@njit(cache=True)
def running_fit_kernel(m: FloatArray, up: FloatArray, gate_fraction: float, min_samples: int,
                       min_field_ut: float, min_arc_deg: float, out: FloatArray
                       ) -> tuple[int, int]:  # pragma: no cover - compiled
    """Circle fit of the field samples ``m`` (N, 3) in the plane perpendicular to ``up``.

    Returns ``(code, n_used)``; ``out`` gets the offset ``c`` (3, device frame), ``r``, the
    residual and the covered angle (deg), valid with ``FIT_OK``.
    """
    norm = math.sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2])
    u0, u1, u2 = up[0] / norm, up[1] / norm, up[2] / norm
    least = 1 if abs(u1) < abs(u0) else 0   # the axis least aligned with up (first of equals)
    if abs(u2) < (abs(u1) if least == 1 else abs(u0)):
        least = 2
    a0 = 1.0 if least == 0 else 0.0
    a1 = 1.0 if least == 1 else 0.0
    a2 = 1.0 if least == 2 else 0.0
    e0, e1, e2 = u1 * a2 - u2 * a1, u2 * a0 - u0 * a2, u0 * a1 - u1 * a0
    n1 = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    e0, e1, e2 = e0 / n1, e1 / n1, e2 / n1
    f0, f1, f2 = u1 * e2 - u2 * e1, u2 * e0 - u0 * e2, u0 * e1 - u1 * e0
    n = m.shape[0]
    p = np.empty((n, 2))
    for i in range(n):
        p[i, 0] = m[i, 0] * e0 + m[i, 1] * e1 + m[i, 2] * e2
        p[i, 1] = m[i, 0] * f0 + m[i, 1] * f1 + m[i, 2] * f2
    keep = np.ones(n, dtype=np.bool_)
    c0, c1, r2 = _plane_solve(p, keep)
    if not r2 > 0.0:
        return FIT_FAILED, 0
    r = math.sqrt(r2)
    n_used = n
    for k in range(GATE_PASSES):
        new = np.empty(n, dtype=np.bool_)
        n_new = 0
        for i in range(n):
            d0 = p[i, 0] - c0
            d1 = p[i, 1] - c1
            new[i] = abs(math.sqrt(d0 * d0 + d1 * d1) - r) <= gate_fraction * r
            n_new += new[i]
        if n_new < min_samples or (n_used == n_new and k > 0):
            break
        keep = new
        n_used = n_new
        c0, c1, r2 = _plane_solve(p, keep)
        if not r2 > 0.0:
            return FIT_FAILED, 0
        r = math.sqrt(r2)
    d = np.empty((n_used, 2))
    j = 0
    resid = 0.0
    for i in range(n):
        if keep[i]:
            d[j, 0] = p[i, 0] - c0
            d[j, 1] = p[i, 1] - c1
            e = math.sqrt(d[j, 0] * d[j, 0] + d[j, 1] * d[j, 1]) - r
            resid += e * e
            j += 1
    arc, extent = _covered_arc(d)
    out[0] = c0 * e0 + c1 * f0
    out[1] = c0 * e1 + c1 * f1
    out[2] = c0 * e2 + c1 * f2
    out[3], out[4], out[5] = r, math.sqrt(resid / n_used), arc
    # samples that hardly move (no turning) fit a small circle around their own noise
    code = (FIT_NARROW if r < min_field_ut or extent < r
            else FIT_SHORT_ARC if arc < min_arc_deg else FIT_OK)
    return code, n_used


@njit(cache=True)
def _plane_solve(p: FloatArray, keep: np.ndarray) -> tuple[float, float, float]:
    # pragma: no cover - compiled
    """Least-squares circle through the rows ``keep`` of ``p`` (N, 2): ``(c0, c1, r^2)``.

    The normal equations of ``|u|^2 = 2 c.u + k`` (``u = p - mean``), then Gaussian
    elimination with partial pivoting; a singular system raises ``ZeroDivisionError``.
    """
    n = 0
    m0 = 0.0
    m1 = 0.0
    for i in range(p.shape[0]):
        if keep[i]:
            n += 1
            m0 += p[i, 0]
            m1 += p[i, 1]
    m0 /= n
    m1 /= n
    a = np.zeros((3, 4))   # [A^T A | A^T b], A = [2u, 1], b = |u|^2
    for i in range(p.shape[0]):
        if not keep[i]:
            continue
        r0 = 2.0 * (p[i, 0] - m0)
        r1 = 2.0 * (p[i, 1] - m1)
        bb = 0.0 + (p[i, 0] - m0) * (p[i, 0] - m0)
        bb += (p[i, 1] - m1) * (p[i, 1] - m1)
        a[0, 0] += r0 * r0
        a[0, 1] += r0 * r1
        a[0, 2] += r0
        a[0, 3] += r0 * bb
        a[1, 1] += r1 * r1
        a[1, 2] += r1
        a[1, 3] += r1 * bb
        a[2, 2] += 1.0
        a[2, 3] += bb
    a[1, 0], a[2, 0], a[2, 1] = a[0, 1], a[0, 2], a[1, 2]
    for col in range(3):
        piv = col
        for r in range(col + 1, 3):
            if abs(a[r, col]) > abs(a[piv, col]):
                piv = r
        for c in range(4):
            tmp = a[col, c]
            a[col, c] = a[piv, c]
            a[piv, c] = tmp
        for r in range(col + 1, 3):
            f = a[r, col] / a[col, col]
            for c in range(col, 4):
                a[r, c] -= f * a[col, c]
    x2 = a[2, 3] / a[2, 2]
    x1 = (a[1, 3] - a[1, 2] * x2) / a[1, 1]
    x0 = ((a[0, 3] - a[0, 1] * x1) - a[0, 2] * x2) / a[0, 0]
    return m0 + x0, m1 + x1, x2 + x0 * x0 + x1 * x1


@njit(cache=True)
def _covered_arc(d: FloatArray) -> tuple[float, float]:  # pragma: no cover - compiled
    """Angle covered by the 2-D vectors ``d`` (N, 2) around the origin, deg; their extent.

    As :func:`hrtls.calibration.hard_iron._spread`: 360 deg less the widest gap between
    neighbouring directions, found without sorting (N directions over a range R leave a gap
    wider than each of N + 1 buckets of width R / N: the widest gap lies between buckets).
    """
    n = d.shape[0]
    ang = np.empty(n)
    lo, hi = math.inf, -math.inf
    lo0, hi0, lo1, hi1 = math.inf, -math.inf, math.inf, -math.inf
    for i in range(n):
        ang[i] = math.atan2(d[i, 1], d[i, 0])
        lo, hi = min(lo, ang[i]), max(hi, ang[i])
        lo0, hi0 = min(lo0, d[i, 0]), max(hi0, d[i, 0])
        lo1, hi1 = min(lo1, d[i, 1]), max(hi1, d[i, 1])
    gap = lo + 2.0 * math.pi - hi
    if hi > lo:
        b_min = np.full(n + 1, math.inf)
        b_max = np.full(n + 1, -math.inf)
        scale = n / (hi - lo)
        for i in range(n):
            k = min(int((ang[i] - lo) * scale), n)
            b_min[k] = min(b_min[k], ang[i])
            b_max[k] = max(b_max[k], ang[i])
        prev = b_max[0]
        for k in range(1, n + 1):
            if b_min[k] <= b_max[k]:
                gap = max(gap, b_min[k] - prev)
                prev = b_max[k]
    return 360.0 - math.degrees(gap), max(0.0, hi0 - lo0, hi1 - lo1)
