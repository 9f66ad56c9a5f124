"""Quaternion and rotation helpers of the attitude kernels (scalar first, Hamilton product).

Conventions (see :mod:`hrtls.frames`): quaternions ``[w, x, y, z]``, ``q`` rotates device
vectors into ENU.
"""

from __future__ import annotations

import math

from hrtls.attitude._jit import JIT
from hrtls.frames import FloatArray
from hrtls.kernels import njit


@njit(inline="always", **JIT)
def qmul(
    aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float, bz: float
) -> tuple[float, float, float, float]:
    """Hamilton product ``a * b``."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@njit(inline="always", **JIT)
def rot_t(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[float, float, float]:
    """``R(q)^T v`` with the homogeneous rotation matrix (exact for unit ``q``)."""
    return (
        (w * w + x * x - y * y - z * z) * v0 + 2.0 * (x * y + w * z) * v1
        + 2.0 * (x * z - w * y) * v2,
        2.0 * (x * y - w * z) * v0 + (w * w - x * x + y * y - z * z) * v1
        + 2.0 * (y * z + w * x) * v2,
        2.0 * (x * z + w * y) * v0 + 2.0 * (y * z - w * x) * v1
        + (w * w - x * x - y * y + z * z) * v2,
    )


@njit(inline="always", **JIT)
def rot(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[float, float, float]:
    """``R(q) v`` for a unit quaternion (device -> navigation)."""
    return rot_t(w, -x, -y, -z, v0, v1, v2)


Row3 = tuple[float, float, float]
Row4 = tuple[float, float, float, float]


@njit(inline="always", **JIT)
def rot_t_jac(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float
) -> tuple[Row4, Row4, Row4]:
    """``d(R(q)^T v)/dq`` (3 x 4, columns w, x, y, z) as three row tuples."""
    return (
        (2.0 * (w * v0 + z * v1 - y * v2), 2.0 * (x * v0 + y * v1 + z * v2),
         2.0 * (-y * v0 + x * v1 - w * v2), 2.0 * (-z * v0 + w * v1 + x * v2)),
        (2.0 * (-z * v0 + w * v1 + x * v2), 2.0 * (y * v0 - x * v1 + w * v2),
         2.0 * (x * v0 + y * v1 + z * v2), 2.0 * (-w * v0 - z * v1 + y * v2)),
        (2.0 * (y * v0 - x * v1 + w * v2), 2.0 * (z * v0 - w * v1 - x * v2),
         2.0 * (w * v0 + z * v1 - y * v2), 2.0 * (x * v0 + y * v1 + z * v2)),
    )


@njit(**JIT)
def rot_t_jacobian(
    w: float, x: float, y: float, z: float, v0: float, v1: float, v2: float, out: FloatArray
) -> None:
    """Write ``d(R(q)^T v)/dq`` (3 x 4, columns w, x, y, z) into ``out``."""
    jac = rot_t_jac(w, x, y, z, v0, v1, v2)
    for j in range(3):
        for b in range(4):
            out[j, b] = jac[j][b]


@njit(inline="always", **JIT)
def cos_sinc(a: float) -> tuple[float, float]:
    """``cos(a)`` and ``sin(a)/a``; Taylor series below 0.1 rad (error < 1e-16)."""
    if abs(a) < 0.1:
        a2 = a * a
        c = 1.0 - a2 / 2.0 * (1.0 - a2 / 12.0 * (1.0 - a2 / 30.0 * (1.0 - a2 / 56.0)))
        sc = 1.0 - a2 / 6.0 * (1.0 - a2 / 20.0 * (1.0 - a2 / 42.0 * (1.0 - a2 / 72.0)))
        return c, sc
    return math.cos(a), math.sin(a) / a


@njit(inline="always", **JIT)
def transition(wx: float, wy: float, wz: float, dt: float, phi: FloatArray) -> None:
    """``Phi = exp(Omega dt)`` for ``dq/dt = Omega q = q * [0, w] / 2`` (Inderst eq. 4.10-4.12).

    ``Omega`` is skew, so the exponential is ``cos(a) I + sin(a)/|w| * 2 Omega`` with
    ``a = |w| dt / 2``.
    """
    n = math.sqrt(wx * wx + wy * wy + wz * wz)
    c, sc = cos_sinc(0.5 * n * dt)
    # sin(a)/|w| = sinc(a) dt / 2 (the 2 of 2 Omega cancels the 1/2 inside Omega)
    s = sc * 0.5 * dt
    phi[0, 0] = c
    phi[0, 1] = -s * wx
    phi[0, 2] = -s * wy
    phi[0, 3] = -s * wz
    phi[1, 0] = s * wx
    phi[1, 1] = c
    phi[1, 2] = s * wz
    phi[1, 3] = -s * wy
    phi[2, 0] = s * wy
    phi[2, 1] = -s * wz
    phi[2, 2] = c
    phi[2, 3] = s * wx
    phi[3, 0] = s * wz
    phi[3, 1] = s * wy
    phi[3, 2] = -s * wx
    phi[3, 3] = c


@njit(**JIT)
def shortest_arc_to_up(ax: float, ay: float, az: float) -> tuple[float, float, float, float]:
    """Quaternion rotating the unit vector ``a`` onto ``+z`` by the shortest arc.

    Our reading of Inderst eq. 4.13 (initial tilt from the specific force at rest): the axis is
    ``a x e_z`` and ``cos(angle) = a_z``, so ``q = [1 + a_z, a_y, -a_x, 0] / norm``.
    """
    w = 1.0 + az
    if w < 1e-9:  # upside down: half turn about x
        return 0.0, 1.0, 0.0, 0.0
    n = math.sqrt(w * w + ay * ay + ax * ax)
    return w / n, ay / n, -ax / n, 0.0


@njit(**JIT)
def heading_from_mag(
    w: float, x: float, y: float, z: float, mx: float, my: float, mz: float
) -> tuple[float, float, float, float]:
    """Rotate ``q`` about the vertical so the horizontal field of ``m`` points north (+y ENU)."""
    nx, ny, _ = rot(w, x, y, z, mx, my, mz)
    if nx * nx + ny * ny < 1e-18:
        return w, x, y, z
    ang = 0.5 * math.pi - math.atan2(ny, nx)
    c = math.cos(0.5 * ang)
    s = math.sin(0.5 * ang)
    return qmul(c, 0.0, 0.0, s, w, x, y, z)


@njit(inline="always", **JIT)
def positive_unit(w: float, x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """``q / |q|`` with the sign chosen so that ``w >= 0``."""
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return w / n, x / n, y / n, z / n


@njit(inline="always", **JIT)
def gyro_quat_step(
    w: float, x: float, y: float, z: float, wx: float, wy: float, wz: float, dt: float
) -> tuple[float, float, float, float]:
    """Gyro step of the attitude, normalised with ``w >= 0`` (Inderst eq. 4.10-4.12).

    ``exp(Omega dt) q = q * [cos(a), sin(a) w / |w|]`` with ``a = |w| dt / 2``.
    """
    c, sc = cos_sinc(0.5 * math.sqrt(wx * wx + wy * wy + wz * wz) * dt)
    sk = 0.5 * dt * sc
    w, x, y, z = qmul(w, x, y, z, c, sk * wx, sk * wy, sk * wz)
    return positive_unit(w, x, y, z)


@njit(inline="always", **JIT)
def set_q(v: FloatArray, k: int, w: float, x: float, y: float, z: float) -> None:
    """``v[k:k + 4] = q`` (a quaternion inside a state vector)."""
    v[k] = w
    v[k + 1] = x
    v[k + 2] = y
    v[k + 3] = z


@njit(inline="always", **JIT)
def write_q(out_q: FloatArray, i: int, w: float, x: float, y: float, z: float) -> None:
    """``out_q[i] = q``."""
    out_q[i, 0] = w
    out_q[i, 1] = x
    out_q[i, 2] = y
    out_q[i, 3] = z
