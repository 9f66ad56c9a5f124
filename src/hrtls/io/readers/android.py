"""Android per-sensor text files ``TIMESTAMP X Y Z`` (Inderst thesis, App. C, eq. 7.16).

The logger of the thesis writes one text file per sensor, one sample per line: a timestamp and
the three values, separated by blanks (commas, semicolons and tabs are accepted too). A first
line that is not numeric is taken as a header; ``#`` and ``%`` lines are comments.

Which sensor a file holds comes from its name, split into words (``"MagneticField_01.txt"`` ->
``magnetic``, ``field``): a word starting with ``acc`` is the accelerometer, ``gyr`` the
gyroscope, ``mag`` the magnetometer, ``orient`` the orientation sensor. Files named after
linear acceleration or gravity are not specific force and are refused; other files are skipped
with a note (or, when given alone, refused), and ``sensors=`` names them explicitly.

Units. The timestamp unit is guessed from the median sample spacing (Android's
``SensorEvent.timestamp`` is in ns, ``System.currentTimeMillis`` in ms) unless
``time_unit`` says it; all files must agree. Values follow Android: m/s^2, rad/s, uT; other
units are caught by the unit checks (``accel_unit="auto"`` converts g, ``gyro_unit="auto"``
deg/s, ``mag_unit="auto"`` gauss/nT, each with a note).

Orientation files hold Android's legacy ``TYPE_ORIENTATION`` angles in degrees: azimuth
(clockwise from magnetic north of the device y axis), pitch about x, roll about y. The
documented reading taken here is ``R_nd = Rz(-azimuth) Rx(-pitch) Ry(-roll)`` (ENU), i.e. pitch
positive when the z axis tilts toward +y and roll positive when the x axis tilts toward +z,
with azimuth/pitch/roll applied in that order; *unverified* on a real file. Every read tests
it against the accelerometer (and magnetometer) and picks the sign variant the data supports
(see :mod:`hrtls.io.readers._orientation`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path, PurePosixPath
from typing import Any, Literal

import numpy as np

from hrtls.data import ImuStream, OrientationSeries, SensorSeries, Session, SessionMeta
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError
from hrtls.frames import quat_multiply, quat_normalize
from hrtls.io.readers._orientation import choose_orientation, quat_axis
from hrtls.io.readers._text import (
    Quantity,
    check_stream,
    content_rows,
    decode_text,
    parse_float_rows,
    time_scale,
    to_si,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.units import DEG

__all__ = ["SensorKind", "read_android", "sensor_from_name"]

SensorKind = Literal["accelerometer", "gyroscope", "magnetometer", "orientation"]
_KINDS: tuple[SensorKind, ...] = ("accelerometer", "gyroscope", "magnetometer", "orientation")
_PREFIX: dict[str, SensorKind] = {"acc": "accelerometer", "gyr": "gyroscope",
                                  "mag": "magnetometer", "orient": "orientation"}
_NOT_SPECIFIC_FORCE = ("linear", "gravity", "lin")
_DATA_SUFFIXES = (".txt", ".csv", ".dat", ".log", "")


def _words(name: str) -> list[str]:
    """Lower-case words of a file name: split at non-letters and camel-case humps."""
    stem = PurePosixPath(name).name
    stem = re.sub(r"\.[A-Za-z0-9]{1,4}$", "", stem)
    spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", stem)
    return [w.lower() for w in re.split(r"[^A-Za-z]+", spaced) if w]


def sensor_from_name(name: str) -> SensorKind | None:
    """The sensor a file name points to (see the module docstring), or None.

    Raises
    ------
    FormatError
        When the name points to several sensors, or to linear acceleration / gravity.
    """
    words = _words(name)
    found = {kind for w in words for p, kind in _PREFIX.items() if w.startswith(p)}
    if "accelerometer" in found and any(w in _NOT_SPECIFIC_FORCE for w in words):
        raise FormatError("linear acceleration / gravity is not the specific force",
                          where=name, expected="the raw accelerometer (with gravity)")
    if len(found) > 1:
        raise FormatError(f"file name points to several sensors ({', '.join(sorted(found))})",
                          where=name, expected="one sensor per file, or sensors={file: kind}")
    return found.pop() if found else None


def _data_rows(text: str, where: str) -> tuple[list[str], np.ndarray, str | None]:
    """Data rows, their line numbers and the separator (a header line is skipped)."""
    rows, numbers = content_rows(text.splitlines(), comment_chars="#%")
    if not rows:
        raise FormatError("no data lines", where=where, expected="lines 'TIMESTAMP X Y Z'")
    sep = _separator(rows[0])
    try:
        [float(f) for f in _fields(rows[0], sep)]
    except ValueError:
        rows, numbers = rows[1:], numbers[1:]  # a header such as "TIMESTAMP X Y Z"
        if not rows:
            raise FormatError("only a header line", where=where,
                              expected="lines 'TIMESTAMP X Y Z'") from None
        sep = _separator(rows[0])
    return rows, numbers, sep


def _separator(line: str) -> str | None:
    for sep in (";", "\t", ","):
        if sep in line:
            return sep
    return None


def _fields(line: str, sep: str | None) -> list[str]:
    return line.split() if sep is None else line.split(sep)


def _read_file(src: Source, name: str) -> tuple[FloatArray, FloatArray, np.ndarray, str]:
    where = src.label(name)
    text = decode_text(src.read(name), where=where)
    rows, lines, sep = _data_rows(text, where)
    values = parse_float_rows(rows, sep=sep, usecols=(0, 1, 2, 3), line_numbers=lines,
                              where=where, field_names=("TIMESTAMP", "X", "Y", "Z"),
                              expected="TIMESTAMP X Y Z", exact_fields=4)
    return values[:, 0], values[:, 1:], lines, where


def _orientation_q(angles_deg: FloatArray, pitch_sign: float, roll_sign: float) -> FloatArray:
    """``q_nd = qz(-azimuth) qx(pitch_sign * pitch) qy(roll_sign * roll)``."""
    a = angles_deg * DEG
    q = quat_multiply(quat_axis("z", -a[:, 0]), quat_axis("x", pitch_sign * a[:, 1]))
    return quat_normalize(quat_multiply(q, quat_axis("y", roll_sign * a[:, 2])))


_RawFile = tuple[FloatArray, FloatArray, np.ndarray, str]
"""``(raw timestamps, values, line numbers, file label)`` of one sensor file."""


def _assign_sensors(src: Source, *, sensors: Mapping[str, str] | None
                    ) -> tuple[dict[str, str], list[str]]:
    """``({file: sensor}, files skipped)``: each file's sensor, from ``sensors`` or its name."""
    explicit = {PurePosixPath(k).name.lower(): v for k, v in (sensors or {}).items()}
    for name, given in explicit.items():
        if given not in _KINDS:
            raise InputError(f"unknown sensor {given!r} for {name}", where="sensors",
                             expected=f"one of {', '.join(_KINDS)}")
    assigned: dict[str, str] = {}
    skipped: list[str] = []
    for name in src.names:
        base = PurePosixPath(name).name
        kind: str | None = explicit.get(base.lower())
        if kind is None:
            if PurePosixPath(base).suffix.lower() not in _DATA_SUFFIXES:
                skipped.append(name)
                continue
            kind = sensor_from_name(name)
        if kind is None:
            if src.kind == "file":
                raise FormatError("cannot tell which sensor the file holds from its name",
                                  where=src.label(name),
                                  expected="a name with acc/accel/accelerometer, gyr/gyro/"
                                  "gyroscope, mag/magnetic/magnetometer or orientation",
                                  hint="rename it or pass sensors={'file': 'accelerometer'}")
            skipped.append(name)
            continue
        if kind in assigned.values():
            other = next(n for n, k in assigned.items() if k == kind)
            raise FormatError(f"two {kind} files ({other}, {name})", where=str(src.path),
                              expected="one file per sensor; pass sensors= to choose")
        assigned[name] = kind
    if "accelerometer" not in assigned.values():
        raise FormatError("no accelerometer file", where=str(src.path),
                          expected="a file named like acc*.txt / accelerometer*.txt with "
                          "'TIMESTAMP X Y Z' lines",
                          hint="pass sensors={'file': 'accelerometer'} if the name does not "
                          "say it" + (f"; files seen: {', '.join(skipped[:8])}" if skipped
                                      else ""))
    return assigned, skipped


def _common_time_scale(raw: dict[str, _RawFile], *, time_unit: str, where: str
                       ) -> tuple[float, str]:
    """``(seconds per tick, unit name)`` shared by all files; files that disagree raise."""
    units = {}
    for kind, (t_raw, _, _, file) in raw.items():
        units[kind] = time_scale(t_raw, time_unit, where=file)
    if len({u for _, u in units.values()}) > 1:
        listing = ", ".join(f"{k}: {u}" for k, (_, u) in units.items())
        raise FormatError(f"files disagree on the time unit ({listing})", where=where,
                          expected="one time unit for all sensors",
                          hint="pass time_unit='ms' or 'ns'")
    return next(iter(units.values()))


def _sensor_series(raw: dict[str, _RawFile], *, t0: float, scale_s: float, repair: bool,
                   units: Mapping[str, str], notes: list[str]
                   ) -> tuple[dict[str, SensorSeries], tuple[FloatArray, FloatArray] | None]:
    """Checked series in SI per sensor, and ``(t_s, angles_deg)`` of the orientation file.

    ``units`` maps accelerometer/gyroscope/magnetometer to their stated unit (or "auto").
    """
    series: dict[str, SensorSeries] = {}
    orient_raw: tuple[FloatArray, FloatArray] | None = None
    quantity: dict[str, Quantity] = {"accelerometer": "accel", "gyroscope": "gyro",
                                     "magnetometer": "mag"}
    for kind, (t_raw, values, lines, where) in raw.items():
        t = (t_raw - t0) * scale_s
        t, (v,) = check_stream(t, [values], lines=lines, where=where, repair=repair)
        if len(t) == 0:
            if kind == "accelerometer":
                raise FormatError("no valid samples left", where=where,
                                  expected="lines 'TIMESTAMP X Y Z' with finite numbers")
            notes.append(f"{where}: no valid samples, not used")
            continue
        if kind == "orientation":
            orient_raw = (t, v)
            continue
        v = to_si(v, quantity[kind], units[kind], where=Path(where).name, notes=notes)
        series[kind] = SensorSeries(t, v, Path(where).name)
    return series, orient_raw


def _legacy_orientation(t_s: FloatArray, angles_deg: FloatArray, *, name: str,
                        accel: SensorSeries, mag: SensorSeries | None, notes: list[str]
                        ) -> OrientationSeries:
    """``TYPE_ORIENTATION`` angles as ``q_nd``, with the pitch/roll signs the data support."""
    candidates = [(f"legacy TYPE_ORIENTATION, pitch {ps:+.0f}, roll {rs:+.0f}",
                   (lambda ps=ps, rs=rs: _orientation_q(angles_deg, ps, rs)))
                  for ps, rs in ((-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0))]
    _, q = choose_orientation(t_s, candidates, accel=accel, mag=mag, where=name, notes=notes)
    return OrientationSeries(t_s, q, name)


def read_android(path: Path | str, *, repair: bool = False, time_unit: str = "auto",
                 accel_unit: str = "auto", gyro_unit: str = "auto", mag_unit: str = "auto",
                 sensors: Mapping[str, str] | None = None,
                 check_units: bool = True, max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read Android per-sensor text files (a folder, a zip, or one file) into a session.

    Parameters
    ----------
    path:
        A folder or zip of per-sensor files, or one accelerometer file.
    repair:
        Drop non-finite rows, sort backward times and merge duplicated times with a
        :class:`~hrtls.errors.RepairWarning`; without it they raise :class:`InputError`
        naming the file line.
    time_unit:
        ``"auto"`` (guess from the sample spacing), ``"s"``, ``"ms"``, ``"us"`` or ``"ns"``.
    accel_unit, gyro_unit, mag_unit:
        ``"auto"`` (SI unless the values clearly are another unit) or a unit such as ``"g"``,
        ``"deg/s"``, ``"gauss"``.
    sensors:
        Explicit ``{file name: sensor}`` (sensor: accelerometer, gyroscope, magnetometer,
        orientation) for files whose names do not tell.
    check_units:
        Reject an IMU whose units still look wrong after conversion (g, deg/s, gauss ...)
        with a :class:`~hrtls.errors.UnitError`; False keeps such data as it is.
    max_bytes:
        Cap on the size read (zip: total uncompressed size).

    Raises
    ------
    FormatError, InputError, UnitError
        Naming the file, line and field that are wrong.
    """
    src = open_source(path, max_bytes=max_bytes)
    assigned, skipped = _assign_sensors(src, sensors=sensors)
    notes: list[str] = []
    raw: dict[str, _RawFile] = {}
    for name, kind in assigned.items():
        raw[kind] = _read_file(src, name)
    # one time unit for all files, and one origin
    scale, unit_name = _common_time_scale(raw, time_unit=time_unit, where=str(src.path))
    firsts = [float(np.nanmin(r[0])) for r in raw.values() if np.isfinite(r[0]).any()]
    t0 = min(firsts) if firsts else 0.0
    notes.append(f"timestamps in {unit_name} "
                 f"({'guessed from the sample spacing' if time_unit == 'auto' else 'stated'}),"
                 f" t = 0 at the first sample")
    time_origin = t0 * scale if 1e9 <= t0 * scale <= 4e9 else None
    series, orient_raw = _sensor_series(
        raw, t0=t0, scale_s=scale, repair=repair, notes=notes,
        units={"accelerometer": accel_unit, "gyroscope": gyro_unit, "magnetometer": mag_unit})
    accel = series["accelerometer"]
    imu = ImuStream(accel, series.get("gyroscope"), series.get("magnetometer"),
                    check_units=check_units)
    orientation = None
    if orient_raw is not None:
        orientation = _legacy_orientation(*orient_raw, name=Path(raw["orientation"][3]).name,
                                          accel=accel, mag=imu.mag, notes=notes)
    source: dict[str, Any] = {"format": "android", "files": [src.label(n) for n in assigned],
                              "sensors": {src.label(n): k for n, k in assigned.items()},
                              "time_unit": unit_name}
    if skipped:
        notes.append(f"files not used: {', '.join(skipped)}")
    meta = SessionMeta(source=source, notes=notes, time_origin_unix_s=time_origin)
    return Session(meta=meta, imu=imu, orientation=orientation)
