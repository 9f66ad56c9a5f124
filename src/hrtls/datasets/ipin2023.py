"""IPIN 2023 competition, track 3 (smartphone, off-site): logfiles of a hand-held phone.

Source: J. Torres-Sospedra et al., "Datasets and Supporting Materials for the IPIN 2023
Competition Track 3", Zenodo, doi 10.5281/zenodo.8362205 (re-uploaded at
https://github.com/Kenny5269/2023_IPIN_Competition_Track03). Nothing is downloaded here.

A thin wrapper: the parsing (units, clocks, AHRS orientation, BLE beacon ids, POSI ground
truth as start pose + checkpoints) is :func:`hrtls.io.readers.ipin.read_ipin`; this module
only finds the files of the dataset folder and passes ``BLE_Locations.csv`` as the beacon
landmarks. The phone was mostly held in front of the body, not at the waist.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hrtls.data import Session
from hrtls.datasets._common import dataset_dir
from hrtls.errors import InputError
from hrtls.io.readers.ipin import read_ipin

BEACONS_FILE = "BLE_Locations.csv"
"""Beacon positions (``bleID,Lat,Lon,floor``) shipped with the competition data."""


def list_logfiles(root: str | Path) -> list[str]:
    """Names of the logfiles (``IPIN*.txt``) under ``root`` (``ipin2023`` or its parent)."""
    folder = dataset_dir(root, "ipin2023")
    return sorted(p.name for p in folder.glob("*.txt") if p.name.upper().startswith("IPIN"))


def load_logfile(root: str | Path, name: str, *, repair: bool = False, **options: Any
                 ) -> Session:
    """Read one logfile with the dataset's beacon positions.

    Parameters
    ----------
    root:
        The ``ipin2023`` folder or a folder containing it.
    name:
        A name from :func:`list_logfiles` (the ``.txt`` may be left out).
    repair:
        Passed to :func:`~hrtls.io.readers.ipin.read_ipin` (sort/merge bad sensor times with
        a warning instead of raising).
    **options:
        Further keyword arguments of :func:`~hrtls.io.readers.ipin.read_ipin`
        (``include_wifi``, ``floor_height_m``, ``trim_to_start`` ...).
    """
    folder = dataset_dir(root, "ipin2023")
    file = folder / (name if name.endswith(".txt") else f"{name}.txt")
    if not file.is_file():
        raise InputError(f"logfile {name!r} not found", where=str(folder),
                         expected=f"one of {', '.join(list_logfiles(folder)) or '(none)'}")
    beacons = folder / BEACONS_FILE
    return read_ipin(file, repair=repair, beacons=beacons if beacons.is_file() else None,
                     **options)
