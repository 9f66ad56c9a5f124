"""JSON documents with long arrays written to a file piece by piece.

A document is plain JSON data (dicts, lists, numbers, text) in which a list may hold
:class:`Rows`: items made on demand, ``SLICE`` at a time, and spliced into that list. Writing
it (:func:`write_json`) gives exactly the text of ``json.dumps(doc, allow_nan=False)`` of the
document with every :class:`Rows` made (:func:`materialized`), but neither the text nor the
long lists are ever held whole.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

SLICE = 4096
"""Items made and encoded at a time."""


@dataclass(frozen=True, slots=True)
class Rows:
    """``n`` items of a JSON list, ``make(i, j)`` giving items ``i`` to ``j - 1`` (plain data)."""

    n: int
    make: Callable[[int, int], list[Any]]


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
            part = item.make(i, min(i + SLICE, item.n))
            if part:
                fh.write(("" if first else ", ") + json.dumps(part, allow_nan=False)[1:-1])
                first = False
    fh.write("]")
