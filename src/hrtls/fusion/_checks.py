"""Input checks shared by the fusion modules (raise :class:`~hrtls.errors.InputError`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

FloatArray = NDArray[np.float64]


def finite_vector(x: Any, *, where: str, length: int | None = None) -> FloatArray:
    """Finite contiguous float64 1-D array (optionally of a given length)."""
    try:
        arr = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise InputError(f"not numeric ({exc})", where=where, expected="numbers") from None
    if arr.ndim != 1:
        raise InputError(f"shape {arr.shape}", where=where, expected="a 1-D array")
    if length is not None and arr.shape[0] != length:
        raise InputError(f"length {arr.shape[0]}", where=where, expected=f"length {length}")
    bad = ~np.isfinite(arr)
    if np.any(bad):
        raise InputError("non-finite value", where=f"{where} index {int(np.flatnonzero(bad)[0])}",
                         expected="finite numbers")
    return arr


def finite_matrix(x: Any, *, where: str, shape: tuple[int, int]) -> FloatArray:
    """Finite contiguous float64 2-D array of an exact shape."""
    try:
        arr = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise InputError(f"not numeric ({exc})", where=where, expected="numbers") from None
    if arr.shape != shape:
        raise InputError(f"shape {arr.shape}", where=where, expected=f"shape {shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("non-finite value", where=where, expected="finite numbers")
    return arr


def finite_scalar(x: Any, *, where: str, positive: bool = False,
                  non_negative: bool = False) -> float:
    """A finite float, optionally > 0 or >= 0."""
    try:
        value = float(x)
    except (TypeError, ValueError):
        raise InputError(f"{x!r} is not a number", where=where, expected="a number") from None
    if not math.isfinite(value):
        raise InputError(f"{value}", where=where, expected="a finite number")
    if positive and value <= 0.0:
        raise InputError(f"{value}", where=where, expected="a value > 0")
    if non_negative and value < 0.0:
        raise InputError(f"{value}", where=where, expected="a value >= 0")
    return value


def probability(x: Any, *, where: str) -> float:
    """A probability in (0, 1)."""
    value = finite_scalar(x, where=where)
    if not 0.0 < value < 1.0:
        raise InputError(f"{value}", where=where, expected="a probability in (0, 1)")
    return value


def broadcast_vector(x: Any, n: int, *, where: str, positive: bool = False,
                     non_negative: bool = False) -> FloatArray:
    """A scalar or an (n,) array as a finite (n,) float64 array."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    out = finite_vector(arr, where=where, length=n)
    if positive and np.any(out <= 0.0):
        idx = int(np.flatnonzero(out <= 0.0)[0])
        raise InputError(f"{out[idx]}", where=f"{where} index {idx}", expected="values > 0")
    if non_negative and np.any(out < 0.0):
        idx = int(np.flatnonzero(out < 0.0)[0])
        raise InputError(f"{out[idx]}", where=f"{where} index {idx}", expected="values >= 0")
    return out


def non_decreasing_time(t: FloatArray, *, where: str, after: float | None = None) -> None:
    """Raise unless ``t`` is non-decreasing and not before ``after``."""
    if t.size > 1:
        d = np.diff(t)
        if np.any(d < 0.0):
            idx = int(np.flatnonzero(d < 0.0)[0]) + 1
            raise InputError("time goes backwards", where=f"{where} index {idx}",
                             expected="non-decreasing time (s)")
    if after is not None and t.size and t[0] < after:
        raise InputError(f"first time {t[0]} s is before the filter time {after} s",
                         where=where, expected="observations in time order")
