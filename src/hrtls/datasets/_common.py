"""Small helpers shared by the dataset loaders: locating folders and parsing header-less CSV."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import FormatError, InputError, RepairWarning

FloatArray = NDArray[np.float64]


def dataset_dir(root: str | Path, subfolder: str) -> Path:
    """The dataset folder: ``root/subfolder`` when it exists, else ``root`` itself.

    Loaders accept either the dataset's own folder or the folder of all recordings
    (``shared/data``), which holds one sub-folder per dataset.
    """
    base = Path(root)
    candidate = base / subfolder
    folder = candidate if candidate.is_dir() else base
    if not folder.is_dir():
        raise InputError("folder not found", where=str(folder),
                         expected=f"the {subfolder!r} dataset folder")
    return folder


def require_file(path: Path, what: str) -> Path:
    """Return ``path`` or raise :class:`InputError` when it is not an existing file."""
    if not path.is_file():
        raise InputError("file not found", where=str(path), expected=what)
    return path


@dataclass(frozen=True, slots=True)
class NumericRows:
    """Rows of a header-less numeric CSV: ``values`` (n, columns), their 1-based ``lines``."""

    values: FloatArray
    lines: NDArray[np.int64]
    dropped: str | None = None
    """What ``repair`` dropped (for the notes), or None."""


def _line_problem(text: str, *, columns: int, cut: bool) -> str | None:
    """Why one line is not ``columns`` finite numbers, or None when it is."""
    fields = text.split(",")
    if len(fields) != columns:
        if cut and len(fields) < columns:
            return f"last line cut short ({len(fields)} of {columns} fields, no newline at the end)"
        return f"{len(fields)} fields"
    for col, field in enumerate(fields, start=1):
        try:
            value = float(field)
        except ValueError:
            return f"field {col} is {field!r}"
        if not np.isfinite(value):
            return f"field {col} is {field.strip()}"
    return None


def _careful_rows(path: Path, *, columns: int, repair: bool) -> NumericRows:
    """Line by line: the first bad line raises, or (repair) bad lines are dropped with a warning."""
    raw = path.read_bytes().decode("utf-8", errors="replace")
    all_lines = raw.split("\n")
    rows: list[list[float]] = []
    numbers: list[int] = []
    bad: list[tuple[int, str]] = []
    for number, line in enumerate(all_lines, start=1):
        text = line.strip()
        if not text:
            continue
        cut = number == len(all_lines) and not raw.endswith("\n")
        problem = _line_problem(text, columns=columns, cut=cut)
        if problem is None:
            rows.append([float(v) for v in text.split(",")])
            numbers.append(number)
        else:
            bad.append((number, problem))
    if not rows and not bad:
        raise FormatError("no data rows", where=path.name, expected=f"rows of {columns} numbers")
    if bad and not rows:
        number, problem = bad[0]
        raise FormatError(f"no line of {columns} numbers (line {number}: {problem})",
                          where=path.name, expected=f"{columns} comma-separated numbers per line",
                          hint="another format? `hrtls formats` lists them (--format)")
    if bad and not repair:
        number, problem = bad[0]
        raise FormatError(problem, where=f"{path.name} line {number}",
                          expected=f"{columns} comma-separated finite numbers",
                          hint="pass repair=True to drop such lines with a warning")
    dropped = drop_lines(path.name, bad)
    return NumericRows(np.asarray(rows, dtype=np.float64).reshape(-1, columns),
                       np.asarray(numbers, dtype=np.int64), dropped)


def drop_lines(file_name: str, bad: list[tuple[int, str]]) -> str | None:
    """Warn of the malformed lines ``(line, problem)`` a repair dropped; the note (None: none)."""
    if not bad:
        return None
    dropped = (f"dropped {len(bad)} malformed line(s): "
               + "; ".join(f"line {n}: {p}" for n, p in bad[:5]) + (" ..." if len(bad) > 5 else ""))
    warn_repair(f"{file_name}: {dropped}")
    return dropped


def numeric_csv(path: Path, *, columns: int, repair: bool = False) -> NumericRows:
    """Read a header-less, comma-separated table of ``columns`` finite numbers.

    The fast path is numpy's parser; when it fails or finds a non-finite value, the file is
    scanned line by line so the error names the first bad line (1-based) and field, or, with
    ``repair``, every malformed line (a cut last line, a partial or non-numeric line, NaN) is
    dropped with a :class:`~hrtls.errors.RepairWarning`.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy warns on empty files
            data = np.loadtxt(path, delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        data = None
    if (data is not None and data.shape[1] == columns and len(data) > 0
            and np.isfinite(data).all()):
        return NumericRows(np.asarray(data, dtype=np.float64),
                           np.arange(1, len(data) + 1, dtype=np.int64))
    return _careful_rows(path, columns=columns, repair=repair)


def warn_repair(message: str) -> None:
    """Announce a repair of the input data."""
    warnings.warn(message, RepairWarning, stacklevel=3)
