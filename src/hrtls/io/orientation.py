"""Orientation time series on disk: the CSV of ``hrtls attitude`` and reference orientations.

A reference orientation is one of

* a CSV ``t,qw,qx,qy,qz[,movement]`` (``q_nb``, ENU; empty fields where the reference was lost;
  ``movement`` 1/0 marks the samples to score), e.g. ``orientation_reference.csv`` in a session
  folder, or the CSV written by ``hrtls attitude`` (its ``roll,pitch,yaw`` columns are ignored);
* a BROAD trial (``.hdf5``): its optical orientation and ``movement`` flags.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.io.csvtable import ColumnKind, read_table

__all__ = ["REFERENCE_FILE", "OrientationTable", "find_reference_orientation",
           "read_orientation_csv", "read_reference_orientation"]

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


def read_reference_orientation(path: Path) -> OrientationTable:
    """A reference orientation from a CSV or a BROAD trial (module text)."""
    path = Path(path)
    if path.is_dir():
        ref = find_reference_orientation(path)
        if ref is None:
            raise InputError(f"no {REFERENCE_FILE}", where=str(path),
                             expected="a session folder with a reference orientation")
        return ref
    if path.suffix.lower() in (".hdf5", ".h5"):
        from hrtls.datasets.broad import load_trial

        trial = load_trial(path)
        imu = trial.session.imu
        assert imu is not None
        return OrientationTable(imu.accel.t, trial.reference_q, trial.movement, path.name)
    return read_orientation_csv(path)


def find_reference_orientation(recording: Path) -> OrientationTable | None:
    """The reference orientation a recording carries (BROAD trial, session folder), or None."""
    recording = Path(recording)
    if recording.is_dir() and (recording / REFERENCE_FILE).is_file():
        return read_orientation_csv(recording / REFERENCE_FILE)
    if recording.is_file() and recording.suffix.lower() in (".hdf5", ".h5"):
        from hrtls.datasets.formats import looks_like_broad

        if looks_like_broad(recording):
            return read_reference_orientation(recording)
    return None
