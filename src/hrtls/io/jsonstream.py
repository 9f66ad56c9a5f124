"""JSON documents with long arrays written to a file piece by piece.

A document is plain JSON data (dicts, lists, numbers, text) in which a list may hold
:class:`Rows`: items made on demand, ``SLICE`` at a time, and spliced into that list. Writing
it (:func:`write_json`) gives exactly the text of ``json.dumps(doc, allow_nan=False)`` of the
document with every :class:`Rows` made (:func:`materialized`), but neither the text nor the
long lists are ever held whole. A :class:`Rows` may give its text directly (``text``): numbers
are then formatted by Arrow (:func:`float_text`), not one by one by Python.

Reading is whole-document: :func:`read_json_file` parses a file, :func:`json_positions` turns
a list of ``[x, y]`` / ``[x, y, z]`` positions into an array (the GeoJSON and MF-JSON readers).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import FormatError, InputError

if TYPE_CHECKING:
    import pyarrow as pa

SLICE = 4096
"""Items made and encoded at a time."""


@dataclass(frozen=True, slots=True)
class Rows:
    """``n`` items of a JSON list, ``make(i, j)`` giving items ``i`` to ``j - 1`` (plain data)."""

    n: int
    make: Callable[[int, int], list[Any]]
    text: Callable[[int, int], str] | None = None
    """The JSON text of items ``i`` to ``j - 1`` joined by ``", "``: what ``json.dumps`` of
    ``make(i, j)`` writes between its brackets, made without it."""


def materialized(value: Any) -> Any:
    """``value`` with every :class:`Rows` made and spliced into its list."""
    if isinstance(value, dict):
        return {k: materialized(v) for k, v in value.items()}
    if isinstance(value, list):
        out: list[Any] = []
        for item in value:
            if isinstance(item, Rows):
                out.extend(item.make(0, item.n))
            else:
                out.append(materialized(item))
        return out
    return value


def write_json(target: Path, doc: Any) -> None:
    """Write ``doc`` and a newline next to ``target``, then move it into place."""
    tmp = target.with_name(target.name + ".partial")
    with tmp.open("w", encoding="utf-8") as fh:
        _encode(doc, fh)
        fh.write("\n")
    tmp.replace(target)


def read_json_file(path: str | Path, *, format_name: str, article: str = "a"
                   ) -> tuple[Path, Any]:
    """The file and its parsed JSON; errors name ``format_name`` (``"GeoJSON"``, ...).

    A missing file raises :class:`~hrtls.errors.InputError`, text that is not JSON
    :class:`~hrtls.errors.FormatError` (expected: ``{article} {format_name} file``).
    """
    file = Path(path)
    if not file.is_file():
        raise InputError("file not found", where=str(file),
                         expected=f"{article} {format_name} file")
    try:
        return file, json.loads(file.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise FormatError(f"invalid JSON ({exc})", where=str(file),
                          expected=format_name) from None


def json_positions(value: Any, *, where: str, finite: bool) -> NDArray[np.float64]:
    """(N, 3) array of a JSON list of ``[x, y]`` or ``[x, y, z]`` numbers (missing z: 0).

    ``finite`` also rejects NaN and infinities (``json.loads`` reads ``NaN``, ``Infinity``).
    """
    if not isinstance(value, list):
        raise FormatError(f"{type(value).__name__}", where=where, expected="a list of positions")
    out = np.zeros((len(value), 3))
    for i, pos in enumerate(value):
        if (not isinstance(pos, list) or not 2 <= len(pos) <= 3
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in pos)):
            raise FormatError(f"position {pos!r}", where=f"{where}[{i}]",
                              expected="[x, y] or [x, y, z] numbers")
        out[i, : len(pos)] = pos
    if finite and not np.all(np.isfinite(out)):
        raise FormatError("non-finite coordinate", where=where, expected="finite numbers")
    return out


def _lazy(value: Any) -> bool:
    if isinstance(value, dict):
        return any(_lazy(v) for v in value.values())
    if isinstance(value, list):
        return any(isinstance(v, Rows) or _lazy(v) for v in value)
    return False


def _encode(value: Any, fh: TextIO) -> None:
    """``json.dumps`` of ``value`` (default separators), written in pieces."""
    if not _lazy(value):
        fh.write(json.dumps(value, allow_nan=False))
        return
    if isinstance(value, dict):
        fh.write("{")
        for k, (key, item) in enumerate(value.items()):
            fh.write(f"{', ' if k else ''}{json.dumps(key)}: ")
            _encode(item, fh)
        fh.write("}")
        return
    fh.write("[")
    first = True
    for item in value:
        if not isinstance(item, Rows):
            fh.write("" if first else ", ")
            _encode(item, fh)
            first = False
            continue
        for i in range(0, item.n, SLICE):
            j = min(i + SLICE, item.n)
            if item.text is not None:
                fh.write(("" if first else ", ") + item.text(i, j))
                first = False
                continue
            part = item.make(i, j)
            if part:
                fh.write(("" if first else ", ") + json.dumps(part, allow_nan=False)[1:-1])
                first = False
    fh.write("]")


def float_text(values: np.ndarray) -> pa.Array:
    """Arrow strings: the JSON text of each float (``json.dumps``'s), ``null`` if not finite.

    Arrow's cast gives the same shortest round-trip digits as ``repr`` but places them
    otherwise (``1`` for ``1.0``, ``1e-7`` for ``1e-07``, exponents from 1e15 on, none down to
    1e-6): where both write an exponent, or both none, its text is taken (``.0`` added to whole
    numbers, exponents of two digits at least), the few others are formatted by ``repr``.
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    v = np.ascontiguousarray(values, dtype=np.float64)
    size = np.abs(v)
    text = pc.cast(pa.array(v), pa.string())
    if (((size >= 1e-4) & (size < 1e9)) | (v == 0)).all():
        # neither text has an exponent there (Arrow's first ones are whole numbers from 1e10
        # on): only whole numbers (no point) need their ``.0``
        point = pc.match_substring(text, ".")
        if pc.all(point).as_py():
            return text
        return pc.if_else(point, text, pc.binary_join_element_wise(text, ".0", ""))
    point, sci = pc.match_substring(text, "."), pc.match_substring(text, "e")
    decimal = ((size >= 1e-4) & (size < 1e16)) | (v == 0)  # repr's choice
    same = np.where(np.asarray(sci), ~decimal, decimal)
    text = pc.if_else(pc.or_(point, sci), text, pc.binary_join_element_wise(text, ".0", ""))
    text = pc.replace_substring_regex(text, pattern=r"e([-+])(\d)$", replacement=r"e\10\2")
    odd = np.flatnonzero(~same)
    if len(odd):
        other = np.full(len(v), None, dtype=object)
        other[odd] = [repr(x) if np.isfinite(x) else "null" for x in v[odd].tolist()]
        text = pc.if_else(pa.array(same), text, pa.array(other, pa.string()))
    return text


def numbers_text(values: np.ndarray) -> str:
    """The JSON text of a list of floats (1-D) or of float rows (2-D), without its brackets.

    NaN and infinities are written ``null``.
    """
    text = float_text(values) if values.ndim == 1 else row_text(values)
    return joined_text(text)


def joined_text(text: pa.Array) -> str:
    """The strings of ``text`` joined by ``", "``, joined by Arrow (no Python string each)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if not len(text):
        return ""
    one_list = pa.ListArray.from_arrays(pa.array(np.array([0, len(text)], dtype=np.int32)), text)
    return str(pc.binary_join(one_list, ", ")[0].as_py())


def row_text(values: np.ndarray) -> pa.Array:
    """Arrow strings: the JSON text of each row of floats (``[1.0, 2.5]``; not finite: null)."""
    import pyarrow.compute as pc

    columns = [float_text(values[:, k]) for k in range(values.shape[1])]
    return pc.binary_join_element_wise("[", pc.binary_join_element_wise(*columns, ", "), "]",
                                       "")
