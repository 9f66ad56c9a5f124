"""A session folder or zip read in chunks of IMU rows, so memory stays bounded.

:func:`open_stream` reads every table but the IMU whole (they are small: observations, ground
truth, a separate gyroscope or magnetometer) and the IMU table's time column, then
:meth:`SessionStream.chunks` yields consecutive :class:`~hrtls.data.Session` chunks of
``chunk_rows`` IMU rows with the observations of the same time span, the way the live service
feeds :meth:`hrtls.pipeline.Tracker.update`. Gyroscope or magnetometer samples with their own
clock are interpolated onto the accelerometer times from the whole series, exactly as
:meth:`hrtls.data.ImuStream.aligned` does offline.

Any chunk that fails a check (a malformed value, time going backwards) makes the stream read
the whole session with :func:`hrtls.io.session.read_session`, which raises the exact message
(file, line, column, value). Repairs need the whole recording, so a stream never repairs.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from hrtls.data import ImuStream, Landmark, SensorSeries, Session, SessionMeta
from hrtls.data.session import SESSION_PARTS
from hrtls.errors import FormatError, InputError
from hrtls.io.csvtable import Table, _header, arrow_columns
from hrtls.io.schema import TABLES
from hrtls.io.session import (
    _group,
    _read_landmarks,
    _read_meta,
    _read_vector_file,
    _SessionFiles,
    other_parts,
    read_session,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, open_source
from hrtls.io.tables import from_arrow

DEFAULT_CHUNK_ROWS = 1 << 16
"""IMU rows per chunk (about 11 minutes at 100 Hz)."""

_AXES = ("x", "y", "z")


@dataclass(frozen=True, slots=True)
class SessionStream:
    """A session whose IMU is read chunk by chunk (see :func:`open_stream`).

    Attributes
    ----------
    meta, landmarks:
        As in the session.
    parts:
        Every other part of the session, read whole (``pressure``, ``fixes``, ..., ``truth``).
    rate_hz:
        The accelerometer's nominal rate over the whole recording (median spacing), Hz.
    t0:
        Earliest time over all streams, observations and ground truth, s.
    """

    path: Path
    meta: SessionMeta
    landmarks: dict[str, Landmark]
    parts: dict[str, Any]
    rate_hz: float
    t0: float
    n_rows: int
    has_gyro: bool
    has_mag: bool
    _imu_name: str = field(repr=False)
    _data: bytes = field(repr=False)
    _gyro: SensorSeries | None = field(repr=False)
    _mag: SensorSeries | None = field(repr=False)
    _chunk_rows: int = field(repr=False)
    _check_units: bool = field(repr=False)
    _max_bytes: int = field(repr=False)

    def session(self, imu: ImuStream) -> Session:
        """The whole session but for its IMU, which is ``imu`` (e.g. one chunk)."""
        return Session(meta=self.meta, imu=imu, landmarks=self.landmarks, **self.parts)

    def start_imu(self) -> ImuStream:
        """What :meth:`hrtls.pipeline.Tracker.start_session` looks at, without the whole IMU.

        The accelerometer and magnetometer of the whole recording (for the hand-held mounting
        and the hard-iron fit) and the gyroscope's first chunk only (it is only checked for).
        """
        columns = [c for c in _columns(self._data, name=self._imu_name)
                   if c == "t" or c[0] in "am"]
        table = _read_columns(self._data, name=self._imu_name, columns=columns)
        checked = None if table is None else _checked(table, name=self._imu_name)
        if checked is None:
            read_session(self.path, max_bytes=self._max_bytes)  # raises the exact message
            raise FormatError("could not be read in columns", where=str(self.path),
                              expected="a session readable whole")
        t = checked.float("t")
        acc = _group(checked, tuple("a" + a for a in _AXES), name=self._imu_name)
        mag = _group(checked, tuple("m" + a for a in _AXES), name=self._imu_name)
        assert acc is not None
        gyro = self._gyro
        if gyro is None and self.has_gyro:
            gyro = next(self._imu_chunks()).gyro
        return ImuStream(SensorSeries(t, acc, f"{self._imu_name} accelerometer"), gyro,
                         self._mag if mag is None else SensorSeries(t, mag, self._imu_name),
                         check_units=False)

    def chunks(self) -> Iterator[Session]:
        """Consecutive chunks: ``chunk_rows`` IMU rows and the observations of their span."""
        t_prev = -math.inf
        pending: ImuStream | None = None
        for imu in self._imu_chunks():
            if pending is not None:
                yield self._chunk(pending, t_prev, float(imu.accel.t[0]))
                t_prev = float(imu.accel.t[0])
            pending = imu
        if pending is not None:
            yield self._chunk(pending, t_prev, math.inf)

    def _chunk(self, imu: ImuStream, t_start: float, t_end: float) -> Session:
        from hrtls.pipeline.chunks import session_window

        observed = self.session(imu).with_parts(truth=None, checkpoints=None)
        window = session_window(observed, t_start, t_end)
        assert window is not None  # it holds the chunk's IMU rows
        return window

    def _batches(self) -> Iterator[pa.RecordBatch]:
        spec = TABLES["imu"]
        if self._imu_name.endswith(".parquet"):
            yield from pq.ParquetFile(pa.BufferReader(self._data)).iter_batches(
                batch_size=self._chunk_rows)
            return
        header, start = _header(self._data, name=self._imu_name)
        types = {c: pa.float64() for c in header if spec.kinds.get(c) == "float"}
        reader = pacsv.open_csv(
            pa.BufferReader(pa.py_buffer(self._data)[start:]),
            read_options=pacsv.ReadOptions(column_names=header,
                                           block_size=self._chunk_rows * 64),
            convert_options=pacsv.ConvertOptions(column_types=types, null_values=[""]))
        yield from reader

    def _imu_chunks(self) -> Iterator[ImuStream]:
        t_last = -math.inf
        try:
            for batch in self._batches():
                if not batch.num_rows:
                    continue
                table = pa.Table.from_batches([batch])
                cols, problem = arrow_columns(table, TABLES["imu"].kinds)
                t = cols["t"] if problem is None else np.zeros(0)
                if problem is not None or t[0] < t_last or np.any(np.diff(t) < 0):
                    raise _Fallback
                t_last = float(t[-1])
                yield self._imu(from_arrow(table, table="imu", name=self._imu_name))
        except (_Fallback, pa.ArrowException):
            read_session(self.path, max_bytes=self._max_bytes)  # raises the exact message
            raise FormatError("could not be read in chunks", where=str(self.path),
                              expected="a session readable whole") from None

    def _imu(self, table: Any) -> ImuStream:
        name = self._imu_name
        t = table.float("t")
        acc = _group(table, tuple("a" + a for a in _AXES), name=name)
        gyr = _group(table, tuple("g" + a for a in _AXES), name=name)
        mag = _group(table, tuple("m" + a for a in _AXES), name=name)
        assert acc is not None
        if gyr is None and self._gyro is not None:
            gyr = self._gyro.interpolate(t)
        if mag is None and self._mag is not None:
            mag = self._mag.interpolate(t)
        return ImuStream(SensorSeries(t, acc, f"{name} accelerometer"),
                         None if gyr is None else SensorSeries(t, gyr, f"{name} gyroscope"),
                         None if mag is None else SensorSeries(t, mag, f"{name} magnetometer"),
                         check_units=self._check_units)


def _checked(table: pa.Table, *, name: str) -> Table | None:
    columns, problem = arrow_columns(table, TABLES["imu"].kinds)
    return None if problem is not None else Table(columns, tuple(table.column_names),
                                                  table.num_rows)


class _Fallback(Exception):
    """A chunk failed a check: the whole-session reader explains it."""


def _has_observations(session: Session) -> bool:
    return any(getattr(session, p) is not None
               for p in ("pressure", "orientation", "fixes", "rss", "tags", "ranges"))


def open_stream(path: Path | str, *, chunk_rows: int = DEFAULT_CHUNK_ROWS,
                check_units: bool = True, max_bytes: int = DEFAULT_MAX_BYTES
                ) -> SessionStream | None:
    """Open a session folder or zip for chunked reading (None when it has no IMU table).

    Raises
    ------
    FormatError, InputError
        As :func:`hrtls.io.session.read_session`, naming the file, line and field.
    """
    if chunk_rows < 2:
        raise InputError(f"chunk_rows = {chunk_rows}", where="chunk_rows",
                         expected="at least 2 rows")
    path = Path(path)
    src = _SessionFiles(open_source(path, max_bytes=max_bytes))
    names = [n for n in ("imu.csv", "imu.parquet") if n in src.names]
    if len(names) != 1:
        return None
    name = names[0]
    data = src.read(name)
    t = _time_column(data, name=name)
    if t is None or len(t) < 2 or np.any(np.diff(t) <= 0):
        read_session(path, max_bytes=max_bytes)  # raises the exact message, or is valid
        return None
    parts = other_parts(src, repair=False)
    gyro = _read_vector_file(src, "gyro", "g", repair=False)
    mag = _read_vector_file(src, "mag", "m", repair=False)
    header = _columns(data, name=name)
    starts = [float(v.t[0]) for k, v in parts.items()
              if k in SESSION_PARTS and v is not None and len(v.t)]
    return SessionStream(
        path=path, meta=_read_meta(src), landmarks=_read_landmarks(src), parts=parts,
        rate_hz=float(1.0 / np.median(np.diff(t))), t0=min([float(t[0]), *starts]),
        n_rows=len(t), has_gyro=gyro is not None or "gx" in header,
        has_mag=mag is not None or "mx" in header, _imu_name=name, _data=data, _gyro=gyro,
        _mag=mag, _chunk_rows=chunk_rows, _check_units=check_units, _max_bytes=max_bytes)


def _columns(data: bytes, *, name: str) -> list[str]:
    if name.endswith(".parquet"):
        return list(pq.ParquetFile(pa.BufferReader(data)).schema_arrow.names)
    return _header(data, name=name)[0]


def _read_columns(data: bytes, *, name: str, columns: list[str]) -> pa.Table | None:
    """Some columns of the IMU table (None when they cannot be read: the full reader explains)."""
    try:
        if name.endswith(".parquet"):
            return pq.read_table(pa.BufferReader(data), columns=columns)
        header, start = _header(data, name=name)
        return pacsv.read_csv(
            pa.BufferReader(pa.py_buffer(data)[start:]),
            read_options=pacsv.ReadOptions(column_names=header, block_size=1 << 24),
            convert_options=pacsv.ConvertOptions(
                include_columns=columns, column_types=dict.fromkeys(columns, pa.float64()),
                null_values=[""]))
    except (pa.ArrowException, KeyError):
        return None


def _time_column(data: bytes, *, name: str) -> np.ndarray | None:
    """The IMU's time column alone (None when it cannot be read: the full reader explains)."""
    table = _read_columns(data, name=name, columns=["t"])
    if table is None:
        return None
    col = table.column("t")
    if col.null_count:
        return None
    t = np.asarray(col.to_numpy(), dtype=np.float64)
    return t if np.all(np.isfinite(t)) else None
