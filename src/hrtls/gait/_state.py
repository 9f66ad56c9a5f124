"""Save/restore helpers shared by the causal gait estimators (state as JSON-able dicts)."""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

FloatArray = NDArray[np.float64]
T = TypeVar("T")


def state_to_dict(state: Any) -> dict[str, Any]:
    """Turn a dataclass of floats, ints, bools and numpy arrays into plain JSON-able values."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(state):
        value = getattr(state, f.name)
        if isinstance(value, np.ndarray):
            out[f.name] = value.tolist()
        elif isinstance(value, np.generic):
            out[f.name] = value.item()
        else:
            out[f.name] = value
    return out


def state_from_dict(cls: type[T], data: dict[str, Any]) -> T:
    """Rebuild a state dataclass from :func:`state_to_dict` output (arrays keep their dtype)."""
    if not dataclasses.is_dataclass(cls):
        raise InputError(f"{cls!r} is not a dataclass", where="state")
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            raise InputError(f"missing key {f.name!r}", where=f"{cls.__name__} state",
                             expected="a dict written by to_dict()")
        value = data[f.name]
        ftype = str(f.type)
        if "ndarray" in ftype or "Array" in ftype:
            dtype = np.int64 if "int" in ftype.lower() else np.float64
            kwargs[f.name] = np.asarray(value, dtype=dtype)
        else:
            kwargs[f.name] = value
    return cls(**kwargs)


def as_vector(x: Any, *, where: str, length: int | None = None) -> FloatArray:
    """Finite float64 vector or :class:`InputError`."""
    arr = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if arr.ndim != 1:
        raise InputError(f"shape {arr.shape}", where=where, expected="a 1-D array")
    if length is not None and arr.shape[0] != length:
        raise InputError(f"length {arr.shape[0]}", where=where, expected=f"length {length}")
    if np.isfinite(np.sum(arr)):  # NaN/inf propagate through the sum: one cheap pass
        return arr
    bad = ~np.isfinite(arr)
    if np.any(bad):
        raise InputError("non-finite value", where=f"{where} index {int(np.flatnonzero(bad)[0])}",
                         expected="finite numbers")
    return arr


def as_matrix(x: Any, *, where: str, columns: int, length: int | None = None) -> FloatArray:
    """Finite float64 (N, columns) array or :class:`InputError`."""
    arr = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if arr.ndim != 2 or arr.shape[1] != columns:
        raise InputError(f"shape {arr.shape}", where=where, expected=f"(N, {columns})")
    if length is not None and arr.shape[0] != length:
        raise InputError(f"{arr.shape[0]} rows", where=where, expected=f"{length} rows")
    if np.isfinite(np.sum(arr)):
        return arr
    bad = ~np.isfinite(arr)
    if np.any(bad):
        row = int(np.flatnonzero(np.any(bad, axis=1))[0])
        raise InputError("non-finite value", where=f"{where} row {row}",
                         expected="finite numbers")
    return arr


def as_time(t: Any, *, where: str = "time", after: float = -np.inf) -> FloatArray:
    """Strictly increasing finite time vector (s), later than ``after``."""
    arr = as_vector(t, where=where)
    if arr.size > 1 and not np.all(arr[1:] > arr[:-1]):
        d = np.diff(arr)
        if np.any(d <= 0):
            idx = int(np.flatnonzero(d <= 0)[0]) + 1
            raise InputError("time does not increase", where=f"{where} index {idx}",
                             expected="strictly increasing time (s)")
    if arr.size and arr[0] <= after:
        raise InputError(f"chunk starts at {arr[0]} s, not after {after} s", where=where,
                         expected="chunks in time order")
    return arr


def check_positive(value: float, name: str, *, zero_ok: bool = False) -> None:
    """Raise :class:`InputError` unless ``value`` is finite and > 0 (>= 0 with ``zero_ok``)."""
    if not (np.isfinite(value) and (value > 0 or (zero_ok and value == 0))):
        raise InputError(f"{name} = {value}", where=name,
                         expected=f"a finite value {'>=' if zero_ok else '>'} 0")


def decisions_from_dict(data: dict[str, Any], *, where: str
                        ) -> tuple[FloatArray, NDArray[np.int64]]:
    """Step times ``t`` and their decisions ``status`` of a state's ``to_dict`` (checked)."""
    try:
        t = np.asarray(data["t"], dtype=np.float64).reshape(-1)
        st = np.asarray(data["status"], dtype=np.int64).reshape(-1)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"malformed state ({exc!r})", where=where,
                         expected="a dict written by to_dict()") from None
    if t.shape != st.shape:
        raise InputError(f"{t.shape[0]} times, {st.shape[0]} decisions", where=where,
                         expected="one decision per step")
    return t, st
