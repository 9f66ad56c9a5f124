"""phyphox CSV exports (a zip or folder, or one CSV) -> :class:`Session`.

phyphox writes one CSV per export set (``Raw Data.csv``, or ``Accelerometer.csv``,
``Gyroscope.csv``, ``Magnetometer.csv``, ``Linear Acceleration.csv`` ... in multi-sensor
experiments) with quoted header names that carry the unit: ``"Time (s)"``,
``"Acceleration x (m/s^2)"``, ``"Gyroscope x (rad/s)"``, ``"Magnetic field x (µT)"``,
``"Pressure (hPa)"``. Comma, tab and semicolon (with decimal comma) exports are understood.

Columns are classified by their names, never by position: ``<quantity> x|y|z (<unit>)`` for
vectors and ``<quantity> (<unit>)`` for scalars; ``Absolute ...`` columns are ignored. The units
in the names are converted to SI (and noted). "Linear acceleration" (acceleration without g) is
not the specific force and is used only when nothing else is there (it is then refused); an
"Acceleration" column in a file named like "without g" is treated the same way.

Time is phyphox's experiment time (s since the start). When ``meta/time.csv`` gives the system
time of the START event, ``meta.time_origin_unix_s`` is set from it.

Axes: phyphox reports the Android device frame on both platforms (x right, y up the screen, z
out of the screen), which is taken as the device frame here; *unverified* for iOS exports.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError
from hrtls.io.readers._text import (
    HeaderCsv,
    Quantity,
    check_stream,
    csv_rows,
    decode_text,
    read_header_csv,
    to_si,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.units import G_TO_M_S2, TIME_SCALES_S

__all__ = ["classify_column", "looks_like_phyphox", "read_phyphox"]

_VECTOR_RE = re.compile(r"^(?P<q>.*?)\s*(?:[_\s])(?P<axis>[xyzXYZ])\s*(?:\((?P<unit>[^)]*)\))?$")
_SCALAR_RE = re.compile(r"^(?P<q>.*?)\s*(?:\((?P<unit>[^)]*)\))?$")
_KINDS = {"accel": ("acceleration", "accelerometer", "acceleration with g"),
          "linear": ("linear acceleration", "acceleration without g", "linear accelerometer"),
          "gyro": ("gyroscope", "gyro", "angular velocity", "rotation rate", "angular rate"),
          "mag": ("magnetic field", "magnetometer", "magnetic flux density", "magnetic flux"),
          "pressure": ("pressure", "air pressure", "barometer")}


_QUANTITY: dict[str, Quantity] = {"accel": "accel", "linear": "accel", "gyro": "gyro",
                                  "mag": "mag", "pressure": "pressure"}


def looks_like_phyphox(head: bytes) -> bool:
    """True when a CSV header looks like phyphox (``"Time (s)"`` and unit-bearing names)."""
    first = head.decode("utf-8", errors="replace").lstrip("\ufeff").split("\n", 1)[0]
    return bool(re.match(r'^\s*"?time \((s|ms)\)"?\s*[,;\t]', first, re.IGNORECASE))


def classify_column(name: str) -> tuple[str, str | None, str | None] | None:
    """``(kind, axis, unit)`` of a phyphox column name, or None when not a sensor column.

    ``kind`` is one of accel, linear, gyro, mag, pressure, time; ``axis`` is x/y/z (None for
    scalars); ``unit`` is the text in parentheses (None when absent).
    """
    low = name.strip().lower()
    if low.startswith("absolute"):
        return None
    m = _VECTOR_RE.match(name.strip())
    if m and m.group("q"):
        quantity = m.group("q").strip().lower()
        for kind, words in _KINDS.items():
            if quantity in words and kind != "pressure":
                return kind, m.group("axis").lower(), m.group("unit")
    m = _SCALAR_RE.match(name.strip())
    if m:
        quantity = m.group("q").strip().lower()
        if quantity in ("time", "t"):
            return "time", None, m.group("unit")
        if quantity in _KINDS["pressure"]:
            return "pressure", None, m.group("unit")
    return None


@dataclass
class _Found:
    kind: str
    t: FloatArray
    values: FloatArray
    units: list[str | None]
    where: str
    lines: np.ndarray


def _scan_table(table: HeaderCsv, name: str) -> list[_Found]:
    """Sensor groups of one CSV (all sharing its time column)."""
    cols = [classify_column(h) for h in table.header]
    times = [i for i, c in enumerate(cols) if c is not None and c[0] == "time"]
    groups: dict[str, dict[str, tuple[int, str | None]]] = {}
    for i, c in enumerate(cols):
        if c is None or c[0] == "time":
            continue
        kind, axis, unit = c
        if kind in ("accel", "linear") and re.search(r"without g|linear", name, re.IGNORECASE):
            kind = "linear"
        slot = groups.setdefault(kind, {})
        key = axis or "value"
        if key in slot:
            raise FormatError(f"two {kind} {key} columns", where=f"{table.where} line 1",
                              expected="one column per axis")
        slot[key] = (i, unit)
    if not groups:
        return []
    if len(times) != 1:
        raise FormatError(f"{len(times)} time columns", where=f"{table.where} line 1",
                          expected="one 'Time (s)' column")
    time_col = cols[times[0]]
    t_unit = time_col[2] if time_col is not None else None
    scale = TIME_SCALES_S.get((t_unit or "s").strip().lower())
    if scale is None:
        raise FormatError(f"time unit {t_unit!r}", where=f"{table.where} line 1",
                          expected="Time (s) or Time (ms)")
    out = []
    for kind, slot in groups.items():
        keys = ["value"] if kind == "pressure" else ["x", "y", "z"]
        missing = [k for k in keys if k not in slot]
        if missing:
            raise FormatError(f"{kind} lacks axis {', '.join(missing)}",
                              where=f"{table.where} line 1", expected="x, y and z columns")
        names = [table.header[times[0]]] + [table.header[slot[k][0]] for k in keys]
        values = table.floats(names)
        out.append(_Found(kind, values[:, 0] * scale, values[:, 1:],
                          [slot[k][1] for k in keys], table.where, table.lines))
    return out


def _time_origin(src: Source, notes: list[str]) -> float | None:
    name = next((n for n in src.names if PurePosixPath(n).as_posix().lower().endswith(
        "meta/time.csv")), None)
    if name is None:
        return None
    try:
        text = decode_text(src.read(name), where=src.label(name))
        rows = csv_rows(text, where=src.label(name))
        header = [h.strip().lower() for h in rows[0]]
        i_ev, i_exp, i_sys = (header.index("event"), header.index("experiment time"),
                              header.index("system time"))
        for r in rows[1:]:
            if r and r[i_ev].strip().upper() == "START":
                origin = float(r[i_sys]) - float(r[i_exp])
                if 1e9 <= origin <= 4e9:
                    return origin
                break
    except (FormatError, ValueError, IndexError):
        pass
    notes.append(f"{src.label(name)} not understood: absolute time unknown")
    return None


def _find_sensor_columns(src: Source) -> tuple[dict[str, _Found], list[str]]:
    """The sensor column groups of the export's CSVs by kind, and the files they are in."""
    found: dict[str, _Found] = {}
    used: list[str] = []
    for name in src.names:
        if not name.lower().endswith((".csv", ".txt")) or name.lower().startswith("meta/") \
                or "/meta/" in name.lower():
            continue
        if not looks_like_phyphox(src.head(name, 4096)):
            continue
        table = read_header_csv(src.read(name), where=src.label(name))
        groups = _scan_table(table, PurePosixPath(name).name)
        if groups:
            used.append(src.label(name))
        for g in groups:
            if g.kind in found:
                raise FormatError(f"{g.kind} data in two files ({found[g.kind].where}, "
                                  f"{g.where})", where=str(src.path),
                                  expected="one export per sensor")
            found[g.kind] = g
    if not found:
        raise FormatError("no phyphox sensor columns", where=str(src.path),
                          expected='a CSV with "Time (s)" and columns like "Acceleration x '
                          '(m/s^2)"')
    return found, used


def _series_in_si(found: dict[str, _Found], *, repair: bool, notes: list[str]
                  ) -> dict[str, SensorSeries]:
    """Checked series per kind, IMU quantities converted to SI (one unit per x, y, z)."""
    series: dict[str, SensorSeries] = {}
    for kind, g in found.items():
        t, (v,) = check_stream(g.t, [g.values], lines=g.lines, where=g.where, repair=repair)
        if len(t) == 0:
            notes.append(f"{g.where}: no {kind} samples, not used")
            continue
        quantity = _QUANTITY.get(kind)
        if quantity is not None:
            unit = g.units[0] or "auto"
            if any(u != g.units[0] for u in g.units):
                raise FormatError(f"axes in different units ({', '.join(map(str, g.units))})",
                                  where=f"{g.where} line 1", expected="one unit for x, y, z")
            v = to_si(v, quantity, unit, where=f"{Path(g.where).name} {kind}", notes=notes)
        series[kind] = SensorSeries(t, v, f"{Path(g.where).name} {kind}")
    return series


def read_phyphox(path: Path | str, *, repair: bool = False, check_units: bool = True,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read a phyphox CSV export (zip, folder or one CSV) into a session.

    Parameters
    ----------
    path:
        The export zip or folder, or a single exported CSV.
    repair:
        Drop non-finite rows, sort backward times and merge duplicated times with a
        :class:`~hrtls.errors.RepairWarning`; without it they raise :class:`InputError`
        naming the file line. (phyphox leaves cells empty where a sensor had no new value;
        those rows need ``repair=True``.)
    check_units:
        Reject an IMU whose units still look wrong after conversion (g, deg/s, gauss ...)
        with a :class:`~hrtls.errors.UnitError`; False keeps such data as it is.
    max_bytes:
        Cap on the size read (zip: total uncompressed size).

    Raises
    ------
    FormatError, InputError, UnitError
        Naming the file, line and column that are wrong.
    """
    src = open_source(path, max_bytes=max_bytes)
    notes: list[str] = []
    found, used = _find_sensor_columns(src)
    series = _series_in_si(found, repair=repair, notes=notes)
    accel = series.get("accel")
    if accel is not None and len(accel) >= 20:
        norm = float(np.median(np.linalg.norm(accel.values, axis=1)))
        if norm < 0.4 * G_TO_M_S2:
            notes.append(f"{accel.name}: median |a| = {norm:.3g} m/s^2, so it is acceleration "
                         "without g")
            series["linear"] = accel
            accel = None
    if accel is None:
        if "linear" in series:
            raise FormatError("only acceleration without g (linear acceleration)",
                              where=str(src.path),
                              expected="an 'Acceleration with g' export (the specific force)",
                              hint="record phyphox's 'Acceleration with g' experiment")
        raise FormatError("no accelerometer columns", where=str(src.path),
                          expected='columns like "Acceleration x (m/s^2)"')
    if "linear" in series:
        notes.append("linear acceleration not used (the specific force with g is)")
    imu = ImuStream(accel, series.get("gyro"), series.get("mag"), check_units=check_units)
    origin = _time_origin(src, notes)
    source: dict[str, Any] = {"format": "phyphox", "files": used}
    notes.append("device frame: phyphox axes (Android convention), unverified for iOS exports")
    meta = SessionMeta(source=source, notes=notes, time_origin_unix_s=origin)
    return Session(meta=meta, imu=imu, pressure=series.get("pressure"))

