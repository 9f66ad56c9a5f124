"""Small helpers shared by the dataset loaders: locating folders and parsing header-less CSV."""

from __future__ import annotations

import warnings
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


def numeric_csv(path: Path, *, columns: int) -> FloatArray:
    """Read a header-less, comma-separated numeric table with ``columns`` columns.

    The fast path is numpy's parser; when it fails, the file is scanned line by line so the
    error names the first bad line (1-based) and field.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy warns on empty files
            data = np.loadtxt(path, delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        data = None
    if data is not None and data.shape[1] == columns and len(data) > 0:
        return np.asarray(data, dtype=np.float64)
    n_rows = 0
    with path.open("r", encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text:
                continue
            n_rows += 1
            fields = text.split(",")
            if len(fields) != columns:
                raise FormatError(f"{len(fields)} fields", where=f"{path.name} line {number}",
                                  expected=f"{columns} comma-separated numbers")
            for col, field in enumerate(fields, start=1):
                try:
                    float(field)
                except ValueError:
                    raise FormatError(f"field {col} is {field!r}",
                                      where=f"{path.name} line {number}",
                                      expected="a number") from None
    if n_rows:
        raise FormatError("numpy could not parse the table", where=path.name,
                          expected=f"rows of {columns} comma-separated numbers")
    raise FormatError("no data rows", where=path.name, expected=f"rows of {columns} numbers")


def warn_repair(message: str) -> None:
    """Announce a repair of the input data."""
    warnings.warn(message, RepairWarning, stacklevel=3)
