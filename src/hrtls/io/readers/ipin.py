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
from collections.abc import Callable, Collection, Mapping
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
    Wgs84,
)
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.readers._ipin_radio import ble_rows, rfid_detections, wifi_rows
from hrtls.io.readers._ipin_records import (
    IpinLog,
    Posi,
    orientation,
    posi,
    sensor_offsets,
    sensor_series,
    split_log,
    without_cut_last_line,
)
from hrtls.io.readers._text import csv_rows, decode_text
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.units import HPA_TO_PA

__all__ = ["BeaconIdRule", "ipin_beacon_id", "looks_like_ipin", "read_beacons_csv", "read_ipin"]

BeaconIdRule = Callable[[str, "int | None"], "str | None"]
"""``rule(mac, minor) -> landmark id`` (None: keep the MAC)."""

_SNIFF_RE = re.compile(r"^(ACCE|GYRO|MAGN|PRES|AHRS|POSI|BLE4|WIFI|GNSS);", re.MULTILINE)


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
    log = _split_logfile(src.read(logname), label=label, repair=repair)
    meta = SessionMeta(placement="hand") if floor_height_m is None else \
        SessionMeta(placement="hand", floor_height_m=floor_height_m)
    notes: list[str] = []
    source: dict[str, Any] = {"format": "ipin", "files": [label]}

    start = posi(log)
    t_min = float(start.t[0]) if (trim_to_start and start is not None) else None
    offsets, offset = sensor_offsets(log)
    _note_clocks(offsets, offset, notes)
    imu, pressure, orient = _inertial(log, offsets, notes, repair=repair, t_min=t_min,
                                      check_units=check_units)
    georef, checkpoints = _ground_truth(start, meta, source, notes, label=label,
                                        trim_to_start=trim_to_start)
    beacon_data = _beacon_csv(src, logname, beacons=beacons, find_beacons=find_beacons)
    landmarks = _landmarks(beacon_data, georef, meta.floor_height_m, source, notes)
    rss = _rss(log, landmarks, beacon_ids, notes, repair=repair, t_min=t_min,
               include_wifi=include_wifi, label=label)
    tags = rfid_detections(log, repair=repair, t_min=t_min)

    _note_log(log, offsets, offset, source, notes)
    meta.source = source
    meta.notes = notes
    if imu is None and rss is None and tags is None:
        raise FormatError("no accelerometer (ACCE), BLE4 or RFID records", where=label,
                          expected="a logfile with sensor or radio records")
    return Session(meta=meta, imu=imu, pressure=pressure, orientation=orient, rss=rss,
                   tags=tags, landmarks=landmarks, checkpoints=checkpoints)


def _split_logfile(data: bytes, *, label: str, repair: bool) -> IpinLog:
    """The records of a logfile's bytes (FormatError when it holds no IPIN records)."""
    if not looks_like_ipin(data[:65536]):
        raise FormatError("no IPIN records (ACCE;, GYRO;, POSI; ...) in the first 64 KiB",
                          where=label, expected="an IPIN/EvAAL logfile")
    return split_log(without_cut_last_line(decode_text(data, where=label, lenient=True), label,
                                           repair=repair), label, repair=repair)


def _beacon_csv(src: Source, logname: str, *, beacons: Path | str | None,
                find_beacons: bool) -> tuple[bytes, str] | None:
    """Bytes and name of the beacon CSV: the one given, else one found beside the logfile."""
    if beacons is not None:
        bpath = Path(beacons)
        if not bpath.is_file():
            raise InputError("no such file", where=str(bpath), expected="a beacon CSV")
        return bpath.read_bytes(), str(bpath)
    return _find_beacons(src, logname) if find_beacons else None


def _note_log(log: IpinLog, offsets: dict[str, float], offset: float | None,
              source: dict[str, Any], notes: list[str]) -> None:
    """Record the unused records, the device header and the sensor clock offsets."""
    if log.skipped:
        notes.append("records not used: " + ", ".join(
            f"{k} ({n})" for k, n in sorted(log.skipped.items())))
    if log.header:
        source["device"] = dict(log.header)
    if offset is not None:
        source["sensor_clock_offset_s"] = offset
        if len(set(offsets.values())) > 1:
            source["sensor_clock_offsets_s"] = offsets


def _inertial(log: IpinLog, offsets: dict[str, float], notes: list[str], *, repair: bool,
              t_min: float | None, check_units: bool
              ) -> tuple[ImuStream | None, SensorSeries | None, OrientationSeries | None]:
    """IMU stream, pressure (Pa) and AHRS orientation on the app clock."""
    accel = sensor_series(log, "ACCE", offsets, repair=repair, t_min=t_min)
    gyro = sensor_series(log, "GYRO", offsets, repair=repair, t_min=t_min)
    mag = sensor_series(log, "MAGN", offsets, repair=repair, t_min=t_min)
    pressure = sensor_series(log, "PRES", offsets, repair=repair, t_min=t_min,
                             scale=HPA_TO_PA)
    if pressure is not None:
        notes.append("PRES converted from mbar to Pa")
    imu = None
    if accel is not None:
        imu = ImuStream(accel, gyro, mag, check_units=check_units)
    elif gyro is not None or mag is not None:
        notes.append("GYRO/MAGN present but no ACCE: no IMU stream")
    orient = orientation(log, offsets, accel, mag, repair=repair, t_min=t_min, notes=notes)
    return imu, pressure, orient


def _note_clocks(offsets: dict[str, float], offset: float | None, notes: list[str]) -> None:
    """Say how the sensor clocks were put on the app clock."""
    if offset is not None and len(set(offsets.values())) == 1:
        notes.append(f"{'/'.join(offsets)} use their sensor timestamps shifted by "
                     f"{offset:+.4f} s (median app - sensor time) onto the app clock of POSI "
                     "and BLE4")
    elif offset is not None:
        notes.append("sensor clocks differ by record type, each shifted by its own median "
                     "app - sensor time: " + ", ".join(f"{k} {v:+.4f} s"
                                                      for k, v in offsets.items()))


def _ground_truth(start: Posi | None, meta: SessionMeta, source: dict[str, Any],
                  notes: list[str], *, label: str, trim_to_start: bool
                  ) -> tuple[Georeference | None, Checkpoints | None]:
    """Georeference, start pose (set on ``meta``) and checkpoints from the POSI records."""
    if start is None:
        notes.append("no POSI records: no georeference, start pose or checkpoints")
        return None, None
    fh = meta.floor_height_m
    georef = Georeference(float(start.lat[0]), float(start.lon[0]), 0.0)
    meta.georeference = GeoreferenceModel(lat_deg=georef.lat_deg, lon_deg=georef.lon_deg,
                                          height_m=0.0)
    meta.start_pose = StartPose(t=float(start.t[0]), x=0.0, y=0.0,
                                z=float(start.floor[0]) * fh)
    source["start_pose_t_s"] = float(start.t[0])
    notes.append(f"POSI {start.counter[0]} (t = {start.t[0]:.3f} s, floor "
                 f"{start.floor[0]:g}) is the start pose and the georeference (local ENU "
                 f"origin, height 0); start heading unknown")
    checkpoints = None
    if len(start.t) > 1:
        xyz = georef.from_wgs84(start.lat[1:], start.lon[1:], np.zeros(len(start.t) - 1))
        xyz[:, 2] = start.floor[1:] * fh
        checkpoints = Checkpoints(start.t[1:], xyz, np.array(start.counter[1:], dtype=np.str_),
                                  f"{Path(label).name} POSI")
        notes.append(f"POSI {start.counter[1]}..{start.counter[-1]} are checkpoints "
                     f"(z = floor x {fh:g} m)")
    if trim_to_start:
        notes.append(f"data before the first POSI (t < {start.t[0]:.3f} s) dropped")
    return georef, checkpoints


def _landmarks(beacon_data: tuple[bytes, str] | None, georef: Georeference | None, fh: float,
               source: dict[str, Any], notes: list[str]) -> dict[str, Landmark]:
    """Beacon landmarks from the CSV ``(data, label)``, placed in ENU when georeferenced."""
    landmarks: dict[str, Landmark] = {}
    if beacon_data is None:
        return landmarks
    source["files"].append(beacon_data[1])
    for lm in read_beacons_csv(beacon_data[0], where=beacon_data[1]):
        if georef is not None and lm.wgs84 is not None:
            xyz = georef.from_wgs84(lm.wgs84.lat, lm.wgs84.lon, 0.0)[0]
            z = (lm.floor or 0) * fh
            lm = lm.model_copy(update={"position": (float(xyz[0]), float(xyz[1]), z)})
        landmarks[lm.id] = lm
    notes.append(f"{len(landmarks)} beacon landmark(s) from {Path(beacon_data[1]).name}"
                 + (" placed with z = floor x floor height" if georef is not None else
                    " (WGS-84 only: no georeference)"))
    return landmarks


def _rss(log: IpinLog, landmarks: dict[str, Landmark],
         beacon_ids: Mapping[str, str] | BeaconIdRule | None, notes: list[str], *,
         repair: bool, t_min: float | None, include_wifi: bool, label: str
         ) -> RssReadings | None:
    """RSS readings of BLE4 (+ WIFI), in time order."""
    t_list: list[FloatArray] = []
    id_list: list[str] = []
    rss_list: list[FloatArray] = []
    if log.rows.get("BLE4"):
        t_b, macs, minors, rss_b, _ = ble_rows(log, repair=repair, t_min=t_min)
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
        t_w, macs_w, rss_w = wifi_rows(log, repair=repair, t_min=t_min)
        t_list.append(t_w)
        id_list.extend(macs_w)
        rss_list.append(rss_w)
        notes.append(f"WIFI: {len(t_w)} readings of {len(set(macs_w))} access points kept "
                     "(anchor id = BSSID; no positions known)")
    elif n_wifi:
        notes.append(f"WIFI: {n_wifi} records not used (no access-point positions; pass "
                     "include_wifi=True to keep them as RSS readings)")
    if not t_list:
        return None
    t_all = np.concatenate(t_list)
    order = np.argsort(t_all, kind="stable")
    if not len(order):
        return None
    return RssReadings(t_all[order], np.array(id_list, dtype=np.str_)[order],
                       np.concatenate(rss_list)[order], f"{Path(label).name} RSS")
