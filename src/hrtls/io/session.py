"""Read and write the session folder (or a zip of it), the canonical interchange format.

Files (all optional; SI units; a header line each) — see ``docs/architecture.md``:

=================== ===================================== =========================================
file                columns                               meaning
=================== ===================================== =========================================
``imu.csv``         ``t,ax,ay,az[,gx,gy,gz][,mx,my,mz]``  device-frame specific force (m/s^2),
                                                          angular rate (rad/s), field (uT)
``gyro.csv``        ``t,gx,gy,gz``                        gyroscope with its own timestamps
``mag.csv``         ``t,mx,my,mz``                        magnetometer with its own timestamps
``pressure.csv``    ``t,pressure_pa``                     barometer, Pa
``orientation.csv`` ``t,qw,qx,qy,qz``                     orientation computed by the device, q_nd
``fixes.csv``       ``t,x,y[,z],sigma``                   position fixes, m
``rss.csv``         ``t,anchor,rss_dbm``                  beacon RSS, dBm
``tags.csv``        ``t,tag``                             passive tag reads
``ranges.csv``      ``t,node,range[,sigma]``              ranges to radio nodes, m
``landmarks.json``  list of location messages             see :class:`hrtls.data.Landmark`
``session.json``    object                                see :class:`hrtls.data.SessionMeta`
``truth.csv``       ``t,x,y,z[,heading]``                 ground-truth trajectory
``checkpoints.csv`` ``t,x,y,z[,label]``                   ground truth at known points
=================== ===================================== =========================================

A zip is read member by member in memory: nothing is extracted, members with absolute paths or
``..`` are refused, and the total uncompressed size is capped (``max_bytes``).
"""

from __future__ import annotations

import json
import re
import warnings
import zipfile
from collections.abc import Mapping
from pathlib import Path, PurePosixPath
from typing import Any, Literal, Protocol

import numpy as np
import pyarrow as pa
from pydantic import ValidationError

from hrtls.data import (
    Checkpoints,
    GroundTruth,
    ImuStream,
    Landmark,
    OrientationSeries,
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    SensorSeries,
    Session,
    SessionMeta,
    TagDetections,
)
from hrtls.data.validation import FloatArray, drop_non_finite, repair_time_order
from hrtls.errors import DegradedInputWarning, FormatError, InputError
from hrtls.io.csvtable import Table, without_cut_last_line
from hrtls.io.schema import SESSION_TABLES, TABLE_SUFFIXES
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source
from hrtls.io.tables import decode_table, encode_table, from_arrow, to_arrow

SESSION_FILES = (*(stem + suffix for suffix in TABLE_SUFFIXES for stem in SESSION_TABLES),
                 "landmarks.json", "session.json")
"""Every file a session may hold: each table as ``.csv`` or ``.parquet``, and the JSON files."""

RESULT_FILES = ("trajectory.csv", "steps.csv", "trajectory.parquet", "steps.parquet",
                "trajectory.geojson", "report.json")
"""Outputs that may sit beside a session without being part of it."""

TableFormat = Literal["csv", "parquet"]
"""How a session's tables are written: ``csv`` (interchange) or ``parquet`` (typed, LZ4)."""

_AXES = ("x", "y", "z")


class _Tables(Protocol):
    """Where a session's tables come from: files, or Arrow tables in memory."""

    label: str

    def table(self, stem: str) -> tuple[Table, str] | None:
        """The checked table ``stem`` and its name for messages (None when absent)."""


class _SessionFiles:
    """The session files of a folder or zip, read as bytes by their base name."""

    def __init__(self, source: Source, *, repair: bool = False):
        self.repair = repair
        by_dir: dict[str, list[str]] = {}
        for name in source.names:
            pure = PurePosixPath(name)
            by_dir.setdefault(str(pure.parent), []).append(name)
        # the folder holding the session files: the root, or a single sub-folder (a zip of it)
        holders = [d for d, names in by_dir.items()
                   if {PurePosixPath(n).name for n in names} & set(SESSION_FILES)]
        if len(holders) > 1 and "." in holders:
            holders = ["."]
        if len(holders) != 1:
            raise FormatError(
                "no session files found" if not holders else
                f"session files in several folders ({', '.join(sorted(holders))})",
                where=str(source.path),
                expected="one folder with imu.csv, fixes.csv, ... (or a zip of it)")
        self._members = {PurePosixPath(n).name: n for n in by_dir[holders[0]]}
        self._source = source
        self.names = set(self._members)
        self.label = str(source.path)

    def read(self, name: str) -> bytes:
        return self._source.read(self._members[name])

    def member(self, name: str) -> str:
        """The source member holding session file ``name``."""
        return self._members[name]

    def table(self, stem: str) -> tuple[Table, str] | None:
        found = [stem + suffix for suffix in TABLE_SUFFIXES if stem + suffix in self.names]
        if not found:
            return None
        if len(found) > 1:
            raise FormatError(f"both {' and '.join(found)}", where=self.label,
                              expected=f"one {stem} table")
        name = found[0]
        data = self._source.buffer(self._members[name])
        if name.endswith(".csv"):
            data = without_cut_last_line(data, name=name, repair=self.repair)
        try:
            return decode_table(data, table=stem, name=name,
                                missing_as_nan=self.repair and stem in _SENSOR_TABLES), name
        except FormatError as exc:
            missing = re.search(r" is (''|nan|missing)$", exc.problem, flags=re.IGNORECASE)
            if stem not in _SENSOR_TABLES or self.repair or exc.hint or missing is None:
                raise
            raise FormatError(exc.problem, where=exc.where, expected=exc.expected,
                              hint="pass repair=True to drop such rows with a warning") from None


_SENSOR_TABLES = frozenset({"imu", "gyro", "mag", "pressure", "orientation"})
"""Tables whose rows with a missing value ``repair`` drops (:func:`drop_non_finite`)."""


class _ArrowTables:
    """Arrow tables in memory, by table name (see :func:`session_from_tables`)."""

    def __init__(self, tables: Mapping[str, pa.Table]):
        unknown = [k for k in tables if k not in SESSION_TABLES]
        if unknown:
            raise FormatError(f"unknown table(s) {', '.join(unknown)}", where="session tables",
                              expected=f"tables among {', '.join(SESSION_TABLES)}")
        self._tables = tables
        self.label = "session tables"

    def table(self, stem: str) -> tuple[Table, str] | None:
        if stem not in self._tables:
            return None
        return from_arrow(self._tables[stem], table=stem, name=stem), stem


def _group(table: Table, cols: tuple[str, ...], *, name: str) -> FloatArray | None:
    present = [c in table.present for c in cols]
    if not any(present):
        return None
    if not all(present):
        missing = [c for c, p in zip(cols, present, strict=True) if not p]
        raise FormatError(f"incomplete column group, missing {', '.join(missing)}",
                          where=f"{name} line 1", expected=f"all of {','.join(cols)} or none")
    return table.matrix(cols)


def _repaired(t: FloatArray, groups: list[FloatArray], *, name: str, repair: bool,
              strict: bool = True) -> tuple[FloatArray, list[FloatArray]]:
    if not repair:
        return t, groups
    t, groups = drop_non_finite(t, groups, where=name)
    return repair_time_order(t, groups, where=name, strict=strict)


def _not_empty(found: tuple[Table, str], what: str) -> tuple[Table, str]:
    """A sensor table with rows; one with a header only is refused (it is not "no sensor")."""
    table, name = found
    if table.n_rows == 0:
        raise FormatError("no rows after the header", where=f"{name} line 2",
                          expected=f"{what} samples (or no such file at all)")
    return table, name


def _read_vector_file(src: _Tables, stem: str, prefix: str, *, repair: bool
                      ) -> SensorSeries | None:
    found = src.table(stem)
    if found is None:
        return None
    table, name = _not_empty(found, {"gyro": "gyroscope", "mag": "magnetometer"}[stem])
    group = _group(table, tuple(prefix + a for a in _AXES), name=name)
    assert group is not None
    t, (values,) = _repaired(table.float("t"), [group], name=name, repair=repair)
    return SensorSeries(t, values, name)


def _read_imu(src: _Tables, *, repair: bool, check_units: bool) -> ImuStream | None:
    found = src.table("imu")
    gyro_file = _read_vector_file(src, "gyro", "g", repair=repair)
    mag_file = _read_vector_file(src, "mag", "m", repair=repair)
    if found is None:
        if gyro_file is not None or mag_file is not None:
            raise FormatError("gyro or mag table without an imu table", where=src.label,
                              expected="imu.csv (or imu.parquet) with the accelerometer")
        return None
    table, name = _not_empty(found, "accelerometer")
    acc = _group(table, tuple("a" + a for a in _AXES), name=name)
    gyr = _group(table, tuple("g" + a for a in _AXES), name=name)
    mag = _group(table, tuple("m" + a for a in _AXES), name=name)
    for inline, separate, label in ((gyr, gyro_file, "gyro"), (mag, mag_file, "mag")):
        if inline is not None and separate is not None:
            raise FormatError(f"both {name} columns and {separate.name}", where=src.label,
                              expected=f"the sensor in one place only: {name} or {label}")
    assert acc is not None
    groups = [g for g in (acc, gyr, mag) if g is not None]
    t, groups = _repaired(table.float("t"), groups, name=name, repair=repair)
    it = iter(groups)
    acc_v = next(it)
    gyr_v = next(it) if gyr is not None else None
    mag_v = next(it) if mag is not None else None
    return ImuStream(
        SensorSeries(t, acc_v, f"{name} accelerometer"),
        gyro_file if gyr_v is None else SensorSeries(t, gyr_v, f"{name} gyroscope"),
        mag_file if mag_v is None else SensorSeries(t, mag_v, f"{name} magnetometer"),
        check_units=check_units,
    )


def _read_landmarks(src: _SessionFiles) -> dict[str, Landmark]:
    if "landmarks.json" not in src.names:
        return {}
    return landmarks_from_json(_json(src, "landmarks.json"), where="landmarks.json")


def landmark_list(items: Any, *, where: str) -> list[Landmark]:
    """The location messages of a parsed JSON list (``where``: its name in errors)."""
    if not isinstance(items, list):
        raise FormatError(f"top level is {type(items).__name__}", where=where,
                          expected="a JSON list of location messages")
    out = []
    for i, item in enumerate(items):
        try:
            out.append(Landmark.model_validate(item))
        except ValidationError as exc:
            raise FormatError(pydantic_problem(exc), where=f"{where} item {i}",
                              expected="a location message (id, kind, position or wgs84, ...)"
                              ) from None
    return out


def landmarks_from_json(items: Any, *, where: str) -> dict[str, Landmark]:
    """The location messages of a parsed ``landmarks.json`` by id (ids unique)."""
    out: dict[str, Landmark] = {}
    for i, landmark in enumerate(landmark_list(items, where=where)):
        if landmark.id in out:
            raise FormatError(f"duplicate id {landmark.id!r}", where=f"{where} item {i}",
                              expected="unique landmark ids")
        out[landmark.id] = landmark
    return out


def pydantic_problem(exc: ValidationError) -> str:
    """The first problem of a pydantic validation error, naming its field."""
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"]) or "(object)"
    return f"field {loc!r}: {err['msg']}"


def _json(src: _SessionFiles, name: str) -> Any:
    try:
        return json.loads(src.read(name).decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise FormatError("not UTF-8 text", where=name, expected="a UTF-8 JSON file") from None
    except json.JSONDecodeError as exc:
        raise FormatError(exc.msg, where=f"{name} line {exc.lineno} column {exc.colno}",
                          expected="valid JSON") from None


def _read_meta(src: _SessionFiles) -> SessionMeta:
    if "session.json" not in src.names:
        warnings.warn(f"{src.label}: no session.json: no start pose, georeference, placement, "
                      "floor height or channel model; the defaults are used",
                      DegradedInputWarning, stacklevel=3)
        return SessionMeta()
    data = _json(src, "session.json")
    if not isinstance(data, dict):
        raise FormatError(f"top level is {type(data).__name__}", where="session.json",
                          expected="a JSON object")
    try:
        return SessionMeta.model_validate(data)
    except ValidationError as exc:
        raise FormatError(pydantic_problem(exc), where="session.json",
                          expected="the session.json schema (docs/architecture.md)") from None


def is_session(path: Path) -> bool:
    """True when ``path`` is a folder or zip holding at least one session file."""
    path = Path(path)
    if path.is_dir():
        return any((path / n).is_file() for n in SESSION_FILES)
    if path.suffix.lower() == ".zip" and zipfile.is_zipfile(path):
        try:
            _SessionFiles(open_source(path))
        except (FormatError, InputError):
            return False
        return True
    return False


def read_session(path: Path | str, *, repair: bool = False, check_units: bool = True,
                 max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read a session folder or zip.

    Parameters
    ----------
    path:
        The folder, or a ``.zip`` of it (files at the root or in one folder).
    repair:
        Drop non-finite rows, sort backward times and merge duplicated times, each with a
        :class:`~hrtls.errors.RepairWarning`. Without it such files raise an error.
    check_units:
        Reject accelerometers in g, gyroscopes in deg/s, magnetometers in gauss/nT.
    max_bytes:
        Cap on the total uncompressed size of a zip.

    Raises
    ------
    FormatError, InputError
        Naming the file, line and field that are wrong.
    """
    path = Path(path)
    src = _SessionFiles(open_source(path, max_bytes=max_bytes), repair=repair)
    try:
        return _assemble(src, _read_meta(src), _read_landmarks(src), repair=repair,
                         check_units=check_units)
    except InputError as exc:
        if str(path) not in exc.where and exc.where:
            raise type(exc)(exc.problem, where=f"{path}/{exc.where}", expected=exc.expected,
                            hint=exc.hint) from None
        raise


def session_from_tables(tables: Mapping[str, pa.Table], *, meta: SessionMeta | None = None,
                        landmarks: Mapping[str, Landmark] | None = None, repair: bool = False,
                        check_units: bool = True) -> Session:
    """A session from Arrow tables by name (``imu``, ``rss``, ...; see :func:`session_tables`).

    The tables are checked as the files of a session folder are (messages name ``imu row N``).
    """
    return _assemble(_ArrowTables(tables), meta or SessionMeta(), dict(landmarks or {}),
                     repair=repair, check_units=check_units)


def _assemble(src: _Tables, meta: SessionMeta, landmarks: dict[str, Landmark], *, repair: bool,
              check_units: bool) -> Session:
    imu = _read_imu(src, repair=repair, check_units=check_units)
    session = Session(meta=meta, imu=imu, landmarks=landmarks, **other_parts(src, repair=repair))
    for label, ids in session.unknown_ids().items():
        shown = ", ".join(ids[:5]) + (" ..." if len(ids) > 5 else "")
        warnings.warn(f"{label}: {len(ids)} id(s) not in landmarks.json ({shown}); "
                      "their readings cannot be placed", DegradedInputWarning, stacklevel=3)
    return session


def truth_from(table: Table, name: str, *, repair: bool = False) -> GroundTruth:
    """The ground truth of a checked ``truth`` table."""
    xyz = _group(table, ("x", "y", "z"), name=name)
    assert xyz is not None
    groups = [xyz] + ([table.float("heading")] if "heading" in table.present else [])
    t, groups = _repaired(table.float("t"), groups, name=name, repair=repair)
    return GroundTruth(t, groups[0], groups[1] if len(groups) > 1 else None, name)


def other_parts(src: _Tables, *, repair: bool, skip: frozenset[str] = frozenset()
                ) -> dict[str, Any]:
    """Every part of the session but the IMU (and ``skip``), by Session field name."""
    pressure = None
    if (found := src.table("pressure")) is not None:
        table, name = found
        t, (p,) = _repaired(table.float("t"), [table.float("pressure_pa")], name=name,
                            repair=repair)
        pressure = SensorSeries(t, p, name)
    orientation = None
    if (found := src.table("orientation")) is not None:
        table, name = _not_empty(found, "orientation")
        q = _group(table, ("qw", "qx", "qy", "qz"), name=name)
        assert q is not None
        t, (q,) = _repaired(table.float("t"), [q], name=name, repair=repair)
        orientation = OrientationSeries(t, q, name)
    fixes = _read_fixes(src, repair=repair)
    rss_obj = None
    if (rss := _read_obs(src, "rss", repair=repair)) is not None:
        rss_obj = RssReadings(rss["t"], rss["anchor"], rss["rss_dbm"], rss["name"])
    tags_obj = None
    if (tags := _read_obs(src, "tags", repair=repair)) is not None:
        tags_obj = TagDetections(tags["t"], tags["tag"], tags["name"])
    ranges_obj = None
    if (ranges := _read_obs(src, "ranges", repair=repair)) is not None:
        ranges_obj = RangeMeasurements(
            ranges["t"], ranges["node"], ranges["range"],
            ranges.get("sigma", np.full(len(ranges["t"]), np.nan)), ranges["name"])
    truth = None
    if "truth" not in skip and (found := src.table("truth")) is not None:
        truth = truth_from(*found, repair=repair)
    checkpoints = None
    if (cp := _read_obs(src, "checkpoints", repair=repair)) is not None:
        labels = cp.get("label", np.full(len(cp["t"]), "", dtype=np.str_))
        checkpoints = Checkpoints(cp["t"], np.column_stack([cp["x"], cp["y"], cp["z"]]), labels,
                                  cp["name"])
    return {"pressure": pressure, "orientation": orientation, "fixes": fixes, "rss": rss_obj,
            "tags": tags_obj, "ranges": ranges_obj, "truth": truth, "checkpoints": checkpoints}


def _read_fixes(src: _Tables, *, repair: bool) -> PositionFixes | None:
    found = src.table("fixes")
    if found is None:
        return None
    table, name = found
    has_z = "z" in table.present
    z = table.float("z") if has_z else np.zeros(table.n_rows)
    xyz = np.column_stack([table.float("x"), table.float("y"), z])
    t, (xyz, sigma) = _repaired(table.float("t"), [xyz, table.float("sigma")], name=name,
                                repair=repair, strict=False)
    return PositionFixes(t, xyz, sigma, has_z, name)


def _read_obs(src: _Tables, stem: str, *, repair: bool) -> dict[str, Any] | None:
    """Observation table as a dict of columns (time non-decreasing, sorted with ``repair``).

    ``"name"`` holds the table's name for messages.
    """
    found = src.table(stem)
    if found is None:
        return None
    table, name = found
    cols: dict[str, Any] = {c: table.column(c) for c in table.present}
    t = table.float("t")
    if repair and len(t) > 1 and np.any(np.diff(t) < 0):
        others = [c for c in table.present if c != "t"]
        t, moved = repair_time_order(t, [np.asarray(cols[c]) for c in others], where=name,
                                     strict=False)
        cols = dict(zip(others, moved, strict=True))
    cols["t"] = t
    cols["name"] = name
    return cols


# ------------------------------------------------------------------------------------------------
# Writing
# ------------------------------------------------------------------------------------------------
def session_columns(session: Session) -> dict[str, dict[str, np.ndarray]]:
    """The columns of each of the session's tables, by table name (``imu``, ``rss``, ...)."""
    out: dict[str, dict[str, np.ndarray]] = {}
    imu = session.imu
    if imu is not None:
        cols: dict[str, np.ndarray] = {"t": imu.accel.t}
        cols.update({"a" + a: imu.accel.values[:, i] for i, a in enumerate(_AXES)})
        for series, prefix, separate in ((imu.gyro, "g", "gyro"), (imu.mag, "m", "mag")):
            if series is None:
                continue
            if imu.shares_time(series):
                cols.update({prefix + a: series.values[:, i] for i, a in enumerate(_AXES)})
            else:
                own = {"t": series.t}
                own.update({prefix + a: series.values[:, i] for i, a in enumerate(_AXES)})
                out[separate] = own
        out["imu"] = cols
    if session.pressure is not None:
        out["pressure"] = {"t": session.pressure.t, "pressure_pa": session.pressure.values[:, 0]}
    if session.orientation is not None:
        q = session.orientation.q
        out["orientation"] = {"t": session.orientation.t, "qw": q[:, 0], "qx": q[:, 1],
                              "qy": q[:, 2], "qz": q[:, 3]}
    if session.fixes is not None:
        f = session.fixes
        cols = {"t": f.t, "x": f.xyz[:, 0], "y": f.xyz[:, 1]}
        if f.has_z:
            cols["z"] = f.xyz[:, 2]
        cols["sigma"] = f.sigma_m
        out["fixes"] = cols
    if session.rss is not None:
        out["rss"] = {"t": session.rss.t, "anchor": session.rss.anchor,
                      "rss_dbm": session.rss.rss_dbm}
    if session.tags is not None:
        out["tags"] = {"t": session.tags.t, "tag": session.tags.tag}
    if session.ranges is not None:
        r = session.ranges
        cols = {"t": r.t, "node": r.node, "range": r.range_m}
        if not np.all(np.isnan(r.sigma_m)):
            cols["sigma"] = r.sigma_m
        out["ranges"] = cols
    if session.truth is not None:
        tr = session.truth
        cols = {"t": tr.t, "x": tr.xyz[:, 0], "y": tr.xyz[:, 1], "z": tr.xyz[:, 2]}
        if tr.heading_rad is not None:
            cols["heading"] = tr.heading_rad
        out["truth"] = cols
    if session.checkpoints is not None:
        c = session.checkpoints
        cols = {"t": c.t, "x": c.xyz[:, 0], "y": c.xyz[:, 1], "z": c.xyz[:, 2]}
        if np.any(np.char.str_len(c.label) > 0):
            cols["label"] = c.label
        out["checkpoints"] = cols
    return {stem: out[stem] for stem in SESSION_TABLES if stem in out}


def session_tables(session: Session) -> dict[str, pa.Table]:
    """The session's tables as typed Arrow tables (units in the field metadata), by name.

    :func:`session_from_tables` turns them back into the session (with its meta and landmarks).
    """
    return {stem: to_arrow(cols, table=stem) for stem, cols in session_columns(session).items()}


def session_files(session: Session, *, table_format: TableFormat = "csv") -> dict[str, bytes]:
    """Render a session as ``{file name: bytes}``, exactly what :func:`write_session` writes."""
    suffix = _suffix(table_format)
    files = {stem + suffix: encode_table(cols, table=stem, suffix=suffix)
             for stem, cols in session_columns(session).items()}
    if session.landmarks:
        items = [lm.model_dump(mode="json", exclude_none=True)
                 for lm in session.landmarks.values()]
        files["landmarks.json"] = (json.dumps(items, indent=2) + "\n").encode("utf-8")
    files["session.json"] = (session.meta.model_dump_json(indent=2, exclude_none=True)
                             + "\n").encode("utf-8")
    return files


def _suffix(table_format: str) -> str:
    if table_format not in ("csv", "parquet"):
        raise InputError(f"table format {table_format!r}", where="table_format",
                         expected="csv or parquet")
    return "." + table_format


def write_session(session: Session, path: Path | str, *, overwrite: bool = False,
                  table_format: TableFormat = "csv") -> Path:
    """Write a session as a folder, or as a zip when ``path`` ends in ``.zip``.

    ``table_format``: tables as ``.csv`` (default) or ``.parquet`` files. With ``overwrite`` an
    existing folder's session files are replaced (stale ones, in either format, removed; other
    files are left alone); without it an existing target is an error.
    """
    path = Path(path)
    files = session_files(session, table_format=table_format)
    if path.suffix.lower() == ".zip":
        if path.exists() and not overwrite:
            raise InputError("already exists", where=str(path),
                             expected="a new path (or overwrite=True)")
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".partial")
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
            for name, data in files.items():
                zf.writestr(name, data)
        tmp.replace(path)
        return path
    if path.exists():
        if not path.is_dir():
            raise InputError("exists and is not a folder", where=str(path),
                             expected="a folder path")
        existing = [n for n in SESSION_FILES if (path / n).exists()]
        if existing and not overwrite:
            raise InputError(f"already holds a session ({', '.join(existing)})", where=str(path),
                             expected="an empty or new folder (or overwrite=True)")
        for name in existing:
            (path / name).unlink()
    path.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (path / name).write_bytes(data)
    return path

