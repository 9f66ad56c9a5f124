"""IPIN / EvAAL competition logfiles (the 'GetSensorData' Android app) -> :class:`Session`.

A logfile is text, one record per line, fields separated by ``;``, each line starting with a
four-letter type; lines starting with ``%`` are comments (the header describes the device and
the layout of every type). The types used here, with the fields read (an optional trailing
accuracy field is ignored):

========= ================================================= ===================================
type      fields                                            becomes
========= ================================================= ===================================
``ACCE``  app_t; sensor_t; x; y; z  (m/s^2)                 accelerometer (device frame)
``GYRO``  app_t; sensor_t; x; y; z  (rad/s)                 gyroscope, its own timestamps
``MAGN``  app_t; sensor_t; x; y; z  (uT)                    magnetometer, its own timestamps
``PRES``  app_t; sensor_t; p  (mbar)                        pressure, converted to Pa
``AHRS``  app_t; sensor_t; pitch; roll; yaw; q2; q3; q4     orientation ``q_nd`` (see below)
``BLE4``  app_t; iBeacon|Eddystone; MAC; RSSI; ...; minor   RSS of beacons (dBm)
``WIFI``  app_t; sensor_t; SSID; MAC; frequency; RSS        RSS of access points (opt-in)
``RFID``  app_t; reader; tag id; RSS_A; RSS_B               passive tag reads
``POSI``  t; counter; latitude; longitude; floor; building  start pose + checkpoints
========= ================================================= ===================================

Other types (GNSS, LIGH, SOUN, PROX, ...) are skipped and counted in the notes. BLE4, WIFI
(the scan's delivery time: the per-result sensor times are not ordered within a scan), RFID
and POSI are timed by their app timestamp.

Time. Everything is put on the *app clock* (the first field, seconds since the log started),
which POSI and BLE4 use. Inertial samples keep their more accurate *sensor* timestamps, shifted
by one constant: the median of ``app_t - sensor_t`` over all ACCE/GYRO/MAGN/AHRS/PRES lines
(the typical delivery delay is a few ms; the value is in ``meta.source``).

Ground truth, as in the competition: the first POSI is the known start. Its latitude/longitude
(height 0) become the georeference, so the local ENU origin is there, and the start pose is
``(0, 0, floor * floor_height_m)`` (heading unknown). Every later POSI becomes a checkpoint at
its local ENU position with ``z = floor * floor_height_m`` and the record's counter as label.
The time of the first POSI is ``meta.start_pose.t`` (also kept as
``meta.source["start_pose_t_s"]``); trackers place the agent there at that time, and
``trim_to_start`` drops the data recorded before it.

Orientation. The AHRS quaternion components are those of the Android rotation-vector sensor
(x, y, z; the scalar is ``sqrt(1 - x^2 - y^2 - z^2)``), which rotates device vectors into
east-north-up: it is taken as ``q_nd`` directly. *Checked* on the IPIN 2023 files (the specific
force and the field rotated by it point up and north); every read checks it again.

Beacons. Positions come from a landmark CSV (the competition ships ``BLE_Locations.csv`` with
``bleID,Lat,Lon,floor``); without ``beacons=`` a file matching ``*ble*locations*.csv`` beside
the logfile (or in the same zip/folder) is used. Beacon ids follow :func:`ipin_beacon_id`
(iBeacon minor N -> ``BLEN``), which ``beacon_ids=`` overrides; beacons that match no landmark
keep their MAC as id and are listed in the notes.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from pydantic import ValidationError

from hrtls.data import (
    Checkpoints,
    GeoreferenceModel,
    ImuStream,
    Landmark,
    OrientationSeries,
    RssReadings,
    SensorSeries,
    Session,
    SessionMeta,
    StartPose,
    TagDetections,
    Wgs84,
)
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.frames import Georeference, quat_conjugate
from hrtls.io.readers._orientation import choose_orientation
from hrtls.io.readers._text import (
    IntArray,
    check_stream,
    csv_rows,
    decode_text,
    parse_float_rows,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.units import HPA_TO_PA

__all__ = ["BeaconIdRule", "ipin_beacon_id", "looks_like_ipin", "read_beacons_csv", "read_ipin"]

BeaconIdRule = Callable[[str, "int | None"], "str | None"]
"""``rule(mac, minor) -> landmark id`` (None: keep the MAC)."""

CLOCK_SPREAD_S = 0.1
"""Largest spread of per-type clock offsets for which one common offset is used, s."""

_TYPE_RE = re.compile(r"[A-Z0-9]{4};")
_SNIFF_RE = re.compile(r"^(ACCE|GYRO|MAGN|PRES|AHRS|POSI|BLE4|WIFI|GNSS);", re.MULTILINE)
_SENSOR_CLOCK_TYPES = ("ACCE", "GYRO", "MAGN", "AHRS", "PRES")
_USED_TYPES = ("ACCE", "GYRO", "MAGN", "PRES", "AHRS", "BLE4", "WIFI", "RFID", "POSI")
_TEXT_TYPES = ("BLE4", "WIFI", "RFID")
_NUMERIC_FIELDS = {
    "ACCE": ("app_t", "sensor_t", "x", "y", "z"), "GYRO": ("app_t", "sensor_t", "x", "y", "z"),
    "MAGN": ("app_t", "sensor_t", "x", "y", "z"), "PRES": ("app_t", "sensor_t", "pressure_mbar"),
    "AHRS": ("app_t", "sensor_t", "pitch", "roll", "yaw", "q2", "q3", "q4")}


def ipin_beacon_id(mac: str, minor: int | None) -> str | None:
    """Default beacon-id rule: an iBeacon with MinorID N is landmark ``BLEN``.

    In the IPIN 2023 files the beacons are ``BE:AC:20:23:00:0N`` with minor N and
    ``BLE_Locations.csv`` lists ``BLE1`` ... ``BLE6``; this numbering match is inferred, not
    documented by the competition. Eddystone records (no minor) keep their MAC.
    """
    return None if minor is None else f"BLE{minor}"


def looks_like_ipin(head: bytes) -> bool:
    """True when the start of a file holds IPIN/EvAAL records (``ACCE;``, ``POSI;`` ...)."""
    text = head.decode("utf-8", errors="replace")
    return bool(_SNIFF_RE.search(text)) or "LogFile created by the 'GetSensorData'" in text


@dataclass
class _Log:
    """A logfile split by record type: rows and their 1-based line numbers."""

    label: str
    rows: dict[str, list[str]] = field(default_factory=dict)
    lines: dict[str, IntArray] = field(default_factory=dict)
    parsed: dict[str, FloatArray] = field(default_factory=dict)
    header: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)

    def get(self, kind: str) -> tuple[list[str], IntArray]:
        return self.rows.get(kind, []), self.lines.get(kind, np.zeros(0, dtype=np.int64))


def _without_cut_last_line(text: str, label: str, *, repair: bool) -> str:
    """``text`` without a last line cut short (no newline, fewer fields than its type's lines).

    A cut line of a record type that is not read is dropped with a warning; one of a type that
    is read is dropped with ``repair`` and refused without.
    """
    if not text or text.endswith(("\n", "\r")):
        return text
    head, _, last = text.rpartition("\n")
    kind = last[:5]
    previous = head.rfind("\n" + kind)
    if previous < 0 and not head.startswith(kind):
        return text
    start = previous + 1 if previous >= 0 else 0
    end = head.find("\n", start)
    fields = head[start:end if end >= 0 else None].rstrip().rstrip(";").count(";")
    have = last.rstrip().rstrip(";").count(";")
    if have >= fields:
        return text
    line = head.count("\n") + 2
    where = f"{label} line {line}"
    problem = f"last line cut short ({have + 1} of {fields + 1} fields, no newline at the end)"
    if kind[:4] in _USED_TYPES and not repair:
        raise FormatError(problem, where=where, expected="complete records",
                          hint="pass --repair (repair=True in Python) to drop the cut line")
    warnings.warn(f"{where}: {problem}; dropped it", RepairWarning, stacklevel=3)
    return head + "\n"


def _split_log(text: str, label: str) -> _Log:
    """Group the lines by record type (vectorized over the whole file)."""
    lines = text.splitlines()
    log = _Log(label)
    if not lines:
        raise FormatError("file is empty", where=label, expected="an IPIN logfile")
    prefixes = np.array([ln[:5] for ln in lines])
    kinds, first = np.unique(prefixes, return_index=True)
    bad = [i for kind, i in zip(kinds.tolist(), first.tolist(), strict=True)
           if not (kind.startswith("%") or not kind.strip() or _TYPE_RE.fullmatch(kind))]
    if bad:
        i = min(bad)
        line = lines[i] if len(lines[i]) <= 40 else lines[i][:37] + "..."
        raise FormatError(f"line {line!r} is not a record", where=f"{label} line {i + 1}",
                          expected="'TYPE;field;...' with a 4-character type (ACCE, GYRO, "
                          "POSI, ...) or a '%' comment")
    for kind in kinds.tolist():
        if kind.startswith("%") or not kind.strip():
            continue
        idx = np.flatnonzero(prefixes == kind)
        name = kind[:4]
        if name in _USED_TYPES:
            if name in _TEXT_TYPES:  # parsed field by field: drop a trailing ';'
                log.rows[name] = [lines[j].rstrip().rstrip(";") for j in idx.tolist()]
            else:
                log.rows[name] = [lines[j] for j in idx.tolist()]
            log.lines[name] = idx.astype(np.int64) + 1
        else:
            log.skipped[name] = len(idx)
    for ln in lines[:200]:
        if ln.startswith("%") and ":" in ln:
            key, _, value = ln[1:].partition(":")
            key = key.strip().lower()
            if key in ("manufacturer", "model", "date of creation", "version",
                       "api android version", "android version release"):
                log.header[key] = value.strip()
        elif ln.startswith("%") and "version" in ln.lower() and "version" not in log.header:
            log.header["version"] = ln[1:].strip()
    return log


def _numeric(log: _Log, kind: str) -> tuple[FloatArray, IntArray]:
    """The numeric fields of a sensor-clock record type (parsed once, then cached)."""
    rows, lines = log.get(kind)
    if kind not in log.parsed:
        names = _NUMERIC_FIELDS[kind]
        usecols = _vector_cols(log, kind) if len(names) == 5 else tuple(
            range(1, len(names) + 1))
        expected = f"{kind};" + ";".join(names)
        log.parsed[kind] = parse_float_rows(rows, sep=";", usecols=usecols,
                                            line_numbers=lines, where=log.label,
                                            field_names=names, expected=expected)
    return log.parsed[kind], lines


def _vector_cols(log: _Log, kind: str) -> tuple[int, ...]:
    """Field indices of app_t, sensor_t, x, y, z (MAGN may carry the header's empty field)."""
    rows, _ = log.get(kind)
    if kind == "MAGN" and rows:
        fields = rows[0].split(";")
        if len(fields) >= 7 and fields[4].strip() == "":
            return (1, 2, 3, 5, 6)
    return (1, 2, 3, 4, 5)


def _sensor_offsets(log: _Log) -> tuple[dict[str, float], float | None]:
    """Offsets ``app_t - sensor_t`` (s) per sensor-clock record type, and their common value.

    One common offset (the median over all such records) is used when the per-type medians
    agree within :data:`CLOCK_SPREAD_S`; otherwise each type keeps its own (some phones stamp
    sensors on different clocks).
    """
    per: dict[str, FloatArray] = {}
    for kind in _SENSOR_CLOCK_TYPES:
        rows, _ = log.get(kind)
        if rows:
            vals, _ = _numeric(log, kind)
            d = vals[:, 0] - vals[:, 1]
            d = d[np.isfinite(d)]
            if len(d):
                per[kind] = d
    if not per:
        return {}, None
    common = float(np.median(np.concatenate(list(per.values()))))
    medians = {k: float(np.median(v)) for k, v in per.items()}
    if max(medians.values()) - min(medians.values()) <= CLOCK_SPREAD_S:
        return dict.fromkeys(medians, common), common
    return medians, common


def _trim(t: FloatArray, cols: list[np.ndarray], t_min: float | None
          ) -> tuple[FloatArray, list[np.ndarray]]:
    if t_min is None:
        return t, cols
    keep = t >= t_min
    return t[keep], [c[keep] for c in cols]


def _sensor_series(log: _Log, kind: str, offsets: dict[str, float], *, repair: bool,
                   t_min: float | None, scale: float = 1.0) -> SensorSeries | None:
    rows, _ = log.get(kind)
    if not rows:
        return None
    offset = offsets.get(kind, 0.0)  # absent: no finite time at all, rejected below
    values, lines = _numeric(log, kind)
    where = f"{log.label} {kind}"
    t, (v,) = check_stream(values[:, 1] + offset, [values[:, 2:] * scale], lines=lines,
                           where=where, repair=repair)
    t, (v,) = _trim(t, [v], t_min)
    if len(t) == 0:
        return None
    return SensorSeries(t, v, f"{Path(log.label).name} {kind}")


def _orientation(log: _Log, offsets: dict[str, float], accel: SensorSeries | None,
                 mag: SensorSeries | None, *, repair: bool, t_min: float | None,
                 notes: list[str]) -> OrientationSeries | None:
    rows, _ = log.get("AHRS")
    if not rows:
        return None
    offset = offsets.get("AHRS", 0.0)  # absent: no finite time at all, rejected below
    values, lines = _numeric(log, "AHRS")
    where = f"{log.label} AHRS"
    t, (vec, ln) = check_stream(values[:, 1] + offset, [values[:, 5:8], lines], lines=lines,
                                where=where, repair=repair)
    sq = np.sum(vec**2, axis=1)
    if np.any(sq > 1.0 + 2e-3):
        i = int(np.flatnonzero(sq > 1.0 + 2e-3)[0])
        raise InputError(f"|(q2, q3, q4)| = {np.sqrt(sq[i]):.4g}",
                         where=f"{log.label} line {int(ln[i])}",
                         expected="rotation-vector components of norm <= 1")
    q = np.column_stack([np.sqrt(np.clip(1.0 - sq, 0.0, None)), vec])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    t, (q,) = _trim(t, [q], t_min)
    if len(t) == 0:
        return None
    _, q_nd = choose_orientation(
        t, [("android rotation vector, device->ENU", lambda: q),
            ("android rotation vector, inverse", lambda: quat_conjugate(q))],
        accel=accel, mag=mag, where=f"{Path(log.label).name} AHRS", notes=notes)
    return OrientationSeries(t, q_nd, f"{Path(log.label).name} AHRS")


def _ble(log: _Log, *, repair: bool, t_min: float | None
         ) -> tuple[FloatArray, list[str], list[int | None], FloatArray, IntArray]:
    """BLE4 rows: time, MAC, minor (None for Eddystone), RSSI, lines."""
    rows, lines = log.get("BLE4")
    t = np.empty(len(rows))
    rss = np.empty(len(rows))
    macs: list[str] = []
    minors: list[int | None] = []
    for k, row in enumerate(rows):
        f = row.split(";")
        at = f"{log.label} line {int(lines[k])}"
        if len(f) < 5:
            raise FormatError(f"{len(f)} field(s)", where=at,
                              expected="BLE4;app_t;iBeacon|Eddystone;MAC;RSSI;...")
        try:
            t[k] = float(f[1])
            rss[k] = float(f[4])
        except ValueError:
            raise FormatError(f"time {f[1]!r} or RSSI {f[4]!r} is not a number", where=at,
                              expected="BLE4;app_t;iBeacon|Eddystone;MAC;RSSI;...") from None
        mac = f[3].strip().upper()
        if not mac:
            raise FormatError("empty MAC", where=at, expected="a beacon MAC address")
        macs.append(mac)
        minor: int | None = None
        if f[2].strip().lower() == "ibeacon" and len(f) >= 8:
            try:
                minor = int(float(f[7]))
            except (ValueError, OverflowError):
                raise FormatError(f"MinorID {f[7]!r} is not a number", where=at,
                                  expected="BLE4;app_t;iBeacon;MAC;RSSI;Power;MajorID;MinorID;"
                                  "UUID") from None
        minors.append(minor)
    _check_rss(rss, lines, log.label)
    mac_arr = np.array(macs, dtype=object)
    minor_arr = np.array(minors, dtype=object)
    t, (rss, mac_arr, minor_arr, lines) = check_stream(
        t, [rss, mac_arr, minor_arr, lines], lines=lines, where=f"{log.label} BLE4",
        repair=repair, strict=False)
    t, (rss, mac_arr, minor_arr, lines) = _trim(t, [rss, mac_arr, minor_arr, lines], t_min)
    return t, list(mac_arr), list(minor_arr), rss, lines


def _check_rss(rss: FloatArray, lines: IntArray, label: str) -> None:
    bad = np.isfinite(rss) & ((rss > 30.0) | (rss < -150.0))
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"RSS {rss[i]:g} dBm", where=f"{label} line {int(lines[i])}",
                         expected="a received power between -150 and 30 dBm")


def _wifi(log: _Log, *, repair: bool, t_min: float | None
          ) -> tuple[FloatArray, list[str], FloatArray]:
    """WIFI rows on the app clock: the scan's delivery time, shared by all its results.

    (The per-result sensor timestamps are not ordered within a scan.)
    """
    rows, lines = log.get("WIFI")
    t = np.empty(len(rows))
    rss = np.empty(len(rows))
    macs: list[str] = []
    for k, row in enumerate(rows):
        f = row.split(";")
        at = f"{log.label} line {int(lines[k])}"
        if len(f) < 7:
            raise FormatError(f"{len(f)} field(s)", where=at,
                              expected="WIFI;app_t;sensor_t;SSID;MAC;frequency;RSS")
        try:
            # the SSID may itself contain ';': take MAC, frequency and RSS from the right
            t[k], rss[k] = float(f[1]), float(f[-1])
        except ValueError:
            raise FormatError("time or RSS is not a number", where=at,
                              expected="WIFI;app_t;sensor_t;SSID;MAC;frequency;RSS") from None
        mac = f[-3].strip().upper()
        if not mac:
            raise FormatError("empty MAC", where=at, expected="an access-point MAC (BSSID)")
        macs.append(mac)
    _check_rss(rss, lines, log.label)
    mac_arr = np.array(macs, dtype=object)
    t, (rss, mac_arr) = check_stream(t, [rss, mac_arr], lines=lines,
                                     where=f"{log.label} WIFI", repair=repair, strict=False)
    t, (rss, mac_arr) = _trim(t, [rss, mac_arr], t_min)
    return t, list(mac_arr), rss


def _rfid(log: _Log, *, repair: bool, t_min: float | None) -> TagDetections | None:
    rows, lines = log.get("RFID")
    if not rows:
        return None
    values = parse_float_rows(rows, sep=";", usecols=(1,), line_numbers=lines,
                              where=log.label, field_names=("app_t",),
                              expected="RFID;app_t;reader;tag;RSS_A;RSS_B")
    tags = []
    for k, row in enumerate(rows):
        f = row.split(";")
        if len(f) < 4 or not f[3].strip():
            raise FormatError("missing tag id", where=f"{log.label} line {int(lines[k])}",
                              expected="RFID;app_t;reader;tag;RSS_A;RSS_B")
        tags.append(f[3].strip())
    tag_arr = np.array(tags, dtype=object)
    t, (tag_arr,) = check_stream(values[:, 0], [tag_arr], lines=lines,
                                 where=f"{log.label} RFID", repair=repair, strict=False)
    t, (tag_arr,) = _trim(t, [tag_arr], t_min)
    if len(t) == 0:
        return None
    return TagDetections(t, np.asarray(tag_arr, dtype=np.str_), f"{Path(log.label).name} RFID")


@dataclass
class _Posi:
    t: FloatArray
    lat: FloatArray
    lon: FloatArray
    floor: FloatArray
    counter: list[str]


def _posi(log: _Log) -> _Posi | None:
    rows, lines = log.get("POSI")
    if not rows:
        return None
    names = ("t", "counter", "latitude", "longitude", "floor")
    values = parse_float_rows(rows, sep=";", usecols=(1, 2, 3, 4, 5), line_numbers=lines,
                              where=log.label, field_names=names,
                              expected="POSI;t;counter;latitude;longitude;floor;building")
    for j, (name, lo, hi) in enumerate((("t", -np.inf, np.inf), ("counter", -np.inf, np.inf),
                                        ("latitude", -90.0, 90.0),
                                        ("longitude", -180.0, 360.0),
                                        ("floor", -1000.0, 1000.0))):
        col = values[:, j]
        bad = ~np.isfinite(col) | (col < lo) | (col > hi)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"{name} is {col[i]:g}", where=f"{log.label} line {int(lines[i])}",
                             expected=f"a finite {name}" + ("" if np.isinf(lo) else
                                                           f" in [{lo:g}, {hi:g}]"))
    t = values[:, 0]
    # ground truth is never repaired: a POSI that goes back in time is an error
    check_stream(t, [], lines=lines, where=f"{log.label} POSI", repair=False, strict=False)
    counter = [f"{c:g}" for c in values[:, 1]]
    return _Posi(t, values[:, 2], values[:, 3], values[:, 4], counter)


# --------------------------------------------------------------------------------------------
# Landmark CSV
# --------------------------------------------------------------------------------------------


def read_beacons_csv(data: bytes, *, where: str) -> list[Landmark]:
    """Landmarks from a CSV with a header ``id,lat,lon[,floor][,alt]`` (WGS-84 degrees).

    Column names are matched without case; the id column may be called ``bleID``, ``id``,
    ``name`` or ``beacon``; latitude ``lat``/``latitude``, longitude ``lon``/``lng``/
    ``longitude``. Quotes around values are allowed.
    """
    text = decode_text(data, where=where)
    numbered = [(n, r) for n, r in enumerate(csv_rows(text, where=where), start=1)
                if r and any(c.strip() for c in r)]
    rows = [r for _, r in numbered]
    if not rows:
        raise FormatError("file is empty", where=where, expected="a header id,lat,lon[,floor]")
    header = [c.strip().lower() for c in rows[0]]

    def col(*names: str, required: bool = True) -> int | None:
        for n in names:
            if n in header:
                return header.index(n)
        if required:
            raise FormatError(f"no {names[0]} column in header {','.join(rows[0])}",
                              where=f"{where} line 1",
                              expected=f"a column named {' or '.join(names)}")
        return None

    i_id = col("bleid", "id", "name", "beacon", "anchor")
    i_lat = col("lat", "latitude")
    i_lon = col("lon", "lng", "long", "longitude")
    i_floor = col("floor", "floorid", "floor_id", required=False)
    i_alt = col("alt", "altitude", "height", required=False)
    assert i_id is not None and i_lat is not None and i_lon is not None
    out: list[Landmark] = []
    seen: set[str] = set()
    for n, row in numbered[1:]:
        at = f"{where} line {n}"
        if len(row) != len(header):
            raise FormatError(f"{len(row)} field(s)", where=at,
                              expected=f"{len(header)} fields like the header")
        ident = row[i_id].strip()
        if not ident:
            raise FormatError("empty id", where=at, expected="a landmark id")
        if ident in seen:
            raise FormatError(f"id {ident!r} appears twice", where=at, expected="unique ids")
        seen.add(ident)
        try:
            lat = float(row[i_lat])
            lon = float(row[i_lon])
            floor = None if i_floor is None or not row[i_floor].strip() else int(
                float(row[i_floor]))
            alt = 0.0 if i_alt is None or not row[i_alt].strip() else float(row[i_alt])
        except (ValueError, OverflowError):
            raise FormatError("latitude, longitude, floor or altitude is not a number",
                              where=at, expected="numbers in degrees / floor number / m") from None
        try:
            out.append(Landmark(id=ident, kind="beacon", wgs84=Wgs84(lat=lat, lon=lon, alt=alt),
                                floor=floor))
        except ValidationError as exc:
            problem = "; ".join(e["msg"] for e in exc.errors())
            raise FormatError(problem, where=at, expected="latitude in [-90, 90], longitude in "
                              "[-180, 360], finite altitude") from None
    return out


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------


def _pick_logfile(src: Source) -> str:
    if src.kind == "file":
        return src.names[0]
    texts = [n for n in src.names
             if PurePosixPath(n).suffix.lower() in (".txt", ".log", ".csv", ".dat", "")]
    found = [n for n in texts if looks_like_ipin(src.head(n, 65536))]
    if not found:
        raise FormatError("no IPIN logfile found", where=str(src.path),
                          expected="a text file with lines like 'ACCE;...' and 'POSI;...'")
    if len(found) > 1:
        raise FormatError(f"{len(found)} logfiles ({', '.join(found[:5])})",
                          where=str(src.path), expected="one logfile; pass the file itself")
    return found[0]


def _find_beacons(src: Source, logname: str) -> tuple[bytes, str] | None:
    pattern = re.compile(r".*ble.*location.*\.csv$|^beacons?\.csv$", re.IGNORECASE)
    if src.kind == "file":
        hits = sorted(p for p in src.path.parent.iterdir()
                      if p.is_file() and pattern.match(p.name))
        return (hits[0].read_bytes(), str(hits[0])) if len(hits) == 1 else None
    hits2 = [n for n in src.names if n != logname and pattern.match(PurePosixPath(n).name)]
    return (src.read(hits2[0]), src.label(hits2[0])) if len(hits2) == 1 else None


def _resolve_ids(macs: list[str], minors: list[int | None], known: Collection[str],
                 beacon_ids: Mapping[str, str] | BeaconIdRule | None
                 ) -> tuple[list[str], dict[str, str], list[str]]:
    """Anchor id per reading, the MAC -> id map used, and the MACs kept unmapped."""
    table = {k.upper(): v for k, v in beacon_ids.items()} if isinstance(beacon_ids,
                                                                          Mapping) else {}
    rule: BeaconIdRule = beacon_ids if callable(beacon_ids) else ipin_beacon_id
    cache: dict[tuple[str, int | None], str] = {}
    used: dict[str, str] = {}
    unknown: set[str] = set()
    out = []
    for mac, minor in zip(macs, minors, strict=True):
        key = (mac, minor)
        if key not in cache:
            ident = table.get(mac) or rule(mac, minor)
            if ident and ident in known:
                cache[key] = ident
                used[mac] = ident
            else:
                cache[key] = mac
                unknown.add(mac)
        out.append(cache[key])
    return out, used, sorted(unknown)


def read_ipin(path: Path | str, *, repair: bool = False, beacons: Path | str | None = None,
              find_beacons: bool = True,
              beacon_ids: Mapping[str, str] | BeaconIdRule | None = None,
              include_wifi: bool = False, floor_height_m: float | None = None,
              trim_to_start: bool = False, check_units: bool = True,
              max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read an IPIN/EvAAL logfile (a file, or a folder/zip holding one) into a session.

    Parameters
    ----------
    path:
        The logfile, or a folder or zip with exactly one logfile (and optionally the beacon
        CSV).
    repair:
        Drop non-finite rows, sort backward times and merge duplicated sensor times, each with
        a :class:`~hrtls.errors.RepairWarning`; without it they raise :class:`InputError`
        naming the file line. Ground truth (POSI) is never repaired.
    beacons:
        Landmark CSV with beacon positions (``id,lat,lon,floor``); see
        :func:`read_beacons_csv`.
    find_beacons:
        Without ``beacons``, look for ``*ble*locations*.csv`` beside the logfile.
    beacon_ids:
        Override of the beacon-id rule: a ``{MAC: id}`` mapping (other MACs follow the
        default rule) or a function ``(mac, minor) -> id | None``. See :func:`ipin_beacon_id`.
    include_wifi:
        Also turn WIFI records into RSS readings with the access-point MAC as anchor id (no
        positions are known for them). Off by default.
    floor_height_m:
        Height of one floor, m, for ``z = floor * floor_height_m`` (default: the session
        default, 3 m).
    trim_to_start:
        Drop everything recorded before the first POSI (the known start).
    check_units:
        Reject an IMU whose units still look wrong after conversion (g, deg/s, gauss ...)
        with a :class:`~hrtls.errors.UnitError`; False keeps such data as it is.
    max_bytes:
        Cap on the size read (zip: total uncompressed size).

    Raises
    ------
    FormatError, InputError
        Naming the file, line and field that are wrong.
    """
    src = open_source(path, max_bytes=max_bytes)
    logname = _pick_logfile(src)
    label = src.label(logname)
    data = src.read(logname)
    if not looks_like_ipin(data[:65536]):
        raise FormatError("no IPIN records (ACCE;, GYRO;, POSI; ...) in the first 64 KiB",
                          where=label, expected="an IPIN/EvAAL logfile")
    log = _split_log(_without_cut_last_line(decode_text(data, where=label, lenient=True), label,
                                            repair=repair), label)
    meta = SessionMeta(placement="hand") if floor_height_m is None else \
        SessionMeta(placement="hand", floor_height_m=floor_height_m)
    fh = meta.floor_height_m
    notes: list[str] = []
    files = [label]

    posi = _posi(log)
    t_min = float(posi.t[0]) if (trim_to_start and posi is not None) else None
    offsets, offset = _sensor_offsets(log)
    if offset is not None and len(set(offsets.values())) == 1:
        notes.append(f"{'/'.join(offsets)} use their sensor timestamps shifted by "
                     f"{offset:+.4f} s (median app - sensor time) onto the app clock of POSI "
                     "and BLE4")
    elif offset is not None:
        notes.append("sensor clocks differ by record type, each shifted by its own median "
                     "app - sensor time: " + ", ".join(f"{k} {v:+.4f} s"
                                                      for k, v in offsets.items()))
    accel = _sensor_series(log, "ACCE", offsets, repair=repair, t_min=t_min)
    gyro = _sensor_series(log, "GYRO", offsets, repair=repair, t_min=t_min)
    mag = _sensor_series(log, "MAGN", offsets, repair=repair, t_min=t_min)
    pressure = _sensor_series(log, "PRES", offsets, repair=repair, t_min=t_min,
                              scale=HPA_TO_PA)
    if pressure is not None:
        notes.append("PRES converted from mbar to Pa")
    imu = None
    if accel is not None:
        imu = ImuStream(accel, gyro, mag, check_units=check_units)
    elif gyro is not None or mag is not None:
        notes.append("GYRO/MAGN present but no ACCE: no IMU stream")
    orientation = _orientation(log, offsets, accel, mag, repair=repair, t_min=t_min,
                               notes=notes)

    # georeference, start pose and checkpoints from POSI
    georef: Georeference | None = None
    checkpoints = None
    source: dict[str, Any] = {"format": "ipin", "files": files}
    if posi is not None:
        georef = Georeference(float(posi.lat[0]), float(posi.lon[0]), 0.0)
        meta.georeference = GeoreferenceModel(lat_deg=georef.lat_deg, lon_deg=georef.lon_deg,
                                              height_m=0.0)
        meta.start_pose = StartPose(t=float(posi.t[0]), x=0.0, y=0.0,
                                    z=float(posi.floor[0]) * fh)
        source["start_pose_t_s"] = float(posi.t[0])
        notes.append(f"POSI {posi.counter[0]} (t = {posi.t[0]:.3f} s, floor "
                     f"{posi.floor[0]:g}) is the start pose and the georeference (local ENU "
                     f"origin, height 0); start heading unknown")
        if len(posi.t) > 1:
            xyz = georef.from_wgs84(posi.lat[1:], posi.lon[1:], np.zeros(len(posi.t) - 1))
            xyz[:, 2] = posi.floor[1:] * fh
            checkpoints = Checkpoints(posi.t[1:], xyz, np.array(posi.counter[1:], dtype=np.str_),
                                      f"{Path(label).name} POSI")
            notes.append(f"POSI {posi.counter[1]}..{posi.counter[-1]} are checkpoints "
                         f"(z = floor x {fh:g} m)")
        if trim_to_start:
            notes.append(f"data before the first POSI (t < {posi.t[0]:.3f} s) dropped")
    else:
        notes.append("no POSI records: no georeference, start pose or checkpoints")

    # landmarks
    landmarks: dict[str, Landmark] = {}
    beacon_data: tuple[bytes, str] | None = None
    if beacons is not None:
        bpath = Path(beacons)
        if not bpath.is_file():
            raise InputError("no such file", where=str(bpath), expected="a beacon CSV")
        beacon_data = (bpath.read_bytes(), str(bpath))
    elif find_beacons:
        beacon_data = _find_beacons(src, logname)
    if beacon_data is not None:
        files.append(beacon_data[1])
        for lm in read_beacons_csv(beacon_data[0], where=beacon_data[1]):
            if georef is not None and lm.wgs84 is not None:
                xyz = georef.from_wgs84(lm.wgs84.lat, lm.wgs84.lon, 0.0)[0]
                z = (lm.floor or 0) * fh
                lm = lm.model_copy(update={"position": (float(xyz[0]), float(xyz[1]), z)})
            landmarks[lm.id] = lm
        notes.append(f"{len(landmarks)} beacon landmark(s) from {Path(beacon_data[1]).name}"
                     + (" placed with z = floor x floor height" if georef is not None else
                        " (WGS-84 only: no georeference)"))

    # RSS: BLE4 (+ WIFI)
    t_list: list[FloatArray] = []
    id_list: list[str] = []
    rss_list: list[FloatArray] = []
    if log.rows.get("BLE4"):
        t_b, macs, minors, rss_b, _ = _ble(log, repair=repair, t_min=t_min)
        ids, used, unknown = _resolve_ids(macs, minors, landmarks, beacon_ids)
        t_list.append(t_b)
        id_list.extend(ids)
        rss_list.append(rss_b)
        if used:
            notes.append("BLE4 beacons mapped to landmarks: " + ", ".join(
                f"{m}->{i}" for m, i in sorted(used.items())))
        if unknown:
            notes.append(f"BLE4: {len(unknown)} beacon(s) match no landmark and keep their MAC "
                         f"as id: {', '.join(unknown)}")
    n_wifi = len(log.rows.get("WIFI", []))
    if n_wifi and include_wifi:
        t_w, macs_w, rss_w = _wifi(log, repair=repair, t_min=t_min)
        t_list.append(t_w)
        id_list.extend(macs_w)
        rss_list.append(rss_w)
        notes.append(f"WIFI: {len(t_w)} readings of {len(set(macs_w))} access points kept "
                     "(anchor id = BSSID; no positions known)")
    elif n_wifi:
        notes.append(f"WIFI: {n_wifi} records not used (no access-point positions; pass "
                     "include_wifi=True to keep them as RSS readings)")
    rss = None
    if t_list:
        t_all = np.concatenate(t_list)
        order = np.argsort(t_all, kind="stable")
        if len(order):
            rss = RssReadings(t_all[order], np.array(id_list, dtype=np.str_)[order],
                              np.concatenate(rss_list)[order], f"{Path(label).name} RSS")
    tags = _rfid(log, repair=repair, t_min=t_min)

    if log.skipped:
        notes.append("records not used: " + ", ".join(
            f"{k} ({n})" for k, n in sorted(log.skipped.items())))
    if log.header:
        source["device"] = dict(log.header)
    if offset is not None:
        source["sensor_clock_offset_s"] = offset
        if len(set(offsets.values())) > 1:
            source["sensor_clock_offsets_s"] = offsets
    meta.source = source
    meta.notes = notes
    if imu is None and rss is None and tags is None:
        raise FormatError("no accelerometer (ACCE), BLE4 or RFID records", where=label,
                          expected="a logfile with sensor or radio records")
    return Session(meta=meta, imu=imu, pressure=pressure, orientation=orientation, rss=rss,
                   tags=tags, landmarks=landmarks, checkpoints=checkpoints)
