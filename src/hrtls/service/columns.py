"""Columns of an ingest batch: rows (lists) or binary column blocks, checked into numpy arrays.

A numeric column is either a list (of numbers, or of ``[x, y, z]`` rows) or a *column block*
``{"dtype": "<f8", "shape": [n, 3], "data": <bytes>}``: the little-endian array bytes, C order,
as msgpack ``bin``. Blocks skip building and checking one Python float per sample, which is
what limits the service's front end at 30,000 IMU samples/s. Every column becomes a float64
array (``n`` or ``n x 3``); a refusal is a :class:`ColumnError` naming the field.
"""

from __future__ import annotations

from typing import Any

import numpy as np

MAX_SAMPLES = 2000
"""Samples per part."""

BLOCK_DTYPES: dict[str, np.dtype[Any]] = {"<f8": np.dtype("<f8"), "<f4": np.dtype("<f4")}
"""Block dtypes accepted (float32 not for times: it cannot hold mission times to the ms)."""

TIME_DTYPES = ("<f8",)
_BLOCK_KEYS = frozenset(("dtype", "shape", "data"))


class ColumnError(ValueError):
    """A column that cannot be read; the message names the field."""


def numeric(value: Any, where: str, *, width: int | None, nan_ok: bool = False,
            time: bool = False) -> np.ndarray:
    """A checked float64 column: shape ``(n,)`` (``width`` None) or ``(n, width)``.

    ``nan_ok``: NaN (and, in rows, null) stands for unknown; infinities are always refused.
    """
    if isinstance(value, dict):
        a = _from_block(value, where, width=width, time=time)
    elif isinstance(value, list):
        a = _from_rows(value, where, width=width, nan_ok=nan_ok)
    else:
        raise ColumnError(f"{where}: expected a list or a column block "
                          "{dtype, shape, data}, got " + type(value).__name__)
    n = a.shape[0]
    if n > MAX_SAMPLES:
        raise ColumnError(f"{where}: {n} samples, at most {MAX_SAMPLES} per part")
    bad = np.isinf(a) if nan_ok else ~np.isfinite(a)
    if bad.any():
        i = int(np.flatnonzero(bad.reshape(n, -1).any(axis=1))[0])
        raise ColumnError(f"{where}[{i}] is not a finite number")
    return a


def _from_rows(value: list[Any], where: str, *, width: int | None,
               nan_ok: bool) -> np.ndarray:
    if nan_ok and width is None:
        obj = np.asarray(value, dtype=object)
        if obj.ndim == 1:
            value = np.where(obj == None, np.nan, obj).tolist()  # noqa: E711 (elementwise)
    try:
        a = np.asarray(value)
    except ValueError:
        raise ColumnError(f"{where}: rows of different lengths") from None
    shape = "n" if width is None else f"n x {width}"
    if a.dtype.kind not in "iuf" or a.ndim != (1 if width is None else 2) \
            or (width is not None and a.shape[1] != width):
        raise ColumnError(f"{where}: expected {shape} numbers")
    return a.astype(np.float64)


def _from_block(block: dict[str, Any], where: str, *, width: int | None,
                time: bool) -> np.ndarray:
    keys = set(block)
    if keys != _BLOCK_KEYS:
        wrong = sorted(keys - _BLOCK_KEYS) or sorted(_BLOCK_KEYS - keys)
        raise ColumnError(f"{where}: a column block has exactly dtype, shape and data "
                          f"({', '.join(map(repr, wrong))} wrong)")
    dtype, shape, data = block["dtype"], block["shape"], block["data"]
    allowed = TIME_DTYPES if time else tuple(BLOCK_DTYPES)
    if dtype not in allowed:
        raise ColumnError(f"{where}.dtype {dtype!r}: one of {', '.join(allowed)}")
    want = 1 if width is None else 2
    if not isinstance(shape, list) or len(shape) != want \
            or not all(type(k) is int and k >= 0 for k in shape) \
            or (width is not None and shape[1] != width):
        expected = "[n]" if width is None else f"[n, {width}]"
        raise ColumnError(f"{where}.shape {shape!r}: expected {expected}")
    if not isinstance(data, bytes):
        raise ColumnError(f"{where}.data: expected bytes (msgpack bin), got "
                          f"{type(data).__name__}")
    if shape[0] > MAX_SAMPLES:
        raise ColumnError(f"{where}: {shape[0]} samples, at most {MAX_SAMPLES} per part")
    dt = BLOCK_DTYPES[dtype]
    n_bytes = int(np.prod(shape)) * dt.itemsize
    if len(data) != n_bytes:
        raise ColumnError(f"{where}.data has {len(data)} bytes, shape {shape} of {dtype} "
                          f"needs {n_bytes}")
    return np.frombuffer(data, dtype=dt).reshape(shape).astype(np.float64)


def strings(value: Any, where: str) -> np.ndarray:
    """A checked column of identifiers (strings of 1-200 characters)."""
    if not isinstance(value, list):
        raise ColumnError(f"{where}: expected a list of strings")
    a = np.asarray(value) if value else np.zeros(0, dtype="<U1")
    if a.dtype.kind != "U" or a.ndim != 1 or a.tolist() != value:
        raise ColumnError(f"{where}: expected a list of strings")
    if len(a) > MAX_SAMPLES:
        raise ColumnError(f"{where}: {len(a)} samples, at most {MAX_SAMPLES} per part")
    lengths = np.char.str_len(a)
    if len(a) and (lengths.min() < 1 or lengths.max() > 200):
        raise ColumnError(f"{where}: identifiers have 1 to 200 characters")
    return a


def block(a: np.ndarray, *, dtype: str = "<f8") -> dict[str, Any]:
    """The column block of an array (for clients)."""
    arr = np.ascontiguousarray(a, dtype=BLOCK_DTYPES[dtype])
    return {"dtype": dtype, "shape": list(arr.shape), "data": arr.tobytes()}
