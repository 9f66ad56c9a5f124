"""Factored Quaternion Algorithm (FQA): attitude of a static body from gravity and field.

The attitude ``q_nd`` is built as ``q_yaw * q_pitch * q_roll`` (the z-y'-x'' sequence of
:mod:`hrtls.frames`). With the unit specific force ``a = R^T e_z = [-sin p, cos p sin r,
cos p cos r]`` (ENU, z up) the elevation (pitch) and roll follow from ``a``; the measured field
is then levelled by ``q_pitch * q_roll`` and its horizontal part gives the azimuth, since the
levelled field reads ``[sin y, cos y] |m_h|`` for a heading ``y`` (north is +y in ENU). Each
factor quaternion is built with half-angle formulas from the sine and cosine of its angle, so no
trigonometric function is evaluated (the idea of the FQA used by Inderst Sec. 4.2.2).

At pitch +-90 deg the roll is undefined and is set to 0. The heading is magnetic (declination
is not applied).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from hrtls.attitude import _quaternion as Q
from hrtls.attitude._jit import JIT
from hrtls.errors import InputError
from hrtls.frames import FloatArray
from hrtls.kernels import njit

__all__ = ["fqa", "fqa_quaternion"]

_EPS = 1e-9


@njit(inline="always", **JIT)
def _half(c: float, s: float) -> tuple[float, float]:
    """``cos(a/2), sin(a/2)`` from ``cos a, sin a`` (sign of the sine kept, 0 -> +)."""
    ch = math.sqrt(max(0.0, 0.5 * (1.0 + c)))
    sh = math.sqrt(max(0.0, 0.5 * (1.0 - c)))
    if s < 0.0:
        sh = -sh
    return ch, sh


@njit(**JIT)
def fqa_quaternion(
    a0: float, a1: float, a2: float, m0: float, m1: float, m2: float
) -> tuple[float, float, float, float]:
    """FQA attitude ``q_nd`` from a specific force ``a`` and a field ``m`` (any scale).

    Returns the identity when ``a`` is zero; keeps heading 0 when ``m`` has no horizontal part.
    """
    an = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if an < _EPS:
        return 1.0, 0.0, 0.0, 0.0
    ax = a0 / an
    ay = a1 / an
    az = a2 / an
    # elevation (pitch): sin p = -a_x
    sp = -ax
    cp = math.sqrt(max(0.0, 1.0 - sp * sp))
    if cp > _EPS:
        sr = ay / cp
        cr = az / cp
    else:
        sr = 0.0
        cr = 1.0
    cph, sph = _half(cp, sp)
    crh, srh = _half(cr, sr)
    # q_pr = q_pitch * q_roll
    w, x, y, z = Q.qmul(cph, 0.0, sph, 0.0, crh, srh, 0.0, 0.0)
    # level the field: m_l = R(q_pr) m
    lx, ly, _ = Q.rot(w, x, y, z, m0, m1, m2)
    hn = math.sqrt(lx * lx + ly * ly)
    if hn < _EPS:
        return w, x, y, z
    cyh, syh = _half(ly / hn, lx / hn)
    w, x, y, z = Q.qmul(cyh, 0.0, 0.0, syh, w, x, y, z)
    if w < 0.0:
        return -w, -x, -y, -z
    return w, x, y, z


@njit(**JIT)
def _fqa_batch(acc: FloatArray, mag: FloatArray, out: FloatArray) -> None:
    for i in range(acc.shape[0]):
        w, x, y, z = fqa_quaternion(acc[i, 0], acc[i, 1], acc[i, 2],
                                    mag[i, 0], mag[i, 1], mag[i, 2])
        out[i, 0] = w
        out[i, 1] = x
        out[i, 2] = y
        out[i, 3] = z


def fqa(acc: ArrayLike, mag: ArrayLike) -> FloatArray:
    """Static attitudes ``q_nd`` (N, 4) from specific force (N, 3) and field (N, 3) samples."""
    a = np.ascontiguousarray(acc, dtype=np.float64)
    m = np.ascontiguousarray(mag, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3 or m.shape != a.shape:
        raise InputError(f"shapes {a.shape} and {m.shape}", where="fqa",
                         expected="two (N, 3) arrays")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(m))):
        raise InputError("non-finite samples", where="fqa", expected="finite samples")
    out = np.empty((len(a), 4))
    _fqa_batch(a, m, out)
    return out
