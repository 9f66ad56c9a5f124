"""Typed Arrow tables for every hrtls table, Parquet I/O, and the ``hrtls track`` results.

The Arrow-table API (:func:`to_arrow`, :func:`from_arrow`) is what the session files, the
service's raw log and exports share: a table of :data:`hrtls.io.schema.TABLES` as a
:class:`pyarrow.Table` with float64 numbers (NaN as null), text as strings, each field's unit in
its metadata (``b"unit"``) and the table's name in the schema metadata (``b"hrtls.table"``).
:func:`from_arrow` applies the checks of the file readers (finite numbers, non-empty labels,
stated units matching ours) and names the first row that fails.

Result tables: ``trajectory.csv``/``.parquet``:
``t,x,y,z,heading,var_x,cov_xy,var_y,var_heading,activity[,lat,lon]`` (m, rad, m^2, rad^2;
activity as a label; ``lat,lon`` in degrees when a georeference is known) and
``steps.csv``/``.parquet``: ``t_start,t_end,length,heading,dz,activity[,frequency,acc_max,
acc_min]``. Unknown numbers (NaN) are written as empty fields (nulls in Parquet). The format
follows the file suffix.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from hrtls.data import StepEvents, Trajectory, activity_codes, activity_labels
from hrtls.errors import FormatError, UnitError
from hrtls.frames import Georeference
from hrtls.io.csvtable import (
    ArrowColumn,
    Table,
    arrow_columns,
    arrow_from_columns,
    check_columns,
    csv_bytes,
    labelled_text,
    read_table,
    write_csv,
)
from hrtls.io.schema import TABLE_KEY, TABLES, UNIT_KEY, TableSpec

PARQUET_COMPRESSION = "lz4"
"""Codec of the Parquet files hrtls writes (LZ4_RAW); numbers are byte-stream-split first
(they compress better and decode about twice as fast as with dictionaries). On byte-stream-
split IMU columns LZ4 is within 2 % of zstd's size and decodes about a third faster."""


def _spec(table: str) -> TableSpec:
    try:
        return TABLES[table]
    except KeyError:
        raise FormatError(f"unknown table {table!r}", where="table",
                          expected=f"one of {', '.join(TABLES)}") from None


def to_arrow(columns: Mapping[str, ArrowColumn], *, table: str) -> pa.Table:
    """A typed Arrow table of ``table`` (a name in :data:`~hrtls.io.schema.TABLES`).

    Columns keep their given order; each must be one the table allows.

    Raises
    ------
    FormatError
        For an unknown table or column, or a missing required column.
    """
    spec = _spec(table)
    check_columns(list(columns), spec.kinds, spec.required, where=f"{table} table")
    arrow = arrow_from_columns(columns)
    fields = [pa.field(f.name, pa.string() if spec.kinds[f.name] == "str" else pa.float64(),
                       metadata={UNIT_KEY: spec.units[f.name].encode()})
              for f in arrow.schema]
    schema = pa.schema(fields, metadata={TABLE_KEY: table.encode()})
    return pa.Table.from_arrays(arrow.columns, schema=schema)


def from_arrow(arrow: pa.Table, *, table: str, name: str | None = None, owned: bool = False
               ) -> Table:
    """The checked columns of an Arrow table of ``table`` (``name`` labels messages).

    Integer and float columns are read as float64; text columns must be strings. A field whose
    metadata states a unit other than ours is refused (hrtls writes SI units only). ``owned``:
    nothing else holds ``arrow`` (it was just read), so its columns may be viewed, not copied.

    Raises
    ------
    FormatError, UnitError
        Naming the column (``name schema``) or the row (``name row N``, first row 1).
    """
    spec = _spec(table)
    label = name or table
    check_columns(arrow.column_names, spec.kinds, spec.required, where=f"{label} schema")
    for f in arrow.schema:
        numeric = pa.types.is_floating(f.type) or pa.types.is_integer(f.type)
        text = pa.types.is_string(f.type) or pa.types.is_large_string(f.type)
        if not (text if spec.kinds[f.name] == "str" else numeric):
            raise FormatError(f"column {f.name!r} has type {f.type}", where=f"{label} schema",
                              expected="text" if spec.kinds[f.name] == "str" else "numbers")
        unit = (f.metadata or {}).get(UNIT_KEY)
        if unit is not None and unit.decode() != spec.units[f.name]:
            raise UnitError(f"column {f.name!r} is in {unit.decode()!r}",
                            where=f"{label} schema", expected=f"{spec.units[f.name]!r}")
    columns, problem = arrow_columns(arrow, spec.kinds)
    if problem is not None:
        raise FormatError(problem.problem, where=f"{label} row {problem.row + 1}",
                          expected=problem.expected)
    return Table(columns, tuple(arrow.column_names), arrow.num_rows, owned=owned)


def parquet_bytes(arrow: pa.Table) -> bytes:
    """``arrow`` as a compressed Parquet file."""
    out = pa.BufferOutputStream()
    write_parquet(arrow, out)
    return bytes(out.getvalue())


def write_parquet(arrow: pa.Table, sink: pa.NativeFile) -> None:
    """``arrow`` as a compressed Parquet file into ``sink``."""
    floats = [f.name for f in arrow.schema if pa.types.is_floating(f.type)]
    import pyarrow.parquet as pq  # imported for Parquet files only

    pq.write_table(arrow, sink, compression=PARQUET_COMPRESSION,
                   use_dictionary=[c for c in arrow.column_names if c not in floats],
                   column_encoding=dict.fromkeys(floats, "BYTE_STREAM_SPLIT"))


def read_parquet(data: bytes | pa.Buffer, *, table: str, name: str) -> Table:
    """Parse a Parquet file of ``table`` and check it like :func:`from_arrow`.

    Raises
    ------
    FormatError
        For a file that is not Parquet, and as :func:`from_arrow`.
    """
    import pyarrow.parquet as pq  # imported for Parquet files only

    try:
        # the file reader, not the dataset reader of pq.read_table: one chunk per row group
        arrow = pq.ParquetFile(pa.BufferReader(data)).read()
    except (pa.ArrowException, OSError) as exc:
        raise FormatError(f"not a readable Parquet file ({exc})", where=name,
                          expected="a Parquet table") from None
    return from_arrow(arrow, table=table, name=name, owned=True)


def encode_table(columns: Mapping[str, ArrowColumn], *, table: str, suffix: str) -> bytes:
    """The file contents of ``table`` as ``.csv`` or ``.parquet``."""
    arrow = to_arrow(columns, table=table)
    if suffix == ".parquet":
        return parquet_bytes(arrow)
    if suffix == ".csv":
        return csv_bytes(arrow)
    raise FormatError(f"suffix {suffix!r}", where=table, expected=".csv or .parquet")


def write_table_file(columns: Mapping[str, ArrowColumn], *, table: str, path: Path) -> Path:
    """Write ``table`` as ``.csv`` or ``.parquet`` (by the suffix of ``path``).

    The file is written as it is encoded (its whole contents are not held in memory).
    """
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise FormatError(f"suffix {suffix!r}", where=table, expected=".csv or .parquet")
    arrow = to_arrow(columns, table=table)
    with pa.OSFile(str(path), "wb") as sink:
        (write_parquet if suffix == ".parquet" else write_csv)(arrow, sink)
    return path


def decode_table(data: bytes | pa.Buffer, *, table: str, name: str,
                 missing_as_nan: bool = False) -> Table:
    """Parse a ``.csv`` or ``.parquet`` file (by the suffix of ``name``) of ``table``.

    ``missing_as_nan`` reads empty and NaN numbers of a CSV as NaN instead of refusing them
    (for a caller that drops such rows with a warning).
    """
    if name.lower().endswith(".parquet"):
        return read_parquet(data, table=table, name=name)
    spec = _spec(table)
    kinds = dict(spec.kinds)
    if missing_as_nan:
        kinds = {c: "float_or_empty" if k == "float" else k for c, k in kinds.items()}
    return read_table(data, name=name, kinds=kinds, required=spec.required)


# --------------------------------------------------------------------------------------------
# Results of ``hrtls track``
# --------------------------------------------------------------------------------------------
_CODE_SPAN = 1024
"""Activity codes spanning more values than this are labelled through :func:`numpy.unique`."""


def activity_text(codes: NDArray[np.integer]) -> tuple[NDArray[np.intp], list[str]]:
    """``(index, labels)`` with ``labels[index]`` equal to ``activity_labels(codes)``.

    The labels of the few distinct codes are looked up once, not per row.
    """
    codes = np.asarray(codes, dtype=np.int64)
    if not len(codes):
        return np.zeros(0, dtype=np.intp), []
    lo, hi = int(codes.min()), int(codes.max())
    if hi - lo < _CODE_SPAN:
        values, index = np.arange(lo, hi + 1), (codes - lo).astype(np.intp)
    else:
        values, index = np.unique(codes, return_inverse=True)
    return index, activity_labels(values).tolist()


def activity_column(codes: NDArray[np.integer]) -> pa.Array:
    """The ``activity`` text column of activity codes."""
    return labelled_text(*activity_text(codes))


def trajectory_columns(trajectory: Trajectory, *, georeference: Georeference | None = None
                       ) -> dict[str, ArrowColumn]:
    """Columns of the ``trajectory`` table (with ``lat,lon`` when a georeference is given)."""
    tr = trajectory
    cols: dict[str, ArrowColumn] = {
        "t": tr.t, "x": tr.xyz[:, 0], "y": tr.xyz[:, 1], "z": tr.xyz[:, 2],
        "heading": tr.heading_rad, "var_x": tr.cov_xy[:, 0, 0], "cov_xy": tr.cov_xy[:, 0, 1],
        "var_y": tr.cov_xy[:, 1, 1], "var_heading": tr.var_heading,
        "activity": activity_column(tr.activity),
    }
    if georeference is not None and len(tr):
        wgs = georeference.to_wgs84(tr.xyz)
        cols["lat"] = wgs[:, 0]
        cols["lon"] = wgs[:, 1]
    return cols


def trajectory_table(trajectory: Trajectory, *, georeference: Georeference | None = None
                     ) -> str:
    """``trajectory.csv`` text (with ``lat,lon`` when a georeference is given)."""
    return encode_table(trajectory_columns(trajectory, georeference=georeference),
                        table="trajectory", suffix=".csv").decode("utf-8")


def write_trajectory(trajectory: Trajectory, path: Path, *,
                     georeference: Georeference | None = None) -> Path:
    """Write ``trajectory.csv`` or ``trajectory.parquet`` (by the suffix of ``path``)."""
    return write_table_file(trajectory_columns(trajectory, georeference=georeference),
                            table="trajectory", path=path)


def trajectory_from_table(table: Table, *, name: str) -> Trajectory:
    """A trajectory from its checked table (``lat,lon``, if any, are ignored: x, y are kept)."""
    n = table.n_rows

    def col(c: str, default: float) -> np.ndarray:
        return table.float(c) if c in table.present else np.full(n, default)

    cov = np.zeros((n, 2, 2))
    cov[:, 0, 0] = np.nan_to_num(col("var_x", 0.0))
    cov[:, 1, 1] = np.nan_to_num(col("var_y", 0.0))
    cov[:, 0, 1] = cov[:, 1, 0] = np.nan_to_num(col("cov_xy", 0.0))
    activity = (activity_codes(table.str("activity"), where=f"{name} activity")
                if "activity" in table.present else np.full(n, -1))
    return Trajectory.build(
        t=table.float("t"),
        xyz=np.column_stack([table.float("x"), table.float("y"), table.float("z")]),
        heading_rad=col("heading", np.nan), cov_xy=cov, var_heading=col("var_heading", np.nan),
        activity=activity)


def read_trajectory(path: Path) -> Trajectory:
    """Read ``trajectory.csv`` or ``trajectory.parquet``."""
    table = decode_table(path.read_bytes(), table="trajectory", name=path.name)
    return trajectory_from_table(table, name=path.name)


def steps_columns(steps: StepEvents) -> dict[str, ArrowColumn]:
    """Columns of the ``steps`` table."""
    return {
        "t_start": steps.t_start, "t_end": steps.t_end, "length": steps.length_m,
        "heading": steps.heading_rad, "dz": steps.dz_m,
        "activity": activity_column(steps.activity),
        "frequency": steps.frequency_hz, "acc_max": steps.acc_max, "acc_min": steps.acc_min,
    }


def steps_table(steps: StepEvents) -> str:
    """``steps.csv`` text."""
    return encode_table(steps_columns(steps), table="steps", suffix=".csv").decode("utf-8")


def write_steps(steps: StepEvents, path: Path) -> Path:
    """Write ``steps.csv`` or ``steps.parquet`` (by the suffix of ``path``)."""
    return write_table_file(steps_columns(steps), table="steps", path=path)


def steps_from_table(table: Table, *, name: str) -> StepEvents:
    """Step events from their checked table."""
    def col(c: str) -> np.ndarray | None:
        return table.float(c) if c in table.present else None

    if not table.n_rows:
        return StepEvents.empty()
    activity = (activity_codes(table.str("activity"), where=f"{name} activity")
                if "activity" in table.present else None)
    dz = col("dz")
    return StepEvents.build(
        t_start=table.float("t_start"), t_end=table.float("t_end"),
        length_m=table.float("length"), heading_rad=col("heading"),
        dz_m=None if dz is None else np.nan_to_num(dz), activity=activity,
        frequency_hz=col("frequency"), acc_max=col("acc_max"), acc_min=col("acc_min"))


def read_steps(path: Path) -> StepEvents:
    """Read ``steps.csv`` or ``steps.parquet``."""
    return steps_from_table(decode_table(path.read_bytes(), table="steps", name=path.name),
                            name=path.name)
