"""Shared parsing helpers of the format readers: sources, text, numbers, streams and units.

* :class:`Source` gives uniform access to a folder, a zip (read in memory, never extracted, with
  unsafe member names refused and the total uncompressed size capped) or a single file.
* :func:`parse_float_rows` parses many delimited rows at once with numpy's C parser and, only
  when that fails, walks the rows one by one to name the first bad line and field.
* :func:`check_stream` enforces finite values and increasing time, naming the file line of the
  first problem, or repairs (``repair=True``) with a :class:`~hrtls.errors.RepairWarning`.
* :func:`to_si` converts sensor units, either as stated or guessed by :mod:`hrtls.units`, and
  records every conversion in the session notes.
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.data.validation import FloatArray, repair_time_order
from hrtls.errors import FormatError, InputError, RepairWarning
from hrtls.units import (
    DEG,
    G_TO_M_S2,
    GAUSS_TO_UT,
    HPA_TO_PA,
    NT_TO_UT,
    TIME_SCALES_S,
    suspect_accelerometer_unit,
    suspect_gyroscope_unit,
    suspect_magnetometer_unit,
)

IntArray = NDArray[np.int64]

# --------------------------------------------------------------------------------------------
# Text
# --------------------------------------------------------------------------------------------


def decode_text(data: bytes, *, where: str, lenient: bool = False) -> str:
    """Decode UTF-8 (a BOM is dropped).

    With ``lenient`` undecodable bytes become U+FFFD (used for logfiles whose only free text,
    e.g. WiFi names, is not needed); otherwise they raise :class:`FormatError` with the line.
    """
    if b"\x00" in data[:4096] and not lenient:
        line = data[: data.index(b"\x00")].count(b"\n") + 1
        raise FormatError("NUL byte (binary data)", where=f"{where} line {line}",
                          expected="a text file")
    try:
        return data.decode("utf-8-sig", errors="replace" if lenient else "strict")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise FormatError(f"byte {exc.start} is not valid UTF-8", where=f"{where} line {line}",
                          expected="a UTF-8 (or ASCII) text file") from None


def csv_rows(text: str, *, where: str) -> list[list[str]]:
    """Rows of a small quoted CSV (metadata, landmarks), blank lines kept as ``[]``.

    Lines are split first, so a stray carriage return cannot confuse :mod:`csv`; a quoted
    field therefore cannot span lines.
    """
    rows: list[list[str]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        try:
            rows.extend(csv.reader([line]) if line else [[]])
        except csv.Error as exc:
            raise FormatError(f"not CSV ({exc})", where=f"{where} line {n}",
                              expected="comma-separated fields, quotes closed on the line"
                              ) from None
    return rows


def content_rows(lines: Sequence[str], *, start: int = 0, comment_chars: str = ""
                 ) -> tuple[list[str], IntArray]:
    """Non-blank, non-comment lines from ``lines[start:]`` and their 1-based line numbers.

    Only lines that start with blank space are inspected one by one, so large files stay fast.
    """
    body = list(lines[start:])
    if not body:
        return [], np.zeros(0, dtype=np.int64)
    first_chars = [ln[:1] for ln in body]
    if not set(first_chars) & {"", " ", "\t", *comment_chars}:
        return body, np.arange(start + 1, start + 1 + len(body), dtype=np.int64)
    heads = np.array(first_chars)
    drop = heads == ""
    for c in comment_chars:
        drop |= heads == c
    for i in np.flatnonzero((heads == " ") | (heads == "\t")).tolist():
        stripped = body[i].strip()
        drop[i] = not stripped or (bool(comment_chars) and stripped[0] in comment_chars)
    if not drop.any():
        return body, np.arange(start + 1, start + 1 + len(body), dtype=np.int64)
    keep = np.flatnonzero(~drop)
    return [body[i] for i in keep.tolist()], keep.astype(np.int64) + start + 1


def split_fields(line: str, sep: str | None) -> list[str]:
    """Fields of one line (``sep=None``: runs of whitespace)."""
    return line.split() if sep is None else line.split(sep)


def parse_float_rows(rows: Sequence[str], *, sep: str | None, usecols: Sequence[int],
                     line_numbers: IntArray, where: str, field_names: Sequence[str],
                     expected: str, exact_fields: int | None = None,
                     empty_as_nan: bool = False, malformed_as_nan: bool = False) -> FloatArray:
    """Parse numeric fields of many delimited rows into an (N, len(usecols)) array.

    The fast path is numpy's C parser over all rows at once. When it fails, the rows are
    checked one by one and the first bad one raises :class:`FormatError` naming the file line,
    the field and what was expected. Non-finite values (``nan``, ``inf``) parse; the stream
    checks decide about them.

    Parameters
    ----------
    rows:
        The lines (without line breaks).
    sep:
        Field separator, or None for whitespace.
    usecols:
        Indices of the numeric fields to return.
    line_numbers:
        1-based file line of each row (for messages).
    where:
        The file, for messages.
    field_names:
        Name of each used field (for messages).
    expected:
        What a row should look like (for messages), e.g. ``"ACCE;app_t;sensor_t;x;y;z"``.
    exact_fields:
        When given, every row must have exactly this many fields.
    empty_as_nan:
        Read empty fields as NaN instead of rejecting them.
    malformed_as_nan:
        Read a row with too few fields or a field that is not a number as NaN (announced by a
        :class:`~hrtls.errors.RepairWarning` naming its lines) for the stream repair to drop.
    """
    cols = list(usecols)
    if len(rows) == 0:
        return np.zeros((0, len(cols)))
    block = "\n".join(rows)
    # with a separator, a field count per row is checked by counting separators (C speed),
    # so only the used columns are converted
    all_cols = exact_fields is not None and sep is None
    counts_ok = (exact_fields is None or sep is None
                 or block.count(sep) == len(rows) * (exact_fields - 1))
    if counts_ok:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                values = np.loadtxt(io.StringIO(block), delimiter=sep,
                                    usecols=None if all_cols else cols,
                                    dtype=np.float64, ndmin=2, comments=None)
            if all_cols:
                if values.shape == (len(rows), exact_fields):
                    return np.ascontiguousarray(values[:, cols])
            elif values.shape == (len(rows), len(cols)):
                return values
        except (ValueError, IndexError, TypeError):
            pass
    return _parse_rows_slowly(rows, sep=sep, usecols=cols, line_numbers=line_numbers,
                              where=where, field_names=field_names, expected=expected,
                              exact_fields=exact_fields, empty_as_nan=empty_as_nan,
                              malformed_as_nan=malformed_as_nan)


def _parse_rows_slowly(rows: Sequence[str], *, sep: str | None, usecols: list[int],
                       line_numbers: IntArray, where: str, field_names: Sequence[str],
                       expected: str, exact_fields: int | None, empty_as_nan: bool,
                       malformed_as_nan: bool = False) -> FloatArray:
    """Row-by-row parser: the exact location of the first problem, or the values.

    With ``malformed_as_nan`` such rows become NaN instead, named in one warning.
    """
    out = np.empty((len(rows), len(usecols)))
    need = max(usecols) + 1
    malformed: list[str] = []
    for k, row in enumerate(rows):
        try:
            out[k] = _parse_row(split_fields(row, sep), usecols=usecols, need=need,
                                field_names=field_names, expected=expected,
                                exact_fields=exact_fields, empty_as_nan=empty_as_nan)
        except FormatError as exc:
            if not malformed_as_nan:
                raise FormatError(exc.problem, where=f"{where} line {int(line_numbers[k])}",
                                  expected=exc.expected) from None
            out[k] = np.nan
            malformed.append(f"line {int(line_numbers[k])}: {exc.problem}")
    if malformed:
        warnings.warn(f"{where}: {len(malformed)} malformed row(s) read as missing values ("
                      + "; ".join(malformed[:5]) + (" ..." if len(malformed) > 5 else "") + ")",
                      RepairWarning, stacklevel=4)
    return out


def _parse_row(fields: list[str], *, usecols: list[int], need: int, field_names: Sequence[str],
               expected: str, exact_fields: int | None, empty_as_nan: bool) -> FloatArray:
    """The used fields of one row as numbers; FormatError (without a place) when it is not."""
    if exact_fields is not None and len(fields) != exact_fields:
        raise FormatError(f"{len(fields)} field(s)",
                          expected=f"{exact_fields} fields ({expected})")
    if len(fields) < need:
        raise FormatError(f"{len(fields)} field(s)",
                          expected=f"at least {need} fields ({expected})")
    out = np.empty(len(usecols))
    for j, c in enumerate(usecols):
        text = fields[c].strip()
        if not text and empty_as_nan:
            out[j] = np.nan
            continue
        try:
            out[j] = float(text)
        except ValueError:
            shown = text if len(text) <= 40 else text[:37] + "..."
            raise FormatError(f"{field_names[j]} is {shown!r}",
                              expected=f"a number ({expected})") from None
    return out


# --------------------------------------------------------------------------------------------
# Streams: finite values and time order
# --------------------------------------------------------------------------------------------


def check_stream(t: FloatArray, columns: Sequence[np.ndarray], *, lines: IntArray, where: str,
                 repair: bool, strict: bool = True
                 ) -> tuple[FloatArray, list[np.ndarray]]:
    """Check (or repair) a stream read from a file: finite values, increasing time.

    Without ``repair`` the first non-finite row or the first time step that is not increasing
    (``strict``) / goes backwards (not ``strict``) raises :class:`InputError` naming the file
    line. With ``repair`` non-finite rows are dropped, backward times sorted and, when
    ``strict``, duplicated times merged (averaged), each announced by a
    :class:`~hrtls.errors.RepairWarning`.

    Returns
    -------
    The (possibly repaired) time and columns.
    """
    if len(t) == 0:
        return t, list(columns)
    keep = np.isfinite(t)
    for col in columns:
        if np.issubdtype(col.dtype, np.number):
            keep &= np.isfinite(col).reshape(len(col), -1).all(axis=1)
    if not np.all(keep):
        first = int(np.flatnonzero(~keep)[0])
        n_bad = int(np.count_nonzero(~keep))
        if not repair:
            raise InputError(f"{n_bad} row(s) with a non-finite value (nan/inf), the first here",
                             where=f"{where} line {int(lines[first])}",
                             expected="finite numbers",
                             hint="pass repair=True to drop such rows with a warning")
        warnings.warn(f"{where}: dropped {n_bad} row(s) with non-finite values "
                      f"(first at line {int(lines[first])})", RepairWarning, stacklevel=3)
        t = t[keep]
        columns = [c[keep] for c in columns]
        lines = lines[keep]
    if len(t) < 2:
        return t, list(columns)
    dt = np.diff(t)
    bad = dt <= 0 if strict else dt < 0
    if not np.any(bad):
        return t, list(columns)
    i = int(np.flatnonzero(bad)[0]) + 1
    if not repair:
        kind = (f"time repeats ({t[i]:.9g} s)" if dt[i - 1] == 0
                else f"time goes backwards by {-dt[i - 1]:.6g} s (to {t[i]:.9g} s)")
        raise InputError(kind, where=f"{where} line {int(lines[i])}",
                         expected="strictly increasing time" if strict else
                         "non-decreasing time",
                         hint="pass repair=True to sort and merge duplicates with a warning")
    t2, cols2 = repair_time_order(t, list(columns), where=f"{where} (first at line "
                                  f"{int(lines[i])})", strict=strict)
    return t2, cols2


# --------------------------------------------------------------------------------------------
# Units
# --------------------------------------------------------------------------------------------

Quantity = Literal["accel", "gyro", "mag", "pressure"]

_FACTORS: dict[str, dict[str, float]] = {
    "accel": {"m/s^2": 1.0, "g": G_TO_M_S2, "mg": G_TO_M_S2 / 1000.0},
    "gyro": {"rad/s": 1.0, "deg/s": DEG, "mrad/s": 1e-3},
    "mag": {"ut": 1.0, "gauss": GAUSS_TO_UT, "mgauss": GAUSS_TO_UT / 1000.0, "nt": NT_TO_UT,
            "mt": 1000.0, "t": 1e6},
    "pressure": {"pa": 1.0, "hpa": HPA_TO_PA, "mbar": HPA_TO_PA, "kpa": 1000.0,
                 "bar": 1e5},
}
_SI_NAME = {"accel": "m/s^2", "gyro": "rad/s", "mag": "uT", "pressure": "Pa"}
_LABEL = {"accel": "accelerometer", "gyro": "gyroscope", "mag": "magnetometer",
          "pressure": "pressure"}
_SUSPECT: dict[str, Callable[[FloatArray], str | None]] = {
    "accel": suspect_accelerometer_unit, "gyro": suspect_gyroscope_unit,
    "mag": suspect_magnetometer_unit}


def normalize_unit(unit: str) -> str:
    """Canonical spelling of a unit (``'m/s²'`` -> ``'m/s^2'``, ``'µT'`` -> ``'ut'``, ...)."""
    u = unit.strip().replace("µ", "u").replace("μ", "u").replace("²", "^2")
    u = u.replace("°", "deg").replace(" ", "").replace("**", "^")
    low = u.lower()
    if low in ("m/s^2", "m/s2", "ms^-2", "ms-2", "m·s^-2", "m*s^-2", "mps2"):
        return "m/s^2"
    if low in ("deg/s", "degree/s", "degrees/s", "dps", "deg/sec"):
        return "deg/s"
    if low in ("rad/s", "rad/sec", "rps"):
        return "rad/s"
    if low in ("millig", "milli-g"):
        return "mg"
    if low == "mg" and u == "mG":
        return "mgauss"
    return low


def unit_factor(quantity: Quantity, unit: str, *, where: str) -> float:
    """SI factor of a stated unit, or :class:`InputError` naming the accepted ones."""
    table = _FACTORS[quantity]
    key = normalize_unit(unit)
    if quantity != "accel" and key == "g":
        key = "gauss" if quantity == "mag" else key
    if key not in table:
        raise InputError(f"unknown {_LABEL[quantity]} unit {unit!r}", where=where,
                         expected=f"one of {', '.join(table)}")
    return table[key]


def to_si(values: FloatArray, quantity: Quantity, unit: str, *, where: str,
          notes: list[str]) -> FloatArray:
    """Convert ``values`` to SI (``unit`` stated, or ``"auto"`` to guess from the values).

    ``"auto"`` keeps values that look SI and converts those that :mod:`hrtls.units` recognizes
    as another unit (g, milli-g, deg/s, gauss, nT); every conversion is added to ``notes``.
    """
    if unit == "auto":
        suspect = _SUSPECT.get(quantity)
        message = suspect(values) if suspect is not None and values.ndim == 2 else None
        if not message:
            return values
        found = re.search(r"_unit='([^']+)'", message)
        if found is None:  # pragma: no cover - units.py always names the reader option
            raise InputError(message, where=where, expected=f"SI ({_SI_NAME[quantity]})")
        unit = found.group(1)
        factor = unit_factor(quantity, unit, where=where)
        notes.append(f"{where}: {_LABEL[quantity]} converted from {unit} "
                     f"(guessed: {message.split(',')[0]})")
        return values * factor
    factor = unit_factor(quantity, unit, where=where)
    if factor != 1.0:
        notes.append(f"{where}: {_LABEL[quantity]} converted from {unit} (stated)")
    return values * factor


def time_scale(t_raw: FloatArray, unit: str, *, where: str) -> tuple[float, str]:
    """Seconds per tick of raw timestamps: stated (``s``, ``ms``, ``us``, ``ns``) or guessed.

    ``"auto"`` tries s, ms and ns (in that order) and takes the first whose median sample
    spacing is a plausible sensor period, 0.2 ms to 0.6 s (rates of 1.7 Hz to 5 kHz). The band
    is narrower than :func:`hrtls.units.guess_time_scale`'s so that 500 Hz in ms (step 2) is
    not read as 0.5 Hz in s; microseconds are never guessed (pass ``time_unit="us"``).
    """
    if unit != "auto":
        if unit not in TIME_SCALES_S:
            raise InputError(f"unknown time unit {unit!r}", where=where,
                             expected=f"one of auto, {', '.join(TIME_SCALES_S)}")
        return TIME_SCALES_S[unit], unit
    steps = np.diff(t_raw)
    steps = steps[steps > 0]
    if len(steps) == 0:
        raise InputError("cannot guess the time unit from fewer than 2 increasing timestamps",
                         where=where, expected="more samples, or a stated time_unit")
    median = float(np.median(steps))
    for name in ("s", "ms", "ns"):
        if 2e-4 <= median * TIME_SCALES_S[name] <= 0.6:
            return TIME_SCALES_S[name], name
    raise InputError(f"median time step {median:.6g} fits no time unit", where=where,
                     expected="a sensor period of 0.2 ms to 0.6 s in s, ms or ns",
                     hint="pass time_unit='s'|'ms'|'us'|'ns'")


# --------------------------------------------------------------------------------------------
# CSV with a header line
# --------------------------------------------------------------------------------------------


@dataclass
class HeaderCsv:
    """A delimited text table: its header names, data rows and their 1-based line numbers."""

    where: str
    header: list[str]
    rows: list[str]
    lines: IntArray
    sep: str
    decimal_comma: bool = False

    def index(self, name: str) -> int | None:
        """Column index of ``name`` (case-insensitive), or None."""
        low = [h.lower() for h in self.header]
        return low.index(name.lower()) if name.lower() in low else None

    def require(self, *names: str) -> list[int]:
        """Indices of columns that must exist, or :class:`FormatError` naming the missing."""
        idx = [self.index(n) for n in names]
        missing = [n for n, i in zip(names, idx, strict=True) if i is None]
        if missing:
            raise FormatError(f"missing column(s) {', '.join(missing)} (header: "
                              f"{self.sep.join(self.header)})", where=f"{self.where} line 1",
                              expected=f"columns {', '.join(names)}")
        return [i for i in idx if i is not None]

    def floats(self, names: Sequence[str]) -> FloatArray:
        """The named columns as an (N, k) array; empty fields read as NaN."""
        cols = self.require(*names)
        rows = self.rows
        if self.decimal_comma:
            rows = [r.replace(",", ".") for r in rows]
        return parse_float_rows(rows, sep=self.sep, usecols=cols, line_numbers=self.lines,
                                where=self.where, field_names=list(names),
                                expected=self.sep.join(self.header),
                                exact_fields=len(self.header), empty_as_nan=True)


def _unquote(cell: str) -> str:
    cell = cell.strip()
    if len(cell) >= 2 and cell[0] == cell[-1] and cell[0] in "\"'":
        cell = cell[1:-1]
    return cell.strip()


def read_header_csv(data: bytes, *, where: str, sep: str | None = None) -> HeaderCsv:
    """Split a delimited table with a header line (separator guessed from the header).

    The separator is the first of tab, ``;`` and ``,`` found in the header; with ``;``
    decimal commas in the data (``1,5``) are read as decimal points. Quotes around header
    names and values are removed; blank lines are skipped.
    """
    text = decode_text(data, where=where)
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise FormatError("file is empty", where=where, expected="a header line and rows")
    head = lines[first]
    if sep is None:
        sep = next((s for s in ("\t", ";", ",") if s in head), ",")
    header = [_unquote(c) for c in head.split(sep)]
    if len(header) > 1 and header[-1] == "":
        header = header[:-1]
    rows, numbers = content_rows(lines, start=first + 1)
    if rows and len(rows[0].split(sep)) == len(header) + 1 and rows[0].rstrip().endswith(sep):
        rows = [r.rstrip() for r in rows]
        rows = [r[: -len(sep)] if r.endswith(sep) else r for r in rows]
    if any('"' in r for r in rows[:20]):
        rows = [r.replace('"', "") for r in rows]
    decimal_comma = sep == ";" and any("," in r for r in rows[:20])
    return HeaderCsv(where, header, rows, numbers, sep, decimal_comma)
