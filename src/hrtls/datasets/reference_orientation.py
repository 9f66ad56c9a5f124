"""Reference orientations from any recording: a CSV, a session folder or a BROAD trial.

A reference orientation is a CSV ``t,qw,qx,qy,qz[,movement]`` (:mod:`hrtls.io.orientation`),
the ``orientation_reference.csv`` of a session folder, or a BROAD trial (``.hdf5``): its
optical orientation and ``movement`` flags.
"""

from __future__ import annotations

from pathlib import Path

from hrtls.errors import InputError
from hrtls.io.orientation import (
    REFERENCE_FILE,
    OrientationTable,
    read_orientation_csv,
    session_reference_orientation,
)

__all__ = ["find_reference_orientation", "read_reference_orientation"]


def read_reference_orientation(path: Path) -> OrientationTable:
    """A reference orientation from a CSV, a session folder or a BROAD trial (module text)."""
    path = Path(path)
    if path.is_dir():
        ref = session_reference_orientation(path)
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
    if recording.is_dir():
        return session_reference_orientation(recording)
    if recording.is_file() and recording.suffix.lower() in (".hdf5", ".h5"):
        from hrtls.datasets.formats import looks_like_broad

        if looks_like_broad(recording):
            return read_reference_orientation(recording)
    return None
