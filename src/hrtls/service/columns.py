"""Columns of an ingest batch: rows (lists) or binary column blocks, checked into numpy arrays.

A numeric column is either a list (of numbers, or of ``[x, y, z]`` rows) or a *column block*
``{"dtype": "<f8", "shape": [n, 3], "data": <bytes>}``: the little-endian array bytes, C order,
as msgpack ``bin``. Blocks skip building and checking one Python float per sample, which is
what limits the service's front end at 30,000 IMU samples/s. Every column becomes a float64
array (``n`` or ``n x 3``); a refusal is a :class:`ColumnError` naming the field.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hrtls.kernels import njit

MAX_SAMPLES = 2000
"""Samples per part."""

BLOCK_DTYPES: dict[str, np.dtype[Any]] = {"<f8": np.dtype("<f8"), "<f4": np.dtype("<f4")}
"""Block dtypes accepted (float32 not for times: it cannot hold mission times to the ms)."""

TIME_DTYPES = ("<f8",)


class ColumnError(ValueError):
    """A column that cannot be read; the message names the field."""


@njit(cache=True)
def _first_not_finite(a: np.ndarray, nan_ok: bool) -> int:  # pragma: no cover (compiled)
    """Index of the first infinity (or NaN unless ``nan_ok``) in a flat array, -1 if none."""
    for i in range(a.size):
        v = a[i]
        if math.isinf(v) or (not nan_ok and math.isnan(v)):
            return i
    return -1


@njit(cache=True)
def first_out_of_order(t: np.ndarray, strict: bool) -> int:  # pragma: no cover (compiled)
    """Index of the first time not after (``strict``) or before its predecessor, -1 if none."""
    for i in range(1, t.size):
        if t[i] < t[i - 1] or (strict and t[i] == t[i - 1]):
            return i
    return -1


def numeric(value: Any, where: str, *, width: int | None, nan_ok: bool = False,
            time: bool = False) -> np.ndarray:
    """A checked float64 column: shape ``(n,)`` (``width`` None) or ``(n, width)``.

    ``nan_ok``: NaN (and, in rows, null) stands for unknown; infinities are always refused.
    A column from a block is a read-only view of the received bytes.
    """
    if type(value) is dict:
        a = _from_block(value, where, width=width, time=time)
    elif type(value) is list:
        a = _from_rows(value, where, width=width, nan_ok=nan_ok)
    else:
        raise ColumnError(f"{where}: expected a list or a column block "
                          "{dtype, shape, data}, got " + type(value).__name__)
    n = len(a)
    if n > MAX_SAMPLES:
        raise ColumnError(f"{where}: {n} samples, at most {MAX_SAMPLES} per part")
    bad = _first_not_finite(a.reshape(-1), nan_ok)
    if bad >= 0:
        raise ColumnError(f"{where}[{bad if width is None else bad // width}] is not a "
                          "finite number")
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
    return a.astype(np.float64, copy=False)


def _from_block(block: dict[str, Any], where: str, *, width: int | None,
                time: bool) -> np.ndarray:
    if len(block) != 3 or "dtype" not in block or "shape" not in block or "data" not in block:
        raise ColumnError(f"{where}: a column block has exactly the fields dtype, shape and "
                          f"data (got {', '.join(map(repr, block))})")
    dtype, shape, data = block["dtype"], block["shape"], block["data"]
    allowed = TIME_DTYPES if time else BLOCK_DTYPES
    if dtype not in allowed:
        raise ColumnError(f"{where}.dtype {dtype!r}: one of {', '.join(allowed)}")
    if type(shape) is not list or len(shape) != (1 if width is None else 2) \
            or type(shape[0]) is not int or shape[0] < 0 \
            or (width is not None and shape[1] != width):
        expected = "[n]" if width is None else f"[n, {width}]"
        raise ColumnError(f"{where}.shape {shape!r}: expected {expected}")
    if type(data) is not bytes:
        raise ColumnError(f"{where}.data: expected bytes (msgpack bin), got "
                          f"{type(data).__name__}")
    n = shape[0]
    if n > MAX_SAMPLES:
        raise ColumnError(f"{where}: {n} samples, at most {MAX_SAMPLES} per part")
    dt = BLOCK_DTYPES[dtype]
    n_bytes = n * (width or 1) * dt.itemsize
    if len(data) != n_bytes:
        raise ColumnError(f"{where}.data has {len(data)} bytes, shape {shape} of {dtype} "
                          f"needs {n_bytes}")
    # a writable copy: kernels get the array types the offline path gives them (one build)
    a = np.frombuffer(data, dtype=dt).astype(np.float64)
    return a if width is None else a.reshape(n, width)


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
