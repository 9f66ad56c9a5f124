"""IPIN logfile radio records: BLE4 and WIFI received powers, RFID tag reads.

Helpers of :func:`hrtls.io.readers.ipin.read_ipin` (the format is described there).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hrtls.data import TagDetections
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError
from hrtls.io.readers._ipin_records import IpinLog, trim
from hrtls.io.readers._text import IntArray, check_stream, parse_float_rows


def ble_rows(log: IpinLog, *, repair: bool, t_min: float | None
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
    check_rss(rss, lines, log.label)
    mac_arr = np.array(macs, dtype=object)
    minor_arr = np.array(minors, dtype=object)
    t, (rss, mac_arr, minor_arr, lines) = check_stream(
        t, [rss, mac_arr, minor_arr, lines], lines=lines, where=f"{log.label} BLE4",
        repair=repair, strict=False)
    t, (rss, mac_arr, minor_arr, lines) = trim(t, [rss, mac_arr, minor_arr, lines], t_min)
    return t, list(mac_arr), list(minor_arr), rss, lines


def check_rss(rss: FloatArray, lines: IntArray, label: str) -> None:
    """Refuse a received power outside [-150, 30] dBm, naming its line."""
    bad = np.isfinite(rss) & ((rss > 30.0) | (rss < -150.0))
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"RSS {rss[i]:g} dBm", where=f"{label} line {int(lines[i])}",
                         expected="a received power between -150 and 30 dBm")


def wifi_rows(log: IpinLog, *, repair: bool, t_min: float | None
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
    check_rss(rss, lines, log.label)
    mac_arr = np.array(macs, dtype=object)
    t, (rss, mac_arr) = check_stream(t, [rss, mac_arr], lines=lines,
                                     where=f"{log.label} WIFI", repair=repair, strict=False)
    t, (rss, mac_arr) = trim(t, [rss, mac_arr], t_min)
    return t, list(mac_arr), rss


def rfid_detections(log: IpinLog, *, repair: bool, t_min: float | None) -> TagDetections | None:
    """RFID rows on the app clock: the tag id of each read."""
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
    t, (tag_arr,) = trim(t, [tag_arr], t_min)
    if len(t) == 0:
        return None
    return TagDetections(t, np.asarray(tag_arr, dtype=np.str_), f"{Path(log.label).name} RFID")
