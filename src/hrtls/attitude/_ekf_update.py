"""Linear algebra of the attitude EKFs: stacked 3-row updates, 3 x 3 inverses, variances."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from hrtls.attitude._jit import FASTMATH, JIT
from hrtls.frames import FloatArray
from hrtls.kernels import njit


@njit(inline="always", **JIT)
def nav_rotation_var(
    w: float, x: float, y: float, z: float, P: FloatArray, out: FloatArray, i: int
) -> None:
    """Variances of the small rotation about the ENU axes implied by a quaternion covariance.

    ``dtheta_n = 2 vec(dq * conj(q)) = 2 M dq``; writes ``diag(4 M P M^T)`` to ``out[i]``.
    """
    m = ((-x, w, -z, y), (-y, z, w, -x), (-z, -y, x, w))
    for r in range(3):
        row = m[r]
        acc = 0.0
        for a in range(4):
            pa = 0.0
            for b in range(4):
                pa += P[a, b] * row[b]
            acc += row[a] * pa
        out[i, r] = 4.0 * acc


@njit(inline="always", **JIT)
def sym3_inverse(
    s00: float, s01: float, s02: float, s11: float, s12: float, s22: float
) -> tuple[bool, float, float, float, float, float, float]:
    """Inverse of a symmetric positive definite 3 x 3 matrix by cofactors (upper triangle).

    Returns False and zeros when the determinant is not positive.
    """
    c00 = s11 * s22 - s12 * s12
    c01 = s02 * s12 - s01 * s22
    c02 = s01 * s12 - s02 * s11
    det = s00 * c00 + s01 * c01 + s02 * c02
    if not det > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    inv = 1.0 / det
    return (True, c00 * inv, c01 * inv, c02 * inv, (s00 * s22 - s02 * s02) * inv,
            (s01 * s02 - s00 * s12) * inv, (s00 * s11 - s01 * s01) * inv)


def make_block3(n: int, m: int) -> Callable[..., bool]:
    """Compile the 3-row block update for ``n`` states of which the first ``m`` are measured.

    ``H`` is zero beyond column ``m`` (e.g. the gyro bias is not measured directly); fixed
    sizes let LLVM unroll the loops.
    """

    # closures of one qualname must not share a cache entry: no cache
    @njit(inline="always", fastmath=FASTMATH, error_model="numpy")
    def update(
        P: FloatArray, dx: FloatArray, H: Any, r0: float, r1: float, r2: float, var: float,
        ph: FloatArray,
    ) -> bool:
        """EKF update with a 3-row measurement block, linearised at the prediction.

        ``dx`` is the correction accumulated so far from earlier blocks (all blocks share one
        linearisation point), so consecutive blocks equal one stacked update (eq. 4.19 / Colombo
        eq. 8-11): ``S = H P H^T + var I``, ``K = P H^T S^-1``, ``dx += K (r - H dx)``,
        ``P -= K H P``. ``H`` is a tuple of three rows, each a tuple of ``m`` values (held in
        registers); ``ph`` is an (n, 3) work array. Returns False (nothing changed) when ``S``
        is not positive definite.
        """
        H0, H1, H2 = H
        for a in range(n):
            acc0 = 0.0
            acc1 = 0.0
            acc2 = 0.0
            for b in range(m):
                pab = P[a, b]
                acc0 += pab * H0[b]
                acc1 += pab * H1[b]
                acc2 += pab * H2[b]
            ph[a, 0] = acc0
            ph[a, 1] = acc1
            ph[a, 2] = acc2
        s00 = var
        s01 = 0.0
        s02 = 0.0
        s11 = var
        s12 = 0.0
        s22 = var
        e0 = r0
        e1 = r1
        e2 = r2
        for a in range(m):
            h0 = H0[a]
            h1 = H1[a]
            h2 = H2[a]
            s00 += h0 * ph[a, 0]
            s01 += h0 * ph[a, 1]
            s02 += h0 * ph[a, 2]
            s11 += h1 * ph[a, 1]
            s12 += h1 * ph[a, 2]
            s22 += h2 * ph[a, 2]
            e0 -= h0 * dx[a]
            e1 -= h1 * dx[a]
            e2 -= h2 * dx[a]
        ok, i00, i01, i02, i11, i12, i22 = sym3_inverse(s00, s01, s02, s11, s12, s22)
        if not ok:
            return False
        for a in range(n):
            p0 = ph[a, 0]
            p1 = ph[a, 1]
            p2 = ph[a, 2]
            k0 = p0 * i00 + p1 * i01 + p2 * i02
            k1 = p0 * i01 + p1 * i11 + p2 * i12
            k2 = p0 * i02 + p1 * i12 + p2 * i22
            dx[a] += k0 * e0 + k1 * e1 + k2 * e2
            # P[a, b] -= K[a, :] . ph[b, :]; the upper triangle, mirrored afterwards
            for b in range(a, n):
                P[a, b] -= k0 * ph[b, 0] + k1 * ph[b, 1] + k2 * ph[b, 2]
        for a in range(n):
            for b in range(a):
                P[a, b] = P[b, a]
        return True

    return update


block3_update = make_block3(3, 3)
"""Block update for 3 states (the Euler EKF); see ``make_block3``."""
block3_update7 = make_block3(7, 4)
"""Block update for 7 states (the quaternion EKF with bias)."""


@njit(inline="always", **JIT)
def update_finite(dx: FloatArray, P: FloatArray) -> bool:
    """The correction and the variances of an EKF update are all finite."""
    ok = True
    for r in range(dx.shape[0]):
        ok = ok and math.isfinite(dx[r]) and math.isfinite(P[r, r])
    return ok
