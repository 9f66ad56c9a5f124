"""Gyroscope bias from the periods when the device rests (batch estimate).

A sample is *at rest* when, over a centred window of ``window_s``, the standard deviation of each
gyro axis stays below ``rest_gyro_rad_s`` and that of each accelerometer axis below
``rest_acc_m_s2``, and the mean specific-force norm is within ``rest_acc_m_s2`` of g. Rest
periods shorter than ``min_rest_s`` are ignored. The bias is the mean gyro rate over the rest
samples. The filters also track the bias causally (``CommonParams.estimate_bias``); this batch
estimate gives them a good start (``gyro_bias_rad_s``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2, FloatArray

__all__ = ["GyroBiasEstimate", "estimate_gyro_bias", "rest_mask"]


@dataclass(frozen=True)
class GyroBiasEstimate:
    """Result of :func:`estimate_gyro_bias`.

    Attributes
    ----------
    bias_rad_s:
        Mean gyro rate at rest, rad/s (zeros when no rest was found).
    std_rad_s:
        Standard deviation of the rate at rest, rad/s (NaN-free; zeros when no rest).
    rest:
        Boolean mask of the samples used.
    found:
        True when at least one rest period was found.
    """

    bias_rad_s: FloatArray
    std_rad_s: FloatArray
    rest: NDArray[np.bool_]
    found: bool


def _moving(x: FloatArray, half: int) -> tuple[FloatArray, FloatArray]:
    """Centred moving mean and standard deviation of each column (window 2*half+1, clipped)."""
    n = len(x)
    c1 = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    c2 = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x * x, axis=0)])
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    cnt = (hi - lo)[:, None].astype(np.float64)
    mean = (c1[hi] - c1[lo]) / cnt
    var = np.maximum((c2[hi] - c2[lo]) / cnt - mean * mean, 0.0)
    return mean, np.sqrt(var)


def rest_mask(t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, *, window_s: float = 1.0,
              rest_gyro_rad_s: float = float(np.deg2rad(1.0)), rest_acc_m_s2: float = 0.3,
              min_rest_s: float = 1.0, gravity_m_s2: float = GRAVITY_M_S2) -> NDArray[np.bool_]:
    """Samples where the device rests (see the module text for the criteria)."""
    tt = np.asarray(t, dtype=np.float64)
    g = np.asarray(gyr, dtype=np.float64)
    a = np.asarray(acc, dtype=np.float64)
    n = len(tt)
    if g.shape != (n, 3) or a.shape != (n, 3):
        raise InputError(f"shapes {g.shape}, {a.shape} for {n} times", where="rest_mask",
                         expected="(N, 3) gyro and accelerometer samples")
    if n < 3:
        return np.zeros(n, dtype=bool)
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(a)) and np.all(np.isfinite(tt))):
        raise InputError("non-finite samples", where="rest_mask", expected="finite samples")
    dt = float(np.median(np.diff(tt)))
    half = max(1, round(0.5 * window_s / dt))
    _, gs = _moving(g, half)
    am, as_ = _moving(a, half)
    still = (np.all(gs < rest_gyro_rad_s, axis=1) & np.all(as_ < rest_acc_m_s2, axis=1)
             & (np.abs(np.linalg.norm(am, axis=1) - gravity_m_s2) < rest_acc_m_s2))
    # keep runs that last at least min_rest_s
    out = np.zeros(n, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if tt[stop - 1] - tt[start] >= min_rest_s:
            out[start:stop] = True
    return out


def estimate_gyro_bias(t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, *, window_s: float = 1.0,
                       rest_gyro_rad_s: float = float(np.deg2rad(1.0)),
                       rest_acc_m_s2: float = 0.3, min_rest_s: float = 1.0,
                       gravity_m_s2: float = GRAVITY_M_S2) -> GyroBiasEstimate:
    """Gyro bias (rad/s) as the mean rate over the rest periods of a recording."""
    mask = rest_mask(t, gyr, acc, window_s=window_s, rest_gyro_rad_s=rest_gyro_rad_s,
                     rest_acc_m_s2=rest_acc_m_s2, min_rest_s=min_rest_s,
                     gravity_m_s2=gravity_m_s2)
    g = np.asarray(gyr, dtype=np.float64)
    if not mask.any():
        return GyroBiasEstimate(np.zeros(3), np.zeros(3), mask, False)
    return GyroBiasEstimate(g[mask].mean(axis=0), g[mask].std(axis=0), mask, True)
