"""IPIN logfile records: the file split by record type, sensor clocks, IMU, AHRS and POSI.

Helpers of :func:`hrtls.io.readers.ipin.read_ipin` (the format is described there).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hrtls.data import OrientationSeries, SensorSeries
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.frames import quat_conjugate
from hrtls.io.readers._orientation import choose_orientation
from hrtls.io.readers._text import IntArray, check_stream, parse_float_rows

CLOCK_SPREAD_S = 0.1
"""Largest spread of per-type clock offsets for which one common offset is used, s."""

_TYPE_RE = re.compile(r"[A-Z0-9]{4};")
_SENSOR_CLOCK_TYPES = ("ACCE", "GYRO", "MAGN", "AHRS", "PRES")
_USED_TYPES = ("ACCE", "GYRO", "MAGN", "PRES", "AHRS", "BLE4", "WIFI", "RFID", "POSI")
_TEXT_TYPES = ("BLE4", "WIFI", "RFID")
_NUMERIC_FIELDS = {
    "ACCE": ("app_t", "sensor_t", "x", "y", "z"), "GYRO": ("app_t", "sensor_t", "x", "y", "z"),
    "MAGN": ("app_t", "sensor_t", "x", "y", "z"), "PRES": ("app_t", "sensor_t", "pressure_mbar"),
    "AHRS": ("app_t", "sensor_t", "pitch", "roll", "yaw", "q2", "q3", "q4")}



@dataclass
class IpinLog:
    """A logfile split by record type: rows and their 1-based line numbers."""

    label: str
    rows: dict[str, list[str]] = field(default_factory=dict)
    lines: dict[str, IntArray] = field(default_factory=dict)
    parsed: dict[str, FloatArray] = field(default_factory=dict)
    header: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)
    repair: bool = False
    """Malformed sensor rows are read as missing values (dropped by the stream repair)."""

    def get(self, kind: str) -> tuple[list[str], IntArray]:
        return self.rows.get(kind, []), self.lines.get(kind, np.zeros(0, dtype=np.int64))


def without_cut_last_line(text: str, label: str, *, repair: bool) -> str:
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


def split_log(text: str, label: str, *, repair: bool = False) -> IpinLog:
    """Group the lines by record type (vectorized over the whole file)."""
    lines = text.splitlines()
    log = IpinLog(label, repair=repair)
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


def numeric(log: IpinLog, kind: str) -> tuple[FloatArray, IntArray]:
    """The numeric fields of a sensor-clock record type (parsed once, then cached)."""
    rows, lines = log.get(kind)
    if kind not in log.parsed:
        names = _NUMERIC_FIELDS[kind]
        usecols = vector_cols(log, kind) if len(names) == 5 else tuple(
            range(1, len(names) + 1))
        expected = f"{kind};" + ";".join(names)
        try:
            log.parsed[kind] = parse_float_rows(rows, sep=";", usecols=usecols,
                                                line_numbers=lines, where=log.label,
                                                field_names=names, expected=expected,
                                                malformed_as_nan=log.repair)
        except FormatError as exc:
            raise FormatError(exc.problem, where=exc.where, expected=exc.expected,
                              hint="pass --repair (repair=True in Python) to drop such rows "
                              "with a warning") from None
    return log.parsed[kind], lines


def vector_cols(log: IpinLog, kind: str) -> tuple[int, ...]:
    """Field indices of app_t, sensor_t, x, y, z (MAGN may carry the header's empty field)."""
    rows, _ = log.get(kind)
    if kind == "MAGN" and rows:
        fields = rows[0].split(";")
        if len(fields) >= 7 and fields[4].strip() == "":
            return (1, 2, 3, 5, 6)
    return (1, 2, 3, 4, 5)


def sensor_offsets(log: IpinLog) -> tuple[dict[str, float], float | None]:
    """Offsets ``app_t - sensor_t`` (s) per sensor-clock record type, and their common value.

    One common offset (the median over all such records) is used when the per-type medians
    agree within :data:`CLOCK_SPREAD_S`; otherwise each type keeps its own (some phones stamp
    sensors on different clocks).
    """
    per: dict[str, FloatArray] = {}
    for kind in _SENSOR_CLOCK_TYPES:
        rows, _ = log.get(kind)
        if rows:
            vals, _ = numeric(log, kind)
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


def trim(t: FloatArray, cols: list[np.ndarray], t_min: float | None
          ) -> tuple[FloatArray, list[np.ndarray]]:
    """``t`` and the columns without the rows before ``t_min`` (None: all rows)."""
    if t_min is None:
        return t, cols
    keep = t >= t_min
    return t[keep], [c[keep] for c in cols]


def sensor_series(log: IpinLog, kind: str, offsets: dict[str, float], *, repair: bool,
                   t_min: float | None, scale: float = 1.0) -> SensorSeries | None:
    """The x, y, z (or pressure) values of ``kind`` times ``scale`` on the app clock."""
    rows, _ = log.get(kind)
    if not rows:
        return None
    offset = offsets.get(kind, 0.0)  # absent: no finite time at all, rejected below
    values, lines = numeric(log, kind)
    where = f"{log.label} {kind}"
    t, (v,) = check_stream(values[:, 1] + offset, [values[:, 2:] * scale], lines=lines,
                           where=where, repair=repair)
    t, (v,) = trim(t, [v], t_min)
    if len(t) == 0:
        return None
    return SensorSeries(t, v, f"{Path(log.label).name} {kind}")


def orientation(log: IpinLog, offsets: dict[str, float], accel: SensorSeries | None,
                 mag: SensorSeries | None, *, repair: bool, t_min: float | None,
                 notes: list[str]) -> OrientationSeries | None:
    """The AHRS rotation vectors as ``q_nd``, their reading checked against the data."""
    rows, _ = log.get("AHRS")
    if not rows:
        return None
    offset = offsets.get("AHRS", 0.0)  # absent: no finite time at all, rejected below
    values, lines = numeric(log, "AHRS")
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
    t, (q,) = trim(t, [q], t_min)
    if len(t) == 0:
        return None
    _, q_nd = choose_orientation(
        t, [("android rotation vector, device->ENU", lambda: q),
            ("android rotation vector, inverse", lambda: quat_conjugate(q))],
        accel=accel, mag=mag, where=f"{Path(log.label).name} AHRS", notes=notes)
    return OrientationSeries(t, q_nd, f"{Path(log.label).name} AHRS")


@dataclass
class Posi:
    """POSI records: time (s), WGS-84 latitude/longitude (deg), floor and counter label."""

    t: FloatArray
    lat: FloatArray
    lon: FloatArray
    floor: FloatArray
    counter: list[str]


def posi(log: IpinLog) -> Posi | None:
    """The POSI records, checked (finite, in range, in time order; never repaired)."""
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
    return Posi(t, values[:, 2], values[:, 3], values[:, 4], counter)
