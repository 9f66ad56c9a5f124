"""BROAD: the Berlin Robust Orientation Estimation Assessment Dataset (HDF5 trials).

Source: https://github.com/dlaidig/broad (data CC BY 4.0); Laidig, Caruso, Cereatti, Seel,
*Data* 6(7), 2021. Nothing is downloaded here: pass a local ``.hdf5`` trial file.

Each trial holds (all gzip-compressed): ``imu_acc`` (N, 3) m/s^2, ``imu_gyr`` (N, 3) rad/s,
``imu_mag`` (N, 3) uT, ``opt_quat`` (N, 4), ``opt_pos`` (N, 3) m, ``movement`` (N,) bool, and the
attributes ``sampling_rate`` (Hz) and ``info``.

``opt_quat`` is scalar first and rotates IMU-frame vectors into an ENU frame whose north is the
lab's magnetic north, i.e. it *is* hrtls's ``q_nb`` with the IMU frame as body frame (checked:
``R(q) acc = [0, 0, 9.82]`` at rest). It is NaN where the optical tracking was lost (3-9 % of the
samples). The IMU signals are already SI and stay in the IMU's own frame. The board is moved by
hand, not worn, so ``meta.mounting_q_bd`` is left unset. Scores should use the ``movement``
samples only and combine quaternions as ``q_est * conj(q_ref)``, as the source does.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta
from hrtls.datasets._common import FloatArray, dataset_dir, require_file
from hrtls.errors import FormatError, InputError

_KEYS = ("imu_acc", "imu_gyr", "imu_mag", "opt_quat", "opt_pos", "movement")
_NORM_TOLERANCE = 1e-6


@dataclass(frozen=True, slots=True, eq=False)
class BroadTrial:
    """One BROAD trial.

    Attributes
    ----------
    name:
        Trial name (the file stem), e.g. ``"02_undisturbed_slow_rotation_B"``.
    session:
        IMU (accelerometer, gyroscope, magnetometer; IMU frame, SI), t = k / rate in s.
    reference_q:
        Optical orientation ``q_nb`` (IMU -> ENU, magnetic north), (N, 4) ``[w, x, y, z]``;
        rows are all-NaN where the tracking was lost.
    reference_pos_m:
        Optical position of the board, (N, 3) m; NaN where lost.
    movement:
        (N,) bool, True for the samples to score.
    rate_hz:
        Sampling rate, Hz (285.714 for the whole dataset).
    info:
        The file's ``info`` attribute (free text).
    description:
        The trial's description from ``trials.json`` ("" when the file is not next to it).
    groups:
        The trial's groups from ``trials.json`` (e.g. ``undisturbed``, ``rotation``, ``slow``).
    """

    name: str
    session: Session
    reference_q: FloatArray
    reference_pos_m: FloatArray
    movement: NDArray[np.bool_]
    rate_hz: float
    info: str
    description: str = ""
    groups: tuple[str, ...] = field(default_factory=tuple)

    @property
    def reference_valid(self) -> NDArray[np.bool_]:
        """(N,) bool, True where the optical orientation is available."""
        return np.all(np.isfinite(self.reference_q), axis=1)


def list_trials(root: str | Path) -> list[Path]:
    """The ``.hdf5`` trial files under ``root`` (the ``broad`` folder or a folder containing it)."""
    folder = dataset_dir(root, "broad")
    return sorted(folder.glob("*.hdf5"))


def load_trials_index(path: str | Path) -> dict[str, Any]:
    """Parse ``trials.json``: ``{"groups": [...], "trials": {name: {description, groups}}}``."""
    file = require_file(Path(path), "BROAD trials.json")
    try:
        content = json.loads(file.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise FormatError(f"invalid JSON ({exc})", where=str(file), expected="JSON") from None
    if not isinstance(content, dict) or not isinstance(content.get("trials"), dict):
        raise FormatError("no 'trials' object", where=str(file),
                          expected='{"groups": [...], "trials": {...}}')
    return content


def _dataset(handle: h5py.File, key: str, file: Path) -> np.ndarray:
    if key not in handle:
        raise FormatError(f"missing dataset {key!r}", where=str(file),
                          expected=f"HDF5 datasets {', '.join(_KEYS)}")
    return np.asarray(handle[key][()])


def load_trial(path: str | Path) -> BroadTrial:
    """Load one BROAD trial file (metadata from ``trials.json`` in the same folder, if any)."""
    file = require_file(Path(path), "a BROAD .hdf5 trial file")
    try:
        handle = h5py.File(file, "r")
    except OSError as exc:
        raise FormatError(f"cannot open as HDF5 ({exc})", where=str(file),
                          expected="an HDF5 file") from None
    with handle:
        arrays = {key: _dataset(handle, key, file) for key in _KEYS}
        if "sampling_rate" not in handle.attrs:
            raise FormatError("missing attribute 'sampling_rate'", where=str(file),
                              expected="the sampling rate in Hz")
        rate = float(handle.attrs["sampling_rate"])
        info_raw = handle.attrs.get("info", "")
        info = info_raw.decode() if isinstance(info_raw, bytes) else str(info_raw)
    if not (np.isfinite(rate) and rate > 0):
        raise FormatError(f"sampling_rate {rate}", where=str(file), expected="a positive rate")
    n = len(arrays["imu_acc"])
    shapes = {"imu_acc": (n, 3), "imu_gyr": (n, 3), "imu_mag": (n, 3), "opt_quat": (n, 4),
              "opt_pos": (n, 3), "movement": (n,)}
    for key, shape in shapes.items():
        if arrays[key].shape != shape:
            raise FormatError(f"{key} has shape {arrays[key].shape}", where=str(file),
                              expected=f"shape {shape}")
    quat = np.asarray(arrays["opt_quat"], dtype=np.float64)
    nan_rows = np.isnan(quat)
    partial = np.any(nan_rows, axis=1) & ~np.all(nan_rows, axis=1)
    if np.any(partial):
        idx = int(np.flatnonzero(partial)[0])
        raise FormatError("quaternion row partly NaN", where=f"{file.name} opt_quat row {idx}",
                          expected="a unit quaternion or an all-NaN row (tracking lost)")
    valid = ~np.any(nan_rows, axis=1)
    norm_error = np.abs(np.linalg.norm(quat[valid], axis=1) - 1.0)
    if np.any(norm_error > _NORM_TOLERANCE):
        idx = int(np.flatnonzero(valid)[np.argmax(norm_error)])
        raise FormatError(f"quaternion norm off by {norm_error.max():.3g}",
                          where=f"{file.name} opt_quat row {idx}", expected="unit quaternions")
    quat[valid] /= np.linalg.norm(quat[valid], axis=1, keepdims=True)

    t = np.arange(n, dtype=np.float64) / rate
    name = file.stem
    imu = ImuStream(
        accel=SensorSeries(t, arrays["imu_acc"], f"{name} imu_acc"),
        gyro=SensorSeries(t, arrays["imu_gyr"], f"{name} imu_gyr"),
        mag=SensorSeries(t, arrays["imu_mag"], f"{name} imu_mag"),
    )
    description = ""
    groups: tuple[str, ...] = ()
    index_file = file.parent / "trials.json"
    if index_file.is_file():
        entry = load_trials_index(index_file)["trials"].get(name)
        if isinstance(entry, dict):
            description = str(entry.get("description", ""))
            groups = tuple(str(g) for g in entry.get("groups", []))
    meta = SessionMeta(
        placement="hand-held board (not body-worn)",
        source={"dataset": "broad", "repository": "https://github.com/dlaidig/broad",
                "file": str(file), "trial": name, "groups": list(groups)},
        notes=[
            "IMU signals are SI in the IMU frame; BroadTrial.reference_q is q_nb (IMU -> ENU "
            "with the lab's magnetic north), NaN where optical tracking was lost.",
            f"t = sample index / {rate:.6g} Hz.",
        ],
    )
    movement = np.asarray(arrays["movement"]).astype(bool)
    if not movement.any():
        raise InputError("no movement samples", where=f"{file.name} movement",
                         expected="at least one sample to score")
    return BroadTrial(name=name, session=Session(meta=meta, imu=imu), reference_q=quat,
                      reference_pos_m=np.asarray(arrays["opt_pos"], dtype=np.float64),
                      movement=movement, rate_hz=rate, info=info, description=description,
                      groups=groups)
