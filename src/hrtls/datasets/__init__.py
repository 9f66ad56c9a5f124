"""Loaders for the public recordings hrtls is tested on (local files only, no downloads).

=================  ===========================================  =================================
module             dataset                                      what it gives
=================  ===========================================  =================================
``mobgap``         Mobilise-D lab trials (lower-back IMU)        session + gait references
``oxford``         Oxford step counter validation (phone acc)    session + true step count/times
``broad``          BROAD orientation benchmark (HDF5)            session + optical ``q_nb``
``ble_rssi``       position-annotated BLE RSSI                   RSS session + beacon truth
``ipin2023``       IPIN 2023 track 3 smartphone logfiles         session (via the IPIN reader)
=================  ===========================================  =================================

Each loader takes the dataset's own folder or the folder that holds all of them (see
:func:`default_data_root`). Every dataset's units, axes and quirks are described in the module
docstrings; conversions to SI happen here, at the boundary.
"""

from __future__ import annotations

import os
from pathlib import Path

DATA_ENV_VAR = "HRTLS_DATA"
"""Environment variable naming the folder of the recordings."""

DATASETS = ("mobgap_lab", "oxford_step", "broad", "ble_rssi", "ipin2023")
"""Sub-folder names of the recordings folder."""


def default_data_root() -> Path | None:
    """Folder of the recordings: ``$HRTLS_DATA``, else ``shared/data`` next to the repository.

    Returns None when neither exists (e.g. an installed package without the recordings).
    """
    env = os.environ.get(DATA_ENV_VAR)
    if env:
        path = Path(env).expanduser()
        return path if path.is_dir() else None
    # src/hrtls/datasets/__init__.py -> repository root is parents[3]
    repo_root = Path(__file__).resolve().parents[3]
    candidate = repo_root.parent / "shared" / "data"
    return candidate if candidate.is_dir() else None


__all__ = ["DATASETS", "DATA_ENV_VAR", "default_data_root"]
