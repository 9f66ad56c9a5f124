"""A session folder or zip read in chunks of IMU rows, so memory stays bounded.

:func:`open_stream` reads every table but the IMU and the ground truth whole (they are small:
observations, a separate gyroscope or magnetometer), then :meth:`SessionStream.chunks` reads
the IMU table from its file once, piece by piece (Parquet row groups or batches of Arrow's
streaming CSV reader), and yields consecutive :class:`~hrtls.data.Session` chunks of about
``chunk_rows`` IMU rows with the observations of the same time span, the way the live service
feeds :meth:`hrtls.pipeline.Tracker.update`. Gyroscope or magnetometer samples with their own
clock are interpolated onto the accelerometer times from the whole series, exactly as
:meth:`hrtls.data.ImuStream.aligned` does offline. The accelerometer times are kept
(:attr:`SessionStream.imu_t`, complete once the chunks are read) for the checks that need the
whole clock; the ground truth is read only when asked for (:meth:`SessionStream.truth`).

A chunk that fails a check (a malformed value, or IMU times that do not increase) makes the
stream read the whole session with :func:`hrtls.io.session.read_session`, which raises the
exact message (file, line, column, value), or, if the careful reader accepts the file,
:class:`NotStreamable`. Repairs need the whole recording, so a stream never repairs: a session
whose header is not on the first line is not streamed (None).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, NoReturn

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from hrtls.data import GroundTruth, ImuStream, Landmark, SensorSeries, Session, SessionMeta
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
    truth_from,
)
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source

DEFAULT_CHUNK_ROWS = 1 << 16
"""IMU rows per chunk (about 11 minutes at 100 Hz)."""

_AXES = ("x", "y", "z")
_BLOCK_BYTES = 1 << 20
"""Read buffer of the streamed tables; larger blocks (and reader threads) hold many in flight."""


class _Fallback(Exception):
    """A chunk failed a check: the whole-session reader explains it."""


class NotStreamable(Exception):
    """The whole-session reader accepts what the chunked reader refused: read it whole.

    For instance spaces around numbers, which only the careful CSV path reads.
    """


@dataclass(frozen=True, slots=True)
class _TableFile:
    """A table's file: name, columns, a way to open it again (read in pieces) and rows.

    ``rows`` is exact for Parquet, estimated from the file size for CSV.
    """

    name: str
    header: list[str]
    open: Callable[[], IO[bytes]]
    rows: int

    @property
    def parquet(self) -> bool:
        return self.name.endswith(".parquet")

    def columns(self, columns: list[str]) -> pa.Table:
        """Some columns, whole (float64)."""
        with self.open() as fh:
            if self.parquet:
                import pyarrow.parquet as pq  # imported for Parquet files only

                return pq.read_table(fh, columns=columns)
            return pacsv.read_csv(fh, read_options=self._read_options(1 << 24),
                                  convert_options=self._convert(columns))

    def pieces(self, rows: int) -> Generator[pa.Table, None, None]:
        """Consecutive pieces of the table of about ``rows`` rows, read one after the other.

        Both are read on one thread through small buffers (bounded memory): Parquet one row
        group at a time, CSV in blocks cut into pieces of ``rows`` rows (the last may be
        shorter).
        """
        with self.open() as fh:
            if self.parquet:
                import pyarrow.parquet as pq  # imported for Parquet files only

                parquet = pq.ParquetFile(fh, buffer_size=_BLOCK_BYTES, pre_buffer=False)
                for batch in parquet.iter_batches(batch_size=rows, use_threads=False):
                    yield pa.Table.from_batches([batch])
                return
            rest: pa.Table | None = None
            for batch in pacsv.open_csv(fh, read_options=self._read_options(
                    _BLOCK_BYTES, threads=False), convert_options=self._convert(self.header)):
                table = pa.Table.from_batches([batch])
                if rest is not None:
                    table = pa.concat_tables([rest, table])
                while table.num_rows >= rows:
                    yield table.slice(0, rows)
                    table = table.slice(rows)
                rest = table
            if rest is not None and rest.num_rows:
                yield rest

    def _read_options(self, block_size: int, *, threads: bool = True) -> pacsv.ReadOptions:
        return pacsv.ReadOptions(column_names=self.header, skip_rows=1, block_size=block_size,
                                 use_threads=threads)

    def _convert(self, columns: list[str]) -> pacsv.ConvertOptions:
        return pacsv.ConvertOptions(include_columns=columns, null_values=[""],
                                    column_types=dict.fromkeys(columns, pa.float64()))


def _checked(table: pa.Table, stem: str = "imu") -> Table:
    columns, problem = arrow_columns(table, TABLES[stem].kinds)
    if problem is not None:
        raise _Fallback
    return Table(columns, tuple(table.column_names), table.num_rows)


@dataclass(frozen=True, slots=True)
class SessionStream:
    """A session whose IMU is read chunk by chunk (see :func:`open_stream`).

    Attributes
    ----------
    meta, landmarks:
        As in the session.
    parts:
        Every other part of the session but the ground truth (:meth:`truth`), read whole.
    rows_hint:
        IMU rows: exact for Parquet, estimated from the file size for CSV (for progress).
    """

    path: Path
    meta: SessionMeta
    landmarks: dict[str, Landmark]
    parts: dict[str, Any]
    rows_hint: int
    has_gyro: bool
    has_mag: bool
    _imu: _TableFile = field(repr=False)
    _truth: _TableFile | None = field(repr=False)
    _gyro: SensorSeries | None = field(repr=False)
    _mag: SensorSeries | None = field(repr=False)
    _starts: list[float] = field(repr=False)
    _chunk_rows: int = field(repr=False)
    _check_units: bool = field(repr=False)
    _max_bytes: int = field(repr=False)
    _times: list[np.ndarray] = field(default_factory=list, repr=False)

    @property
    def imu_t(self) -> np.ndarray:
        """The accelerometer times read so far (all of them once :meth:`chunks` is done), s."""
        if len(self._times) > 1:  # joined once, in place of the chunks' pieces
            self._times[:] = [np.concatenate(self._times)]
        return self._times[0] if self._times else np.zeros(0)

    def t0(self, imu_t0: float) -> float:
        """Earliest time over all streams, observations and ground truth, s.

        ``imu_t0``: the first accelerometer time (of the first chunk).
        """
        return min([imu_t0, *self._starts])

    def sensor_times(self) -> list[tuple[str, str, np.ndarray]]:
        """``(key, name, t)`` of every sensor stream with its own clock, accelerometer first.

        The accelerometer's times are complete once :meth:`chunks` is done.
        """
        out = [("accel", f"{self._imu.name} accelerometer", self.imu_t)]
        for key, series in (("gyro", self._gyro), ("mag", self._mag),
                            ("pressure", self.parts.get("pressure")),
                            ("orientation", self.parts.get("orientation"))):
            if series is not None:
                out.append((key, series.name, series.t))
        return out

    def session(self, imu: ImuStream) -> Session:
        """The whole session but for its IMU, which is ``imu`` (e.g. one chunk)."""
        return Session(meta=self.meta, imu=imu, landmarks=self.landmarks, **self.parts)

    def truth(self) -> GroundTruth | None:
        """The ground truth, read now in pieces (it is not held while the IMU streams).

        The pieces are copied into arrays sized from the table's row count (grown if the CSV
        estimate falls short), so the whole table is held once.
        """
        if self._truth is None:
            return None
        name = self._truth.name
        columns: list[np.ndarray] = []
        n = 0
        try:
            for piece in self._truth.pieces(self._chunk_rows):
                if not piece.num_rows:
                    continue
                part = truth_from(_checked(piece, "truth"), name)
                values = [part.t, part.xyz] + ([] if part.heading_rad is None
                                               else [part.heading_rad])
                if not columns:
                    columns = [np.empty((max(self._truth.rows, len(part.t)), *v.shape[1:]))
                               for v in values]
                columns = [_placed(c, n, v) for c, v in zip(columns, values, strict=True)]
                n += len(part.t)
            columns = columns or [np.zeros(0), np.zeros((0, 3))]
            truth = GroundTruth(columns[0][:n], columns[1][:n],
                                columns[2][:n] if len(columns) > 2 else None, name)
        except (_Fallback, pa.ArrowException, FormatError, InputError):
            self._explain()
        pa.default_memory_pool().release_unused()
        return truth

    def chunks(self) -> Iterator[Session]:
        """Consecutive chunks: about ``chunk_rows`` IMU rows and the observations of their span.

        Every observation goes into exactly one chunk: those before the first IMU row into the
        first, those after the last into the last. Reading them again starts over.
        """
        self._times.clear()
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

    def _explain(self) -> NoReturn:
        """Read the whole session: raises the exact message of what failed in a chunk.

        Raises
        ------
        NotStreamable
            When the whole session reads (the chunked reader is stricter).
        """
        read_session(self.path, max_bytes=self._max_bytes)
        raise NotStreamable(str(self.path))

    def _imu_chunks(self) -> Iterator[ImuStream]:
        t_last = -math.inf
        try:
            for piece in self._imu.pieces(self._chunk_rows):
                if not piece.num_rows:
                    continue
                imu = self._imu_of(_checked(piece))
                t = imu.accel.t
                _check_time(t, t_last, self._explain)
                self._times.append(t)
                t_last = float(t[-1])
                yield imu
        except (_Fallback, pa.ArrowException):
            self._explain()

    def _imu_of(self, table: Table) -> ImuStream:
        name = self._imu.name
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


def _placed(buffer: np.ndarray, n: int, values: np.ndarray) -> np.ndarray:
    """``buffer`` (grown by half when too short) with ``values`` at rows ``n`` onwards."""
    end = n + len(values)
    if end > len(buffer):
        grown = np.empty((max(end, len(buffer) * 3 // 2), *buffer.shape[1:]))
        grown[:n] = buffer[:n]
        buffer = grown
    buffer[n:end] = values
    return buffer


def _check_time(t: np.ndarray, t_before: float, explain: Callable[[], NoReturn]) -> None:
    """IMU times that increase, from after ``t_before``; else the whole-session reader explains.

    The whole-session reader refuses them with their line, or repairs them (``--repair``).
    """
    if t[0] <= t_before or np.any(np.diff(t) <= 0):
        explain()


def open_stream(path: Path | str, *, chunk_rows: int = DEFAULT_CHUNK_ROWS,
                check_units: bool = True, max_bytes: int = DEFAULT_MAX_BYTES
                ) -> SessionStream | None:
    """Open a session folder or zip for chunked reading (the IMU is read by the chunks).

    None when it cannot stream: no IMU table, or an IMU or truth table whose header is not on
    the first line (:func:`~hrtls.io.session.read_session` handles those).

    Raises
    ------
    FormatError, InputError
        As :func:`hrtls.io.session.read_session`, naming the file, line and field.
    """
    if chunk_rows < 2:
        raise InputError(f"chunk_rows = {chunk_rows}", where="chunk_rows",
                         expected="at least 2 rows")
    path = Path(path)
    source = open_source(path, max_bytes=max_bytes)
    src = _SessionFiles(source)
    names = [n for n in ("imu.csv", "imu.parquet") if n in src.names]
    truths = [n for n in ("truth.csv", "truth.parquet") if n in src.names]
    if len(names) != 1 or len(truths) > 1:
        return None  # the whole-session reader explains
    imu = _table_file(source, src, names[0])
    truth = _table_file(source, src, truths[0]) if truths else None
    if imu is None or (truths and truth is None):
        return None
    truth_t0 = None if truth is None else _first_time(truth)
    starts = [] if truth_t0 is None else [truth_t0]
    header = imu.header
    parts = other_parts(src, repair=False, skip=frozenset({"truth"}))
    gyro = _read_vector_file(src, "gyro", "g", repair=False)
    mag = _read_vector_file(src, "mag", "m", repair=False)
    starts += [float(v.t[0]) for k, v in parts.items()
               if k in SESSION_PARTS and v is not None and len(v.t)]
    pa.default_memory_pool().release_unused()  # the parsers' buffers, before the IMU streams
    return SessionStream(
        path=path, meta=_read_meta(src), landmarks=_read_landmarks(src), parts=parts,
        rows_hint=imu.rows, has_gyro=gyro is not None or "gx" in header,
        has_mag=mag is not None or "mx" in header, _imu=imu, _truth=truth, _gyro=gyro,
        _mag=mag, _starts=starts, _chunk_rows=chunk_rows, _check_units=check_units,
        _max_bytes=max_bytes)


def _table_file(source: Source, src: _SessionFiles, name: str) -> _TableFile | None:
    """The table's file, or None when its header is not on the first line (read it whole)."""
    member = src.member(name)
    if name.endswith(".parquet"):
        import pyarrow.parquet as pq  # imported for Parquet files only

        try:
            with source.open(member) as fh:
                parquet = pq.ParquetFile(fh)
                header, rows = list(parquet.schema_arrow.names), parquet.metadata.num_rows
        except (pa.ArrowException, OSError):
            return None
    else:
        head = source.head(member, 1 << 16)
        header, start = _header(head, name=name)
        if head[:start].count(b"\n") != 1:
            return None
        body = head[start:]
        size = source.size(member)
        if len(head) == size:  # the whole file: its rows
            rows = body.count(b"\n") + (bool(body) and not body.endswith(b"\n"))
        else:  # the size over the mean row of the head
            rows = round((size - start) * body.count(b"\n") / max(len(body), 1))
    return _TableFile(name, header, lambda: source.open(member), rows)


def _first_time(table: _TableFile) -> float | None:
    """The first row's time, from the table's first batch (None when it cannot be read)."""
    try:
        pieces = table.pieces(1)
        piece = next((p for p in pieces if p.num_rows), None)
        pieces.close()
    except pa.ArrowException:
        return None
    if piece is None or "t" not in piece.column_names:
        return None
    value = piece.column("t")[0].as_py()
    return float(value) if value is not None and math.isfinite(value) else None
