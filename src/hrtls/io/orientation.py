"""Orientation time series on disk: the CSV of ``hrtls attitude`` and reference orientations.

The CSV is ``t,qw,qx,qy,qz[,movement]`` (``q_nb``, ENU; empty fields where the reference was
lost; ``movement`` 1/0 marks the samples to score), e.g. ``orientation_reference.csv`` in a
session folder, or the CSV written by ``hrtls attitude`` (its ``roll,pitch,yaw`` columns are
ignored). A reference orientation from any recording, BROAD trials included, is read by
:mod:`hrtls.datasets.reference_orientation`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.io.csvtable import ColumnKind, read_table

__all__ = ["REFERENCE_FILE", "OrientationTable", "read_orientation_csv",
           "session_reference_orientation"]

REFERENCE_FILE = "orientation_reference.csv"
"""Name of a reference orientation inside a session folder."""


@dataclass(frozen=True, slots=True, eq=False)
class OrientationTable:
    """Times (s), quaternions ``q_nb`` (N, 4; NaN rows where unknown) and the samples to score."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    mask: NDArray[np.bool_] | None
    source: str


def read_orientation_csv(path: Path) -> OrientationTable:
    """Read ``t,qw,qx,qy,qz[,movement][,roll,pitch,yaw]``."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", where=str(path), expected="an orientation CSV")
    kinds: dict[str, ColumnKind] = {"t": "float", "qw": "float_or_empty",
                                    "qx": "float_or_empty", "qy": "float_or_empty",
                                    "qz": "float_or_empty", "movement": "float",
                                    "roll": "float_or_empty", "pitch": "float_or_empty",
                                    "yaw": "float_or_empty"}
    table = read_table(path.read_bytes(), name=path.name, kinds=kinds,
                       required=("t", "qw", "qx", "qy", "qz"))
    q = np.column_stack([table.float(c) for c in ("qw", "qx", "qy", "qz")])
    mask = table.float("movement") != 0.0 if "movement" in table.present else None
    return OrientationTable(table.float("t"), q, mask, path.name)


def session_reference_orientation(folder: Path) -> OrientationTable | None:
    """The reference orientation of a session folder (its ``REFERENCE_FILE``), or None."""
    folder = Path(folder)
    if folder.is_dir() and (folder / REFERENCE_FILE).is_file():
        return read_orientation_csv(folder / REFERENCE_FILE)
    return None
