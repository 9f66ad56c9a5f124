"""CSV tables with a header line, read at library speed, with exact error locations.

The fast path is Arrow's multi-threaded CSV parser (:func:`pyarrow.csv.read_csv`) with an
explicit type per column, followed by vectorized checks (finite numbers, non-empty labels).
Whenever it refuses a file or a check fails, the careful path reads the file again row by row
with :mod:`csv` and either names the first bad line, column and value, or, for input the fast
parser is merely stricter about (spaces around numbers, ``1_000``), returns the same table.
Writing renders numbers with the shortest text that reads back to the same float.
"""

from __future__ import annotations

import csv
import io
import math
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, TypeAlias

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
from numpy.typing import NDArray

from hrtls.errors import FormatError, RepairWarning

ColumnKind = Literal["float", "str", "float_or_empty"]
"""``float``: a required number; ``float_or_empty``: a number or empty (read as NaN); ``str``."""

Column = NDArray[np.float64] | NDArray[np.str_]


@dataclass(frozen=True, slots=True)
class Table:
    """Checked columns of a parsed table by name; ``present`` lists the columns the file had.

    Numeric columns may be held as the parser's float64 Arrow arrays (nulls for unknown
    values) and become numpy arrays only when asked for, so a group of columns is copied once,
    straight into its ``(n, k)`` array (:meth:`matrix`). With ``owned`` (the Arrow arrays were
    made by the reader and nothing else holds them) a column of one chunk without nulls is
    handed out by :meth:`float` as a writable view of its buffer, not copied.
    """

    columns: Mapping[str, Column | pa.ChunkedArray]
    present: tuple[str, ...]
    n_rows: int
    owned: bool = False

    def column(self, name: str) -> Column:
        """A column as numpy: text, or float64 numbers."""
        col = self.columns[name]
        return self.float(name) if isinstance(col, pa.ChunkedArray) else col

    def matrix(self, names: Sequence[str]) -> NDArray[np.float64]:
        """Numeric columns side by side, ``(n_rows, len(names))`` (unknown values as NaN)."""
        out = np.empty((self.n_rows, len(names)), dtype=np.float64)
        for j, name in enumerate(names):
            col = self.columns[name]
            if not isinstance(col, pa.ChunkedArray):
                out[:, j] = col
                continue
            k = 0
            for chunk in col.chunks:
                out[k:k + len(chunk), j] = float_values(chunk)
                k += len(chunk)
        return out

    def float(self, name: str) -> NDArray[np.float64]:
        """A numeric column (unknown values as NaN)."""
        col = self.columns[name]
        if isinstance(col, pa.ChunkedArray):
            if self.owned and col.num_chunks == 1 and not col.null_count:
                view = float_values(col.chunks[0])
                if view.flags.writeable:
                    return view
            return self.matrix((name,))[:, 0]
        return np.asarray(col, dtype=np.float64)

    def str(self, name: str) -> NDArray[np.str_]:
        """A text column."""
        return np.asarray(self.columns[name], dtype=np.str_)


def float_values(array: pa.Array) -> NDArray[np.float64]:
    """A float64 Arrow array as numpy (nulls as NaN), viewed without a copy when it has none.

    Read from its buffers: :meth:`pyarrow.Array.to_numpy` (and Arrow scalars made from Python
    values) would import pandas.
    """
    validity, data = array.buffers()[:2]
    values = np.frombuffer(data, dtype=np.float64, count=len(array), offset=array.offset * 8)
    if not array.null_count:
        return values
    bits = np.unpackbits(np.frombuffer(validity, dtype=np.uint8), bitorder="little")
    return np.where(bits[array.offset:array.offset + len(array)].astype(bool), values, np.nan)


@dataclass(frozen=True, slots=True)
class ValueProblem:
    """The first value of an Arrow table that does not fit its column (row from 0)."""

    row: int
    column: str
    problem: str
    expected: str


# --------------------------------------------------------------------------------------------
# Columns of an Arrow table, checked (shared with the Parquet reader)
# --------------------------------------------------------------------------------------------
def _first(mask: pa.ChunkedArray | pa.Array) -> int:
    return int(np.flatnonzero(np.asarray(mask, dtype=bool))[0])


def _as_float64(col: pa.ChunkedArray) -> pa.ChunkedArray:
    """Numbers as float64 with nulls kept (no copy when they already are)."""
    return col if col.type == pa.float64() else col.cast(pa.float64())


def _all_finite(values: pa.ChunkedArray) -> bool:
    """True when the values that are not null are all finite, in one pass (a sum).

    A sum is finite only if every value summed is (IEEE: inf and NaN propagate); a False
    (a non-finite value, or finite values whose sum overflows) only calls for the exact check.
    """
    total = pc.sum(values, skip_nulls=True).as_py()
    return total is None or math.isfinite(total)


def arrow_columns(table: pa.Table, kinds: Mapping[str, ColumnKind]
                  ) -> tuple[dict[str, Column | pa.ChunkedArray], ValueProblem | None]:
    """Checked columns of ``table``, or the first value that does not fit.

    Numbers stay float64 Arrow arrays (see :class:`Table`); text becomes numpy. ``float``
    columns must hold finite numbers; ``float_or_empty`` numbers or nulls (NaN, not infinite);
    ``str`` columns non-empty text (leading and trailing spaces are dropped).
    """
    out: dict[str, Column | pa.ChunkedArray] = {}
    for name in table.column_names:
        col = table.column(name)
        kind = kinds[name]
        if kind == "str":
            text = pc.utf8_trim_whitespace(col)
            if col.null_count:
                return out, ValueProblem(_first(col.is_null()), name, f"empty {name!r}",
                                         "a non-empty text value")
            # length 0 casts to False; comparing with a Python 0 would import pandas
            empty = pc.invert(pc.cast(pc.utf8_length(text), pa.bool_()))
            if pc.any(empty).as_py():
                return out, ValueProblem(_first(empty), name, f"empty {name!r}",
                                         "a non-empty text value")
            out[name] = np.array(text.to_pylist(), dtype=np.str_)
            continue
        if col.null_count and kind == "float":
            return out, ValueProblem(_first(col.is_null()), name, f"{name!r} is missing",
                                     "a number")
        values = _as_float64(col)
        if not _all_finite(values):
            bad = (pc.is_inf(values) if kind == "float_or_empty"
                   else pc.invert(pc.is_finite(values)))
            if pc.any(bad).as_py():
                k = _first(pc.fill_null(bad, False))
                return out, ValueProblem(k, name, f"{name!r} is {values[k].as_py()}",
                                         "a finite number")
        out[name] = values
    return out, None


def check_columns(header: Sequence[str], kinds: Mapping[str, ColumnKind],
                  required: Sequence[str], *, where: str) -> None:
    """Unique, known column names with every required one present."""
    header = list(header)
    if len(set(header)) != len(header):
        dup = next(c for c in header if header.count(c) > 1)
        raise FormatError(f"column {dup!r} appears twice", where=where,
                          expected="unique column names")
    missing = [c for c in required if c not in header]
    if missing:
        raise FormatError(f"missing column(s) {', '.join(missing)}", where=where,
                          expected=f"header with {','.join(required)}")
    unknown = [c for c in header if c not in kinds]
    if unknown:
        raise FormatError(f"unknown column(s) {', '.join(unknown)}", where=where,
                          expected=f"columns among {','.join(kinds)}")


# --------------------------------------------------------------------------------------------
# Reading CSV
# --------------------------------------------------------------------------------------------
_NON_SPACE = re.compile(rb"\S")
_HEAD_BYTES = 1 << 16
_BLOCK_BYTES = 1 << 20
"""Arrow CSV block size: blocks that stay in cache parse faster than large ones."""


def _decode(data: bytes, *, name: str) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise FormatError(f"byte {exc.start} is not valid UTF-8", where=f"{name} line {line}",
                          expected="a UTF-8 text file") from None


def _header(data: bytes, *, name: str) -> tuple[list[str], int]:
    """Column names and the byte offset of the first row after the header line."""
    start = 3 if data.startswith(b"\xef\xbb\xbf") else 0
    while True:
        end = data.find(b"\n", start)
        line = data[start:] if end < 0 else data[start:end]
        if line.strip():
            try:
                text = line.decode("utf-8")
            except UnicodeDecodeError:
                _decode(data, name=name)
                raise
            cols = [c.strip().strip('"') for c in text.strip().split(",")]
            return cols, (len(data) if end < 0 else end + 1)
        if end < 0:
            raise FormatError("file is empty", where=name, expected="a header line and rows")
        start = end + 1


def _careful(text: str, header: list[str], kinds: Mapping[str, ColumnKind], *,
             name: str) -> Table:
    """Row-by-row parse: the table, or the first malformed line (after the fast path failed)."""
    reader = csv.reader(io.StringIO(text))
    raw_lines = text.split("\n")  # the lines csv.reader counts (StringIO splits at newlines)
    cells: list[list[str]] = [[] for _ in header]
    line_no = 0
    for row in reader:
        first, line_no = line_no + 1, reader.line_num
        if line_no > first or any("\n" in c or "\r" in c for c in row):
            raise FormatError("a quoted value runs past the end of the line",
                              where=f"{name} line {first}", expected="quotes closed on their line")
        blank = not row or (len(row) == 1 and not raw_lines[line_no - 1].strip())
        if line_no == 1 or blank:
            continue  # a blank line (a line of bare commas or of "" is a row of empty fields)
        if len(row) != len(header):
            raise FormatError(f"{len(row)} fields", where=f"{name} line {line_no}",
                              expected=f"{len(header)} fields ({','.join(header)})")
        for i, (col, value) in enumerate(zip(header, row, strict=True)):
            kind = kinds[col]
            cells[i].append(value.strip())
            if kind == "str":
                if not value.strip():
                    raise FormatError(f"empty {col!r}", where=f"{name} line {line_no}",
                                      expected="a non-empty text value")
                continue
            if kind == "float_or_empty" and not value.strip():
                cells[i][-1] = "nan"
                continue
            try:
                number = float(value)
            except ValueError:
                raise FormatError(f"{col!r} is {value!r}", where=f"{name} line {line_no}",
                                  expected="a number") from None
            if np.isinf(number) or (kind == "float" and np.isnan(number)):
                raise FormatError(f"{col!r} is {value.strip()}", where=f"{name} line {line_no}",
                                  expected="a finite number")
    columns: dict[str, Column] = {
        col: (np.array(vals, dtype=np.str_) if kinds[col] == "str"
              else np.array(vals, dtype=np.float64))
        for col, vals in zip(header, cells, strict=True)}
    return Table(columns, tuple(header), len(cells[0]) if cells else 0)


def _fast(body: pa.Buffer, header: list[str], kinds: Mapping[str, ColumnKind]) -> Table | None:
    types = {c: pa.string() if kinds[c] == "str" else pa.float64() for c in header}
    try:
        parsed = pacsv.read_csv(
            pa.BufferReader(body),
            read_options=pacsv.ReadOptions(column_names=header, block_size=_BLOCK_BYTES),
            parse_options=pacsv.ParseOptions(delimiter=",", ignore_empty_lines=True),
            convert_options=pacsv.ConvertOptions(
                column_types=types, null_values=[""], strings_can_be_null=False,
                quoted_strings_can_be_null=False, check_utf8=True))
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return None
    columns, problem = arrow_columns(parsed, kinds)
    if problem is not None:
        return None
    return Table(columns, tuple(header), parsed.num_rows, owned=True)


def _head(buf: pa.Buffer) -> bytes:
    """The start of the file, up to the end of its header line."""
    head = buf[:_HEAD_BYTES].to_pybytes()
    if len(buf) > len(head) and re.search(rb"\S[^\n]*\n", head) is None:
        return buf.to_pybytes()
    return head


def read_table(data: bytes | pa.Buffer, *, name: str, kinds: Mapping[str, ColumnKind],
               required: Sequence[str]) -> Table:
    """Parse a CSV table with a header line.

    Parameters
    ----------
    data:
        File contents (a memory-mapped file's Arrow buffer is read without a copy).
    name:
        File name for error messages.
    kinds:
        Every allowed column and its kind; other columns are an error.
    required:
        Columns that must be present.

    Raises
    ------
    FormatError
        Naming the line, column and value that do not fit.
    """
    buf = data if isinstance(data, pa.Buffer) else pa.py_buffer(data)
    header, body_start = _header(_head(buf), name=name)
    check_columns(header, kinds, required, where=f"{name} line 1")
    if _NON_SPACE.search(memoryview(buf), body_start) is None:
        empty: dict[str, Column | pa.ChunkedArray] = {
            c: (np.zeros(0, dtype=np.str_) if kinds[c] == "str" else np.zeros(0)) for c in header}
        return Table(empty, tuple(header), 0)
    table = _fast(buf[body_start:], header, kinds)
    if table is not None:
        return table
    raw = buf.to_pybytes()
    return _careful(_decode(raw, name=name), header, kinds, name=name)


_TAIL_BYTES = 1 << 12


def without_cut_last_line(data: pa.Buffer, *, name: str, repair: bool) -> pa.Buffer:
    """``data`` checked for a last line cut short (a copy or a recording stopped mid-line).

    Such a line has no newline after it and fewer fields than the header: it raises
    :class:`~hrtls.errors.FormatError` naming the line, or with ``repair`` it is dropped with a
    :class:`~hrtls.errors.RepairWarning`.
    """
    if not len(data) or data[len(data) - 1:].to_pybytes() == b"\n":
        return data
    tail = data[max(0, len(data) - _TAIL_BYTES):].to_pybytes()
    cut_at = tail.rfind(b"\n")
    if cut_at < 0:
        return data  # a single line (the header) or a line longer than the tail
    start = len(data) - len(tail) + cut_at + 1
    header = data[:min(len(data), _TAIL_BYTES)].to_pybytes().split(b"\n", 1)[0]
    have, fields = tail[cut_at + 1:].count(b",") + 1, header.count(b",") + 1
    if have >= fields or not tail[cut_at + 1:].strip():
        return data
    line = int(np.count_nonzero(np.frombuffer(data, dtype=np.uint8) == ord("\n"))) + 1
    problem = f"last line cut short ({have} of {fields} fields, no newline at the end)"
    if not repair:
        raise FormatError(problem, where=f"{name} line {line}", expected="complete rows",
                          hint="pass repair=True to drop the cut line")
    warnings.warn(f"{name} line {line}: {problem}; dropped it", RepairWarning, stacklevel=4)
    return data[:start]


# --------------------------------------------------------------------------------------------
# Writing CSV
# --------------------------------------------------------------------------------------------
def _needs_quotes(table: pa.Table) -> bool:
    return any(pc.any(pc.match_substring_regex(table.column(c), '[,"\r\n]')).as_py()
               for c in table.column_names if pa.types.is_string(table.schema.field(c).type))


def csv_bytes(table: pa.Table) -> bytes:
    """``table`` as CSV (see :func:`write_csv`)."""
    out = pa.BufferOutputStream()
    write_csv(table, out)
    return bytes(out.getvalue())


def write_csv(table: pa.Table, sink: pa.NativeFile) -> None:
    """``table`` as CSV into ``sink``, batch by batch.

    A plain header line, nulls as empty fields, text quoted only if needed. Numbers are
    written with the fewest digits that read back to the same float64.
    """
    sink.write((",".join(table.column_names) + "\n").encode("utf-8"))
    if table.num_rows:
        style = "needed" if _needs_quotes(table) else "none"
        pacsv.write_csv(table, sink, write_options=pacsv.WriteOptions(
            include_header=False, quoting_style=style, batch_size=1 << 16))


ArrowColumn: TypeAlias = NDArray[np.generic] | pa.Array
"""A column to write: numpy (numbers or text), or an Arrow array taken as it is."""


def arrow_from_columns(columns: Mapping[str, ArrowColumn]) -> pa.Table:
    """Arrow table of numpy columns: numbers as float64 (NaN as null), anything else as text.

    Built from buffers: :func:`pyarrow.array` and :func:`pyarrow.table` would import pandas.
    Arrow arrays are kept as they are.
    """
    arrays = []
    for values in columns.values():
        if isinstance(values, pa.Array):
            arrays.append(values)
            continue
        arr: NDArray[np.generic] = np.asarray(values)
        arrays.append(_float_array(arr) if arr.dtype.kind in "fiub" else _text_array(arr))
    return pa.Table.from_arrays(arrays, names=list(columns))


def labelled_text(indices: NDArray[np.integer], labels: Sequence[str]) -> pa.Array:
    """The text column ``labels[indices]`` (a few labels over many rows), made in Arrow."""
    index = np.ascontiguousarray(indices, dtype=np.int32)
    if len(index) and (index.min() < 0 or index.max() >= len(labels)):
        raise IndexError(f"label index outside 0..{len(labels) - 1}")
    codes = pa.Array.from_buffers(pa.int32(), len(index), [None, pa.py_buffer(index)])
    dictionary = _text_array(np.asarray(list(labels), dtype=np.str_))
    return pa.DictionaryArray.from_arrays(codes, dictionary).dictionary_decode()


def _float_array(values: NDArray[np.generic]) -> pa.Array:
    data = np.ascontiguousarray(values, dtype=np.float64)
    nan = np.isnan(data)
    validity = pa.py_buffer(np.packbits(~nan, bitorder="little")) if nan.any() else None
    return pa.Array.from_buffers(pa.float64(), len(data), [validity, pa.py_buffer(data)],
                                 null_count=int(np.count_nonzero(nan)))


def _text_array(values: NDArray[np.generic]) -> pa.Array:
    encoded = [v.encode("utf-8") for v in values.astype(np.str_).tolist()]
    offsets = np.zeros(len(encoded) + 1, dtype=np.int32)
    np.cumsum([len(e) for e in encoded], out=offsets[1:])
    return pa.Array.from_buffers(pa.string(), len(encoded),
                                 [None, pa.py_buffer(offsets), pa.py_buffer(b"".join(encoded))])


def format_table(columns: Mapping[str, ArrowColumn]) -> str:
    """Render columns as CSV text with a header line (NaN in a numeric column: empty field)."""
    return csv_bytes(arrow_from_columns(columns)).decode("utf-8")
