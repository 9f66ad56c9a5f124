"""Interval tables ``t_start,t_end,...``: activity labels, calibration positions, rate tests.

One reader for every such file, built on :func:`hrtls.io.csvtable.read_table`, so malformed
values are reported with their line and column and every interval must satisfy
``t_start < t_end`` (both finite, s).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import FormatError, InputError
from hrtls.io.csvtable import ColumnKind, Table, read_table


@dataclass(frozen=True, slots=True)
class Intervals:
    """Parsed intervals: times (s), the other columns, and the file line of each row."""

    t_start: NDArray[np.float64]
    t_end: NDArray[np.float64]
    table: Table
    line: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.t_start)


def read_intervals(path: Path, *, columns: Mapping[str, ColumnKind]) -> Intervals:
    """Read ``t_start,t_end`` plus ``columns`` (all required) from a CSV file.

    Raises
    ------
    InputError
        When the file cannot be read.
    FormatError
        Naming the line of a malformed value or of an interval with ``t_end <= t_start``.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"cannot be read ({exc.strerror})", where=str(path),
                         expected="a readable CSV file") from None
    kinds: dict[str, ColumnKind] = {"t_start": "float", "t_end": "float", **columns}
    table = read_table(data, name=str(path), kinds=kinds, required=tuple(kinds))
    text = data.decode("utf-8-sig")
    lines = text.splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.strip())
    line = np.array([i + 1 for i in range(header + 1, len(lines))
                     if lines[i].strip().strip(",").strip()], dtype=np.int64)[: table.n_rows]
    t0, t1 = table.float("t_start"), table.float("t_end")
    bad = ~(t1 > t0)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise FormatError(f"interval {t0[k]}..{t1[k]}", where=f"{path} line {line[k]}",
                          expected="t_start < t_end")
    return Intervals(t0, t1, table, line)
