"""Sensor Logger (the iOS/Android app by Kelvin Choi) CSV export, a folder or zip -> Session.

An export holds one CSV per sensor with a header line; ``time`` is Unix time in ns and
``seconds_elapsed`` the time since the recording started. Files read (names without case):

======================== ==================================== ===================================
file                     columns used                          becomes
======================== ==================================== ===================================
``TotalAcceleration.csv`` ``time, x, y, z`` (m/s^2, incl. g)    accelerometer (preferred)
``Accelerometer.csv``    ``time, x, y, z`` (m/s^2, without g)  accelerometer, + ``Gravity.csv``
``Gravity.csv``          ``time, x, y, z`` (m/s^2)             added to ``Accelerometer.csv``
``Gyroscope.csv``        ``time, x, y, z`` (rad/s)             gyroscope
``Magnetometer.csv``     ``time, x, y, z`` (uT)                magnetometer
``Barometer.csv``        ``time, pressure`` (hPa)              pressure, converted to Pa
``Orientation.csv``      ``time, qw, qx, qy, qz``              orientation ``q_nd`` (see below)
``Metadata.csv``         ``platform, standardisation, ...``    platform and unit conventions
======================== ==================================== ===================================

The columns are found by name, so the app's ``z,y,x`` order does not matter. Time is
``(time - first time) * 1e-9`` s over all files; ``meta.time_origin_unix_s`` is the first time.

Acceleration. ``TotalAcceleration.csv`` (Android) is the specific force. Otherwise
``Accelerometer.csv`` (user acceleration) plus ``Gravity.csv`` (gravity interpolated onto the
accelerometer's times when they differ) is. The app's documentation (``COORDINATES.md`` of
*awesome-sensor-logger*) states that iOS reports acceleration and gravity with the opposite sign
of Android, unless "Standardise Units & Frames" is on (``standardisation`` in
``Metadata.csv``); such iOS exports are negated. Exports in g (some iOS settings) are caught by
the unit check (``accel_unit="auto"`` converts them, with a note).

Orientation. Documented reading, *unverified*: on Android the quaternion is that of the
rotation-vector sensor, device -> east-north-up, so it is ``q_nd`` as is; on iOS it is Core
Motion's attitude, device -> (x north, y west, z up), so ``q_nd = q_z(+90 deg) * q``. The reading
is tested against the recording (gravity must point up, the field north) and, when the data
contradict it, the convention the data support is used and the notes say so
(:mod:`hrtls.io.readers._orientation`). ``orientation="enu"|"nwu"|"ned"`` (optionally with
``"-inverse"``) forces a reading; ``"none"`` skips the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hrtls.data import ImuStream, OrientationSeries, SensorSeries, Session, SessionMeta
from hrtls.data.validation import FloatArray
from hrtls.errors import FormatError, InputError
from hrtls.io.readers._orientation import FRAME_TO_ENU, choose_orientation, reference_to_enu
from hrtls.io.readers._text import (
    HeaderCsv,
    IntArray,
    Quantity,
    check_stream,
    csv_rows,
    decode_text,
    read_header_csv,
    to_si,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.units import G_TO_M_S2, HPA_TO_PA

__all__ = ["SENSOR_LOGGER_FILES", "read_sensorlogger"]

SENSOR_LOGGER_FILES = ("TotalAcceleration.csv", "Accelerometer.csv", "Gravity.csv",
                       "Gyroscope.csv", "Magnetometer.csv", "Barometer.csv", "Orientation.csv",
                       "Metadata.csv")
"""Files of an export that the reader uses."""

_XYZ = ("x", "y", "z")
_ORIENTATION_CHOICES = ("auto", "none", *FRAME_TO_ENU, *(f"{f}-inverse" for f in FRAME_TO_ENU))


class _Reader:
    """Reads the export's CSVs with one shared time origin."""

    def __init__(self, src: Source):
        self.src = src
        self.tables: dict[str, HeaderCsv] = {}
        for base in SENSOR_LOGGER_FILES[:-1]:
            name = src.find(base)
            if name is not None:
                self.tables[base] = read_header_csv(src.read(name), where=src.label(name))
        self.use_ns = all(t.index("time") is not None for t in self.tables.values())
        if not self.use_ns:
            for t in self.tables.values():
                t.require("seconds_elapsed")
        firsts = [self._first_time(t) for t in self.tables.values() if t.rows]
        finite = [f for f in firsts if np.isfinite(f)]
        self.t0 = min(finite) if finite else 0.0

    def _first_time(self, table: HeaderCsv) -> float:
        col = "time" if self.use_ns else "seconds_elapsed"
        head = HeaderCsv(table.where, table.header, table.rows[:1], table.lines[:1], table.sep,
                         table.decimal_comma)
        return float(head.floats([col])[0, 0])

    def read(self, base: str, columns: tuple[str, ...]
             ) -> tuple[FloatArray, FloatArray, IntArray, str] | None:
        """Raw ``(t_s, values, lines, where)`` of a file, or None when it is absent/empty."""
        table = self.tables.get(base)
        if table is None or not table.rows:
            return None
        col = "time" if self.use_ns else "seconds_elapsed"
        vals = table.floats([col, *columns])
        scale = 1e-9 if self.use_ns else 1.0
        return (vals[:, 0] - self.t0) * scale, vals[:, 1:], table.lines, table.where


def _reading_name(frame: str, inverse: bool) -> str:
    """E.g. ``"nwu: device->NWU"`` or ``"enu-inverse: ENU->device"``."""
    if inverse:
        return f"{frame}-inverse: {frame.upper()}->device"
    return f"{frame}: device->{frame.upper()}"


def _metadata(src: Source) -> dict[str, str]:
    name = src.find("Metadata.csv")
    if name is None:
        return {}
    text = decode_text(src.read(name), where=src.label(name))
    rows = [r for r in csv_rows(text, where=src.label(name)) if r]
    if len(rows) < 2:
        return {}
    return {k.strip().lower(): v.strip() for k, v in zip(rows[0], rows[1], strict=False)}


def _stream(reader: _Reader, base: str, columns: tuple[str, ...], *, repair: bool
            ) -> tuple[FloatArray, FloatArray, str] | None:
    raw = reader.read(base, columns)
    if raw is None:
        return None
    t, v, lines, where = raw
    t, (v,) = check_stream(t, [v], lines=lines, where=where, repair=repair)
    if len(t) == 0:
        return None
    return t, v, where


def _resolve_platform(platform: str, *, meta_row: dict[str, str], has_total: bool,
                      notes: list[str]) -> str:
    """The platform whose conventions apply: the stated one, else from the export."""
    if platform != "auto":
        return platform
    standardised = meta_row.get("standardisation", "").lower() == "true"
    found = meta_row.get("platform", "").lower()
    if found in ("ios", "android"):
        platform = "ios-standardised" if found == "ios" and standardised else found
        notes.append(f"platform {platform} (Metadata.csv)")
    elif has_total:
        platform = "android"
        notes.append("platform android (TotalAcceleration.csv present; no Metadata.csv)")
    else:
        platform = "android"
        notes.append("platform unknown (no Metadata.csv): Android sign conventions "
                     "assumed, unverified; pass platform='ios' for an iPhone export")
    return platform


def _user_plus_gravity(t_a: FloatArray, user_acc: FloatArray,
                       grav: tuple[FloatArray, FloatArray, str], *, notes: list[str]
                       ) -> FloatArray:
    """``Accelerometer.csv + Gravity.csv``, gravity interpolated when the times differ."""
    t_g, g, _ = grav
    if len(t_g) == len(t_a) and np.array_equal(t_g, t_a):
        notes.append("accelerometer = Accelerometer.csv + Gravity.csv")
        return user_acc + g
    g_i = np.column_stack([np.interp(t_a, t_g, g[:, k]) for k in range(3)])
    notes.append("accelerometer = Accelerometer.csv + Gravity.csv (gravity "
                 "interpolated onto the accelerometer's times)")
    return user_acc + g_i


def _require_gravity_included(acc: FloatArray, *, where: str, notes: list[str]) -> None:
    """Accept ``Accelerometer.csv`` alone only when its median norm is about 1 g."""
    norm = float(np.median(np.linalg.norm(acc, axis=1))) if len(acc) else 0.0
    near_g = 0.7 * G_TO_M_S2 <= norm <= 1.3 * G_TO_M_S2 or 0.7 <= norm <= 1.3
    if not near_g:
        raise FormatError(
            f"Accelerometer.csv holds acceleration without gravity (median |a| = "
            f"{norm:.3g}) and there is no Gravity.csv or TotalAcceleration.csv",
            where=where, expected="the specific force (with gravity)",
            hint="enable Gravity or Total Acceleration in the app")
    notes.append(f"accelerometer = Accelerometer.csv, which includes gravity "
                 f"(median |a| = {norm:.3g})")


def _specific_force(reader: _Reader, *, flip: bool, repair: bool, notes: list[str]
                    ) -> tuple[FloatArray, FloatArray, str]:
    """``(t_s, specific force, file)`` from the acceleration files (see the module docstring)."""
    total = _stream(reader, "TotalAcceleration.csv", _XYZ, repair=repair)
    if total is not None:
        notes.append("accelerometer = TotalAcceleration.csv (specific force incl. gravity)")
        return total
    user = _stream(reader, "Accelerometer.csv", _XYZ, repair=repair)
    grav = _stream(reader, "Gravity.csv", _XYZ, repair=repair)
    if user is None:
        raise FormatError("no samples in TotalAcceleration.csv or Accelerometer.csv",
                          where=str(reader.src.path),
                          expected="a Sensor Logger export with accelerometer data")
    t_a, acc, where_a = user
    if grav is not None:
        acc = _user_plus_gravity(t_a, acc, grav, notes=notes)
    else:
        _require_gravity_included(acc, where=where_a, notes=notes)
    if flip:
        acc = -acc
        notes.append("iOS acceleration negated to the specific-force convention (iOS "
                     "reports it with the opposite sign of Android)")
    return t_a, acc, where_a


def _orientation_series(reader: _Reader, *, orientation: str, platform: str,
                        accel: SensorSeries, mag: SensorSeries | None, repair: bool,
                        notes: list[str]) -> OrientationSeries | None:
    """``q_nd`` from ``Orientation.csv`` in the reading the data support, or None."""
    ori = None if orientation == "none" else _stream(
        reader, "Orientation.csv", ("qw", "qx", "qy", "qz"), repair=repair)
    if ori is None:
        return None
    t_o, q_raw, where = ori
    norms = np.linalg.norm(q_raw, axis=1)
    if np.any(norms < 1e-6):
        i = int(np.flatnonzero(norms < 1e-6)[0])
        raise InputError("zero quaternion", where=f"{where} line "
                         f"{int(reader.tables['Orientation.csv'].lines[i])}",
                         expected="unit quaternions qw,qx,qy,qz")
    q_raw = q_raw / norms[:, None]
    if orientation == "auto":
        first = "nwu" if platform.startswith("ios") else "enu"
        order = [first] + [f for f in FRAME_TO_ENU if f != first]
        names = [(f, False) for f in order] + [(f, True) for f in order]
    else:
        frame, _, inv = orientation.partition("-")
        names = [(frame, bool(inv))]
    candidates = [(_reading_name(f, inv),
                   (lambda f=f, inv=inv: reference_to_enu(q_raw, f, inverse=inv)))
                  for f, inv in names]
    _, q_nd = choose_orientation(t_o, candidates, accel=accel, mag=mag,
                                 where="Orientation.csv", notes=notes,
                                 verify_only=orientation != "auto")
    return OrientationSeries(t_o, q_nd, "Orientation.csv")


def _imu_series(reader: _Reader, base: str, quantity: Quantity, unit: str, *, repair: bool,
                notes: list[str]) -> SensorSeries | None:
    """An x/y/z sensor file as a series in SI units, or None when absent/empty."""
    found = _stream(reader, base, _XYZ, repair=repair)
    if found is None:
        return None
    return SensorSeries(found[0], to_si(found[1], quantity, unit, where=base, notes=notes), base)


def read_sensorlogger(path: Path | str, *, repair: bool = False, platform: str = "auto",
                      accel_unit: str = "auto", gyro_unit: str = "auto",
                      mag_unit: str = "auto", orientation: str = "auto",
                      check_units: bool = True, max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read a Sensor Logger export (folder or zip) into a session.

    Parameters
    ----------
    path:
        The export folder or zip (files at its root or in one sub-folder).
    repair:
        Drop non-finite rows, sort backward times and merge duplicated times with a
        :class:`~hrtls.errors.RepairWarning`; without it they raise :class:`InputError`
        naming the file line.
    platform:
        ``"auto"`` (from ``Metadata.csv``; else Android when ``TotalAcceleration.csv``
        exists), ``"android"``, ``"ios"`` or ``"ios-standardised"``.
    accel_unit, gyro_unit, mag_unit:
        ``"auto"`` (SI unless the values clearly are another unit) or a stated unit.
    orientation:
        ``"auto"`` (documented reading, checked against the data), a forced reading
        (``"enu"``, ``"nwu"``, ``"ned"``, optionally ``"-inverse"``), or ``"none"``.
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
    if platform not in ("auto", "android", "ios", "ios-standardised"):
        raise InputError(f"platform {platform!r}", where="platform",
                         expected="auto, android, ios or ios-standardised")
    if orientation not in _ORIENTATION_CHOICES:
        raise InputError(f"orientation {orientation!r}", where="orientation",
                         expected=f"one of {', '.join(_ORIENTATION_CHOICES)}")
    src = open_source(path, max_bytes=max_bytes)
    reader = _Reader(src)
    if not reader.tables:
        raise FormatError("no Sensor Logger files", where=str(src.path),
                          expected=f"some of {', '.join(SENSOR_LOGGER_FILES)}")
    notes: list[str] = []
    meta_row = _metadata(src)
    platform = _resolve_platform(platform, meta_row=meta_row,
                                 has_total="TotalAcceleration.csv" in reader.tables, notes=notes)
    t_a, acc, where_a = _specific_force(reader, flip=platform == "ios", repair=repair,
                                        notes=notes)
    acc = to_si(acc, "accel", accel_unit, where=Path(where_a).name, notes=notes)
    accel = SensorSeries(t_a, acc, Path(where_a).name)
    gyro = _imu_series(reader, "Gyroscope.csv", "gyro", gyro_unit, repair=repair, notes=notes)
    mag = _imu_series(reader, "Magnetometer.csv", "mag", mag_unit, repair=repair, notes=notes)
    imu = ImuStream(accel, gyro, mag, check_units=check_units)
    pressure = None
    bar = _stream(reader, "Barometer.csv", ("pressure",), repair=repair)
    if bar is not None:
        pressure = SensorSeries(bar[0], bar[1] * HPA_TO_PA, "Barometer.csv")
        notes.append("Barometer.csv pressure converted from hPa to Pa")
    orient = _orientation_series(reader, orientation=orientation, platform=platform,
                                 accel=accel, mag=mag, repair=repair, notes=notes)
    source: dict[str, Any] = {"format": "sensorlogger",
                              "files": [t.where for t in reader.tables.values()],
                              "platform": platform}
    if meta_row:
        source["metadata"] = {k: v for k, v in meta_row.items() if k != "device id"}
    origin = reader.t0 * 1e-9 if reader.use_ns and 1e9 <= reader.t0 * 1e-9 <= 4e9 else None
    if not reader.use_ns:
        notes.append("no 'time' column: seconds_elapsed used, absolute time unknown")
    meta = SessionMeta(source=source, notes=notes, time_origin_unix_s=origin)
    return Session(meta=meta, imu=imu, pressure=pressure, orientation=orient)
