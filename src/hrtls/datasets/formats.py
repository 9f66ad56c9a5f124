"""The public datasets as input formats of ``hrtls info / convert / track``.

Each reader takes one path as a user would point at it and returns a session:

* ``mobgap``: a participant folder holding ``data.mat`` (or the file itself); one trial, chosen
  with ``trial="Test5/Trial1"`` (default: the first one listed);
* ``oxford-step``: one ``user*_<placement>_<ms>.csv`` file of the Oxford step counter set;
* ``broad``: one BROAD ``.hdf5`` trial;
* ``ble-rssi``: one ``trk/<name>_all_sensors.mbd`` file (the receivers come from ``cnf/``).

These loaders convert units themselves (they know each dataset's units), so ``check_units``
is accepted for a uniform signature and has nothing left to check.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from hrtls.data import Session
from hrtls.errors import DegradedInputWarning, FormatError, InputError

_HEAD = 4096


def looks_like_mobgap(path: Path) -> bool:
    """A ``data.mat`` file, or a folder holding one."""
    return (path.is_file() and path.name == "data.mat") or (path.is_dir()
                                                            and (path / "data.mat").is_file())


def looks_like_oxford(path: Path) -> bool:
    """A header-less CSV of 7 numbers per line whose first column is a ns clock."""
    if not (path.is_file() and path.suffix.lower() == ".csv"):
        return False
    with path.open("rb") as fh:
        head = fh.read(_HEAD).decode("utf-8", errors="replace").splitlines()
    rows = [ln.split(",") for ln in head[:3] if ln.strip()]
    if not rows or any(len(r) != 7 for r in rows):
        return False
    try:
        return all(float(r[0]) > 1e9 for r in rows)
    except ValueError:
        return False


def looks_like_broad(path: Path) -> bool:
    """An HDF5 file with ``imu_acc`` and ``opt_quat`` datasets."""
    if not (path.is_file() and path.suffix.lower() in (".hdf5", ".h5")):
        return False
    import h5py

    try:
        with h5py.File(path, "r") as handle:
            return "imu_acc" in handle and "opt_quat" in handle
    except OSError:
        return False


def looks_like_ble_rssi(path: Path) -> bool:
    """A ``*_all_sensors.mbd`` track file."""
    return path.is_file() and path.name.endswith("_all_sensors.mbd")


def read_mobgap(path: Path | str, *, repair: bool = False, check_units: bool = True,
                trial: str | None = None) -> Session:
    """Mobilise-D lab recording (lower-back IMU): one trial of a participant's ``data.mat``."""
    from hrtls.datasets.mobgap import list_trials, load_trial

    p = Path(path)
    folder = p.parent if p.is_file() else p
    participant = f"{folder.parent.name}/{folder.name}"
    root = folder.parent.parent
    trials = [t for t in list_trials(root) if t.participant == participant]
    if not trials:
        raise FormatError("no trials found", where=str(p), expected="a mobgap participant "
                          "folder (e.g. mobgap_lab/HA/001) with data.mat")
    names = [f"{t.test}/{t.trial}" for t in trials]
    chosen = trial or names[0]
    if chosen not in names:
        raise InputError(f"trial {chosen!r}", where=str(p),
                         expected=f"one of {', '.join(names)}")
    test, trial_name = chosen.split("/", 1)
    loaded = load_trial(root, participant, test, trial_name)
    session = loaded.session
    refs = [r for r in (loaded.reference.indip, loaded.reference.stereophoto) if r is not None]
    ref = next((r for r in refs if len(r.bout_start_s)), None)
    if ref is None and refs:
        session.meta.source["reference_steps"] = {
            "count": None, "source": f"no walking bout in the "
            f"{' or '.join(r.system for r in refs)} reference of this trial"}
    if ref is not None:
        session.meta.source["reference_steps"] = {
            "count": len(ref.initial_contacts_s),
            "source": f"{ref.system} initial contacts (walking bouts only)",
            "intervals_s": [[float(a), float(b)]
                            for a, b in zip(ref.bout_start_s, ref.bout_end_s, strict=True)]}
    others = [n for n in names if n != chosen]
    if others:
        session.meta.notes.append(f"trial {chosen} of {participant}; others: "
                                  f"{', '.join(others)} (choose with trial=...)")
    return session


def read_oxford(path: Path | str, *, repair: bool = False, check_units: bool = True) -> Session:
    """Oxford step-counter validation file (phone accelerometer, step ground truth)."""
    from hrtls.datasets.oxford import load_recording

    recording = load_recording(path, repair=repair)
    session = recording.session
    session.meta.source["reference_steps"] = {
        "count": recording.total_steps, "source": "ground-truth step counter (column 6)"}
    return session


def read_broad(path: Path | str, *, repair: bool = False, check_units: bool = True) -> Session:
    """BROAD orientation-benchmark trial (IMU on an optically tracked board)."""
    from hrtls.datasets.broad import load_trial

    warnings.warn(f"{Path(path).name}: BROAD is a board turned and moved by hand, not a walk: "
                  "steps and positions tracked from it mean nothing (`hrtls attitude` estimates "
                  "and scores its orientation)", DegradedInputWarning, stacklevel=2)
    return load_trial(path).session


def read_ble_rssi(path: Path | str, *, repair: bool = True, check_units: bool = True
                  ) -> Session:
    """Position-annotated BLE RSSI track (12 fixed receivers as anchors, one moving beacon)."""
    from hrtls.datasets.ble_rssi import load_trajectory

    p = Path(path)
    name = p.name[: -len("_all_sensors.mbd")]
    return load_trajectory(p.parent.parent, name, repair=repair).session
