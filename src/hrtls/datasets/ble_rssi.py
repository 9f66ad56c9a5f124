"""Position-annotated BLE RSSI dataset: 12 fixed receivers, one moving beacon, camera truth.

Source: https://github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset (CC0 1.0); Daniş et
al., *Pervasive and Mobile Computing* 81, 2022. Nothing is downloaded: pass the local folder
(``ble_rssi`` with ``cnf/`` and ``trk/``, or a folder that contains it).

Files read:

* ``cnf/tetam.dev``: lines ``Dongles:{mac: [[x, y, z], colour, alias], ...}`` (the 12 fixed
  receivers, m) and ``Beacons:{mac: [[], colour, alias]}``.
* ``trk/<name>_all_sensors.mbd``: CSV lines ``unix_s, receiver_mac, beacon_mac, rssi_dbm, x, y,
  z, r11..r33``: one RSS reading of the beacon by one receiver, labelled with the beacon
  position (m, venue frame, z = height) and a 3x3 orientation matrix (convention unverified).

In the session, the receivers are the *anchors*: path loss is symmetric, so it does not matter
that here the moving device transmits and the anchors receive. Anchor ids are the receivers'
**aliases** (``sensor10`` ... ``sensor42``): short, readable and unique; the MAC address is kept
on each landmark (extra field ``mac``) and in :attr:`BleRssiTrajectory.receivers`.

Time order. The merged files are not strictly sorted: each has at most one backward step of
<= 1 ms (the text timestamps are truncated to different numbers of digits), and a few readings
share a time. RSS readings may share a time but must not go back. Because this defect is in
every published file and is harmless, **this loader repairs by default** (``repair=True``):
it sorts the readings by time (stable) and says so with a
:class:`~hrtls.errors.RepairWarning` naming the lines. With ``repair=False`` (the CLI without
``--repair``) backward steps of at most :data:`MERGE_JITTER_S` are still sorted with the
warning, and a larger one raises :class:`~hrtls.errors.InputError` naming its line.

Ground truth: the beacon positions at the distinct reading times (readings at the same time
carry the same position; differing ones would be averaged with a warning), as
:class:`~hrtls.data.GroundTruth`. Times are from the first reading in s;
``meta.time_origin_unix_s`` holds its Unix time.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.data import GroundTruth, Landmark, RssReadings, Session, SessionMeta
from hrtls.datasets._common import (
    FloatArray,
    dataset_dir,
    drop_lines,
    require_file,
    warn_repair,
)
from hrtls.errors import FormatError, InputError

_SUFFIX = "_all_sensors.mbd"
_COLUMNS = 16
MERGE_JITTER_S = 0.01
"""Backward steps up to this size (the merge order of the receivers' readings) are sorted,
with a warning, even without ``repair``; larger ones are clock problems and need it."""


@dataclass(frozen=True, slots=True)
class BleReceiver:
    """A fixed receiver ("dongle"): MAC, position (m) and alias."""

    mac: str
    xyz: tuple[float, float, float]
    alias: str


@dataclass(frozen=True, slots=True, eq=False)
class BleRssiTrajectory:
    """One trajectory of the moving beacon.

    Attributes
    ----------
    name:
        Trajectory name, e.g. ``"straight_01"``.
    session:
        RSS readings (anchor = receiver alias), the receivers as landmarks of kind
        ``"anchor"``, and the beacon positions as ground truth.
    receivers:
        Receivers by alias.
    beacon_mac:
        MAC of the moving beacon.
    t:
        Time of every reading (sorted), s from the first reading, (N,).
    anchor:
        Receiver alias of every reading, (N,).
    rss_dbm:
        RSS of every reading, dBm, (N,).
    beacon_xyz:
        Beacon position labelled on every reading, m, (N, 3).
    beacon_rotation:
        The 3x3 orientation matrix of every reading, (N, 3, 3) (convention not verified).
    """

    name: str
    session: Session
    receivers: dict[str, BleReceiver]
    beacon_mac: str
    t: FloatArray
    anchor: NDArray[np.str_]
    rss_dbm: FloatArray
    beacon_xyz: FloatArray
    beacon_rotation: FloatArray

    def distances_m(self) -> FloatArray:
        """True 3-D distance from the beacon to the receiver of every reading, m, (N,)."""
        pos = np.array([self.receivers[a].xyz for a in self.anchor.tolist()], dtype=np.float64)
        return np.asarray(np.linalg.norm(self.beacon_xyz - pos.reshape(-1, 3), axis=1))


def load_devices(path: str | Path) -> tuple[dict[str, BleReceiver], dict[str, str]]:
    """Parse ``tetam.dev``: receivers by alias, and beacons as ``{mac: alias}``."""
    file = require_file(Path(path), "the BLE device file cnf/tetam.dev")
    receivers: dict[str, BleReceiver] = {}
    beacons: dict[str, str] = {}
    for number, line in enumerate(file.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if not text:
            continue
        kind, sep, body = text.partition(":")
        where = f"{file.name} line {number}"
        if not sep or kind not in ("Dongles", "Beacons"):
            raise FormatError(f"line starts with {kind[:20]!r}", where=where,
                              expected="'Dongles:{...}' or 'Beacons:{...}'")
        try:
            devices = json.loads(body)
        except ValueError as exc:
            raise FormatError(f"invalid device dictionary ({exc})", where=where,
                              expected='{"mac": [[x, y, z], colour, "alias"], ...}') from None
        if not isinstance(devices, dict):
            raise FormatError("not a dictionary", where=where, expected="{mac: [...]}")
        for mac, entry in devices.items():
            if not (isinstance(entry, list) and len(entry) == 3 and isinstance(entry[2], str)):
                raise FormatError(f"device {mac!r} entry {entry!r}", where=where,
                                  expected="[[x, y, z], colour, alias]")
            if kind == "Beacons":
                beacons[mac.lower()] = entry[2]
                continue
            pos = entry[0]
            if not (isinstance(pos, list) and len(pos) == 3
                    and all(isinstance(v, int | float) for v in pos)):
                raise FormatError(f"receiver {mac!r} position {pos!r}", where=where,
                                  expected="[x, y, z] in m")
            if entry[2] in receivers:
                raise FormatError(f"alias {entry[2]!r} used twice", where=where,
                                  expected="unique receiver aliases")
            receivers[entry[2]] = BleReceiver(mac=mac.lower(), xyz=(float(pos[0]),
                                              float(pos[1]), float(pos[2])), alias=entry[2])
    if not receivers:
        raise FormatError("no receivers", where=file.name, expected="a 'Dongles:' line")
    return receivers, beacons


def list_trajectories(root: str | Path) -> list[str]:
    """Names of the trajectories in ``trk/`` (e.g. ``"straight_01"``)."""
    folder = dataset_dir(root, "ble_rssi") / "trk"
    return sorted(p.name[: -len(_SUFFIX)] for p in folder.glob(f"*{_SUFFIX}"))


@dataclass(frozen=True, slots=True, eq=False)
class _TrackRows:
    """The readings of a track file with their 1-based line numbers."""

    unix_s: FloatArray
    receivers: list[str]
    beacons: list[str]
    rss_dbm: FloatArray
    numbers: FloatArray
    lines: NDArray[np.int64]
    dropped: str | None
    """What ``repair`` dropped (for the notes), or None."""


def _line_problem(fields: list[str]) -> str | None:
    """Why one line's fields are not a reading, or None."""
    if len(fields) != _COLUMNS:
        return f"{len(fields)} fields"
    try:
        values = [float(fields[0]), float(fields[3])] + [float(v) for v in fields[4:]]
    except ValueError as exc:
        return f"not a number ({exc})"
    if not np.all(np.isfinite(values)):
        return "a non-finite number"
    return None


def _read_track(file: Path, *, repair: bool) -> _TrackRows:
    """Readings of a track file; a malformed line raises, or (``repair``) is dropped, warned."""
    rows: list[list[str]] = []
    lines: list[int] = []
    bad: list[tuple[int, str]] = []
    for number, line in enumerate(file.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if not text:
            continue
        fields = text.split(",")
        problem = _line_problem(fields)
        if problem is None:
            rows.append(fields)
            lines.append(number)
        elif not repair:
            raise FormatError(problem, where=f"{file.name} line {number}",
                              expected=f"{_COLUMNS} fields (time, receiver, beacon, rssi, x, y, "
                                       "z, 9 matrix entries)",
                              hint="pass repair=True to drop such lines with a warning")
        else:
            bad.append((number, problem))
    if not rows:
        first = f" (all {len(bad)} malformed, line {bad[0][0]}: {bad[0][1]})" if bad else ""
        raise FormatError(f"no readings{first}", where=file.name, expected="CSV lines")
    dropped = drop_lines(file.name, bad)
    numbers = np.array([[float(v) for v in r[4:]] for r in rows], dtype=np.float64)
    return _TrackRows(np.array([float(r[0]) for r in rows]), [r[1].strip().lower() for r in rows],
                      [r[2].strip().lower() for r in rows], np.array([float(r[3]) for r in rows]),
                      numbers.reshape(-1, _COLUMNS - 4), np.asarray(lines, dtype=np.int64),
                      dropped)


def _time_order(unix_s: FloatArray, lines: NDArray[np.int64], *, file_name: str, repair: bool,
                notes: list[str]) -> NDArray[np.intp] | None:
    """The sorting order of readings that go back in time (repair), else None; or raise."""
    back = np.flatnonzero(np.diff(unix_s) < 0)
    if not len(back):
        return None
    steps_back = unix_s[back] - unix_s[back + 1]
    largest = float(np.max(steps_back))
    if not repair and largest > MERGE_JITTER_S:
        worst = int(back[np.argmax(steps_back)])
        raise InputError(f"time goes back by {largest:.6g} s",
                         where=f"{file_name} line {lines[worst + 1]}",
                         expected="non-decreasing times (backward steps of at most "
                         f"{MERGE_JITTER_S:g} s are sorted with a warning)",
                         hint="pass repair=True to sort the readings with a warning")
    order = np.argsort(unix_s, kind="stable")
    message = (f"{file_name}: sorted {len(back)} backward time step(s) of at most "
               f"{largest:.3g} s at line(s) {', '.join(str(lines[i + 1]) for i in back[:5])}")
    warn_repair(message)
    notes.append("repair: " + message.split(": ", 1)[1])
    return order


def _truth_per_time(t: FloatArray, xyz: FloatArray, *, file_name: str
                    ) -> tuple[FloatArray, FloatArray]:
    """One truth sample per distinct time: the mean beacon position (m), warned if they differ.

    Equal times carry equal positions in the published files.
    """
    t_truth, start, counts = np.unique(t, return_index=True, return_counts=True)
    truth_xyz = np.add.reduceat(xyz, start, axis=0) / counts[:, None]
    spread = np.zeros(len(t_truth))
    for i in np.flatnonzero(counts > 1):
        group = xyz[start[i]:start[i] + counts[i]]
        spread[i] = float(np.max(np.ptp(group, axis=0)))
    if np.any(spread > 0):
        warn_repair(f"{file_name}: {int(np.count_nonzero(spread > 0))} time(s) with differing "
                    f"beacon positions (up to {spread.max():.3g} m) averaged for the truth")
    return t_truth, truth_xyz


def load_trajectory(root: str | Path, name: str, *, repair: bool = True) -> BleRssiTrajectory:
    """Load ``trk/<name>_all_sensors.mbd`` with the receivers of ``cnf/tetam.dev``.

    Parameters
    ----------
    root:
        The ``ble_rssi`` folder or a folder containing it.
    name:
        Trajectory name, e.g. ``"straight_01"`` (see :func:`list_trajectories`).
    repair:
        Sort readings that go back in time, with a :class:`~hrtls.errors.RepairWarning`
        (default True: every published file has one sub-millisecond backward step). With
        False only steps of at most :data:`MERGE_JITTER_S` are sorted (warned); a larger one
        raises :class:`~hrtls.errors.InputError` naming the line.
    """
    folder = dataset_dir(root, "ble_rssi")
    file = folder / "trk" / f"{name}{_SUFFIX}"
    if not file.is_file():
        raise InputError(f"trajectory {name!r} not found", where=str(folder / "trk"),
                         expected=f"one of {', '.join(list_trajectories(folder)) or '(none)'}")
    receivers, beacons = load_devices(folder / "cnf" / "tetam.dev")
    by_mac = {r.mac: r.alias for r in receivers.values()}
    track = _read_track(file, repair=repair)
    unix, rx_macs, bx_macs, rss, numbers = (track.unix_s, track.receivers, track.beacons,
                                            track.rss_dbm, track.numbers)
    lines = track.lines
    unknown = sorted(set(rx_macs) - set(by_mac))
    if unknown:
        idx = rx_macs.index(unknown[0])
        raise FormatError(f"unknown receiver {unknown[0]!r}",
                          where=f"{file.name} line {lines[idx]}",
                          expected="a receiver listed in cnf/tetam.dev")
    if len(set(bx_macs)) != 1:
        raise FormatError(f"{len(set(bx_macs))} beacons", where=file.name,
                          expected="readings of a single moving beacon")
    anchor = np.array([by_mac[m] for m in rx_macs], dtype=np.str_)
    xyz = numbers[:, 0:3]
    rotation = numbers[:, 3:].reshape(-1, 3, 3)

    notes: list[str] = [] if track.dropped is None else ["repair: " + track.dropped]
    order = _time_order(unix, lines, file_name=file.name, repair=repair, notes=notes)
    if order is not None:
        unix, anchor, rss = unix[order], anchor[order], rss[order]
        xyz, rotation, lines = xyz[order], rotation[order], lines[order]
    origin = float(unix[0])
    t = unix - origin

    t_truth, truth_xyz = _truth_per_time(t, xyz, file_name=file.name)

    landmarks = {
        alias: Landmark.model_validate({"id": alias, "kind": "anchor", "position": rec.xyz,
                                        "mac": rec.mac})
        for alias, rec in receivers.items()
    }
    meta = SessionMeta(
        time_origin_unix_s=origin,
        placement="hand-carried BLE beacon (transmitter)",
        source={"dataset": "ble_rssi",
                "repository": "https://github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset",
                "file": str(file), "trajectory": name, "beacon_mac": bx_macs[0],
                "beacon_alias": beacons.get(bx_macs[0], "")},
        notes=["Anchors are the 12 fixed receivers, ids = aliases (sensor10..sensor42); the "
               "moving beacon transmits (path loss is symmetric).",
               "Truth = beacon positions from the AR-tag camera system (venue frame, m; x/y "
               "handedness not verified).", *notes],
    )
    session = Session(
        meta=meta,
        rss=RssReadings(t, anchor, rss, name=f"{file.name} rss"),
        landmarks=landmarks,
        truth=GroundTruth(t_truth, truth_xyz, name=f"{file.name} beacon position"),
    )
    return BleRssiTrajectory(name=name, session=session, receivers=receivers,
                             beacon_mac=bx_macs[0], t=t, anchor=anchor, rss_dbm=rss,
                             beacon_xyz=xyz, beacon_rotation=rotation)
