"""Array checks shared by all containers: shapes, finite values, time order, explicit repairs.

Checks raise :class:`~hrtls.errors.InputError` naming the stream and the first offending index.
Repairs (``repair_time_order``, ``drop_non_finite``) return new arrays and warn with a
:class:`~hrtls.errors.RepairWarning` that says exactly what changed.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.errors import InputError, RepairWarning

FloatArray = NDArray[np.float64]


def as_float_vector(x: ArrayLike, *, where: str, length: int | None = None) -> FloatArray:
    """Return ``x`` as a 1-D float64 array, checking its length when given."""
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"not numeric ({exc})", where=where, expected="numbers") from None
    if arr.ndim != 1:
        raise InputError(f"shape {arr.shape}", where=where, expected="a 1-D array")
    if length is not None and len(arr) != length:
        raise InputError(f"length {len(arr)}", where=where, expected=f"length {length}")
    return arr


def as_float_matrix(x: ArrayLike, *, where: str, columns: int, length: int | None = None
                    ) -> FloatArray:
    """Return ``x`` as an (N, columns) float64 array."""
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"not numeric ({exc})", where=where, expected="numbers") from None
    if arr.ndim != 2 or arr.shape[1] != columns:
        raise InputError(f"shape {arr.shape}", where=where, expected=f"shape (N, {columns})")
    if length is not None and len(arr) != length:
        raise InputError(f"{len(arr)} rows", where=where, expected=f"{length} rows like its time")
    return arr


def as_str_vector(x: ArrayLike | Sequence[str], *, where: str, length: int) -> NDArray[np.str_]:
    """Return ``x`` as a 1-D array of non-empty strings of the given length."""
    arr = np.asarray(x, dtype=np.str_)
    if arr.ndim != 1 or len(arr) != length:
        raise InputError(f"shape {arr.shape}", where=where, expected=f"{length} identifiers")
    if length and np.any(np.char.str_len(arr) == 0):
        idx = int(np.flatnonzero(np.char.str_len(arr) == 0)[0])
        raise InputError("empty identifier", where=f"{where} index {idx}",
                         expected="a non-empty id")
    return arr


def check_finite(values: FloatArray, *, where: str, allow_nan: bool = False) -> None:
    """Raise when ``values`` hold inf (or NaN unless ``allow_nan``), naming the first index."""
    bad = np.isinf(values) if allow_nan else ~np.isfinite(values)
    if np.any(bad):
        flat = np.flatnonzero(bad.reshape(len(values), -1).any(axis=1))
        idx = int(flat[0])
        raise InputError(
            f"{len(flat)} row(s) with non-finite values, first at index {idx}",
            where=where,
            expected="finite numbers",
            hint="pass repair=True to drop them with a warning",
        )


def check_time(t: FloatArray, *, where: str, strict: bool = True) -> None:
    """Check that time is finite and strictly increasing (or non-decreasing if not ``strict``)."""
    check_finite(t, where=f"{where} time")
    if len(t) < 2:
        return
    dt = np.diff(t)
    bad = dt <= 0.0 if strict else dt < 0.0
    if np.any(bad):
        idx = int(np.flatnonzero(bad)[0]) + 1
        kind = "duplicated" if dt[idx - 1] == 0.0 else f"goes backwards by {-dt[idx - 1]:.6g} s"
        raise InputError(
            f"time {kind} at index {idx} (t={t[idx]:.9g})",
            where=where,
            expected="strictly increasing time" if strict else "non-decreasing time",
            hint="pass repair=True to sort and merge duplicates with a warning",
        )


def drop_non_finite(t: FloatArray, columns: Sequence[FloatArray], *, where: str,
                    allow_nan_columns: Sequence[bool] | None = None
                    ) -> tuple[FloatArray, list[FloatArray]]:
    """Drop rows whose time or values are not finite; warn with the count dropped."""
    allow = list(allow_nan_columns) if allow_nan_columns is not None else [False] * len(columns)
    keep = np.isfinite(t)
    for col, nan_ok in zip(columns, allow, strict=True):
        finite = ~np.isinf(col) if nan_ok else np.isfinite(col)
        keep &= finite.reshape(len(col), -1).all(axis=1)
    n_bad = int(len(t) - keep.sum())
    if n_bad:
        first = int(np.flatnonzero(~keep)[0])
        warnings.warn(
            f"{where}: dropped {n_bad} row(s) with non-finite values (first at index {first})",
            RepairWarning,
            stacklevel=3,
        )
        return t[keep], [c[keep] for c in columns]
    return t, list(columns)


def repair_time_order(t: FloatArray, columns: Sequence[FloatArray], *, where: str,
                      strict: bool = True) -> tuple[FloatArray, list[FloatArray]]:
    """Sort by time (stable) and, when ``strict``, merge rows with equal time by averaging.

    When ``strict`` (sensor streams), a backward jump longer than jitter is a clock reset: the
    samples after it are shifted to continue the clock instead of being sorted in between
    (:func:`hrtls.data.clocks.repair_backward_jumps`).

    Numeric columns of merged rows are averaged, so no sample is dropped without trace. A
    :class:`RepairWarning` reports how many rows were moved and merged.
    """
    if len(t) < 2:
        return t, list(columns)
    if strict:
        from hrtls.data.clocks import repair_backward_jumps

        t = repair_backward_jumps(t, where=where)
    messages = []
    order = np.argsort(t, kind="stable")
    n_moved = int(np.count_nonzero(order != np.arange(len(t))))
    if n_moved:
        n_back = int(np.count_nonzero(np.diff(t) < 0))
        messages.append(f"sorted {n_back} backward time jump(s) ({n_moved} rows moved)")
        t = t[order]
        columns = [c[order] for c in columns]
    if strict:
        unique_t, start, counts = np.unique(t, return_index=True, return_counts=True)
        if len(unique_t) < len(t):
            merged = []
            for col in columns:
                if np.issubdtype(col.dtype, np.number):
                    sums = np.add.reduceat(col, start, axis=0)
                    shape = (len(counts),) + (1,) * (col.ndim - 1)
                    merged.append(sums / counts.reshape(shape))
                else:
                    merged.append(col[start])
            messages.append(
                f"merged {len(t) - len(unique_t)} row(s) with duplicated time by averaging"
            )
            t, columns = unique_t, merged
    if messages:
        warnings.warn(f"{where}: " + "; ".join(messages), RepairWarning, stacklevel=3)
    return t, list(columns)
