"""Oxford step counter validation recordings: a phone accelerometer with a ground-truth count.

Source: the ``validation/`` folder of https://github.com/Oxford-step-counter/DataSet (CC BY
4.0). Files are named ``<user>_<placement>_<unix start ms>.csv``; nothing is downloaded here.

Format (no header), one sample per line::

    timestamp_ns_since_boot, acc_x, acc_y, acc_z, app_steps, truth_steps, hardware_steps

The accelerometer is in m/s^2 including gravity, in the (undocumented) Android device frame;
there is no gyroscope or magnetometer. Column 6 is the step count of a ground-truth device;
it rises by one per step, so the rows where it rises give approximate step times (the
device's latency is unknown).

Known defects of the published files and what is done about each. The two below carry no
information, so they are repaired by default, with a :class:`~hrtls.errors.RepairWarning`:

* ``hand``: the first row is all zeros (accelerometer 0, 0, 0): *the row is dropped* (all-zero
  rows at the start of a file; later ones need ``repair=True``).
* ``armband`` (1) and ``neckpouch`` (2): a timestamp equal to (not greater than) the previous
  one. In these files the row is an exact copy of the previous row: *the copy is dropped*.

Other defects raise :class:`~hrtls.errors.InputError` naming the file and line unless
``repair=True``: with it, rows are sorted by timestamp (stable) and rows sharing a timestamp
are merged (accelerometer averaged, step counters taken from the last row), all-zero rows are
dropped, and malformed lines (a cut last line, a partial line, an empty or non-finite field)
are dropped.

The 220 ms gaps in ``armband`` and ``neckpouch`` are real gaps in the recording, not defects;
they are kept and listed in ``meta.notes``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta
from hrtls.datasets._common import FloatArray, dataset_dir, numeric_csv, require_file, warn_repair
from hrtls.errors import FormatError, InputError

PLACEMENTS = ("hand", "frontpocket", "backpocket", "neckpouch", "bag", "armband")
"""Placements in the validation set; ``frontpocket`` and ``backpocket`` are the waist-like ones."""

_NAME = re.compile(r"^(?P<user>[^_]+)_(?P<placement>[A-Za-z]+)_(?P<start_ms>\d+)\.csv$")
_GAP_REPORT_S = 0.1


@dataclass(frozen=True, slots=True, eq=False)
class OxfordRecording:
    """One Oxford validation recording.

    Attributes
    ----------
    session:
        Accelerometer only (m/s^2, device frame), t from the first sample in s.
    placement:
        Where the phone was: one of :data:`PLACEMENTS` (from the file name).
    total_steps:
        Ground-truth steps: last minus first value of column 6.
    step_times_s:
        Times of the rows where the ground-truth counter rises (one entry per step counted),
        s on the session clock.
    app_steps:
        Steps counted by the recording app's own algorithm (last minus first of column 5).
    path:
        The file that was read.
    """

    session: Session
    placement: str
    total_steps: int
    step_times_s: FloatArray
    app_steps: int
    path: Path


def list_recordings(root: str | Path) -> list[Path]:
    """CSV recordings under ``root`` (the ``oxford_step`` folder, or a folder containing it)."""
    folder = dataset_dir(root, "oxford_step")
    return sorted(p for p in folder.glob("*.csv") if _NAME.match(p.name))


def _merge_equal_times(ns: np.ndarray, rows: FloatArray) -> tuple[np.ndarray, FloatArray, int, int]:
    """Merge rows with equal timestamps; returns (ns, rows, n_exact_copies, n_averaged)."""
    unique, start, counts = np.unique(ns, return_index=True, return_counts=True)
    if len(unique) == len(ns):
        return ns, rows, 0, 0
    out = rows[start].copy()
    n_copies = n_avg = 0
    for i in np.flatnonzero(counts > 1):
        group = rows[start[i]:start[i] + counts[i]]
        if np.all(group == group[0]):
            n_copies += counts[i] - 1
        else:
            n_avg += counts[i] - 1
            out[i, 0:3] = group[:, 0:3].mean(axis=0)
            out[i, 3:] = group[-1, 3:]
    return unique, out, n_copies, n_avg


def _drop_zero_rows(ns: np.ndarray, rows: FloatArray, lines: np.ndarray, *, file_name: str,
                    repair: bool, notes: list[str]
                    ) -> tuple[np.ndarray, FloatArray, np.ndarray]:
    """Rows whose accelerometer is all zero: dropped (warned) if leading or with ``repair``.

    Leading rows come before the sensor's first sample; others are an error without ``repair``.
    """
    zero = np.all(rows[:, 0:3] == 0.0, axis=1)
    leading = np.logical_and.accumulate(zero)
    if np.any(zero):
        first = int(lines[np.flatnonzero(zero)[0]])
        if not repair and np.any(zero & ~leading):
            inner = int(lines[np.flatnonzero(zero & ~leading)[0]])
            raise InputError(f"{int(zero.sum())} all-zero accelerometer row(s), first at line "
                             f"{first}", where=f"{file_name} line {inner}",
                             expected="a real accelerometer sample (|a| near 9.8 m/s^2)",
                             hint="pass repair=True to drop such rows with a warning")
        warn_repair(f"{file_name}: dropped {int(zero.sum())} all-zero row(s) "
                    f"(line(s) {', '.join(str(v) for v in lines[zero][:5])})")
        notes.append(f"repair: dropped {int(zero.sum())} all-zero row(s) starting at line {first}")
        ns, rows, lines = ns[~zero], rows[~zero], lines[~zero]
    return ns, rows, lines


def _increasing_times(ns: np.ndarray, rows: FloatArray, lines: np.ndarray, *, file_name: str,
                      repair: bool, notes: list[str]) -> tuple[np.ndarray, FloatArray]:
    """Non-increasing timestamps: sorted and merged with a warning, or an error.

    They are repaired with ``repair``, or without it when every one is an exact copy of the row
    before it (no information is lost).
    """
    step = np.diff(ns)
    bad = np.flatnonzero(step <= 0)
    if len(bad):
        copy = (step[bad] == 0) & np.all(rows[bad + 1] == rows[bad], axis=1)
        if not repair and not np.all(copy):
            bad = bad[~copy]
            first_line = int(lines[bad[0] + 1])
            kind = "equals" if step[bad[0]] == 0 else "is before"
            raise InputError(f"timestamp {kind} the previous one ({len(bad)} such row(s) in the "
                             "file)", where=f"{file_name} line {first_line}",
                             expected="strictly increasing timestamps",
                             hint="pass repair=True to sort and merge them with a warning")
        order = np.argsort(ns, kind="stable")
        n_back = int(np.count_nonzero(step < 0))
        largest_s = float(-step.min()) * 1e-9 if n_back else 0.0
        ns, rows = ns[order], rows[order]
        ns, rows, n_copies, n_avg = _merge_equal_times(ns, rows)
        actions = [text for count, text in (
            (n_back, f"sorted {n_back} backward step(s) (largest {largest_s:.3g} s)"),
            (n_copies, f"dropped {n_copies} exact duplicate row(s)"),
            (n_avg, f"merged {n_avg} row(s) with equal time (accelerometer averaged)"))
            if count]
        message = (f"{file_name}: non-increasing timestamps at line(s) "
                   f"{', '.join(str(int(lines[i + 1])) for i in bad[:5])}: "
                   + ", ".join(actions))
        warn_repair(message)
        notes.append("repair: " + message.split(": ", 1)[1])
    return ns, rows


def _step_counts(t: FloatArray, rows: FloatArray, *, file_name: str
                 ) -> tuple[FloatArray, int, int]:
    """``(ground-truth step times s, ground-truth steps, app steps)`` from the counters."""
    truth = rows[:, 4]
    if np.any(truth != np.round(truth)) or np.any(np.diff(truth) < 0):
        raise FormatError("ground-truth step counter is not a non-decreasing integer",
                          where=f"{file_name} column 6", expected="a running step count")
    rises = np.diff(truth).astype(np.int64)
    idx = np.flatnonzero(rises > 0)
    step_times = np.repeat(t[idx + 1], rises[idx])
    total_steps = int(truth[-1] - truth[0])
    app_steps = int(rows[-1, 3] - rows[0, 3])
    return step_times, total_steps, app_steps


def load_recording(path: str | Path, *, repair: bool = False) -> OxfordRecording:
    """Load one recording.

    Parameters
    ----------
    path:
        A ``<user>_<placement>_<unix ms>.csv`` file.
    repair:
        Drop all-zero rows, sort backward timestamps and merge rows with equal timestamps,
        each announced with a :class:`~hrtls.errors.RepairWarning`. Without it such defects
        raise :class:`~hrtls.errors.InputError` naming the file and line.
    """
    file = require_file(Path(path), "an Oxford step counter CSV file")
    parsed = numeric_csv(file, columns=7, repair=repair)
    table = parsed.values
    ns = table[:, 0].astype(np.int64)
    if not np.array_equal(ns.astype(np.float64), table[:, 0]):
        raise FormatError("timestamps are not integers", where=file.name,
                          expected="integer nanoseconds since boot in column 1")
    rows = table[:, 1:]
    lines = parsed.lines
    notes: list[str] = [] if parsed.dropped is None else ["repair: " + parsed.dropped]

    ns, rows, lines = _drop_zero_rows(ns, rows, lines, file_name=file.name, repair=repair,
                                      notes=notes)
    ns, rows = _increasing_times(ns, rows, lines, file_name=file.name, repair=repair,
                                 notes=notes)
    if len(ns) < 2:
        raise FormatError(f"{len(ns)} usable rows", where=file.name, expected="at least 2 rows")

    t = (ns - ns[0]).astype(np.float64) * 1e-9
    gaps = np.flatnonzero(np.diff(t) > _GAP_REPORT_S)
    for i in gaps:
        notes.append(f"gap of {1e3 * (t[i + 1] - t[i]):.0f} ms after t = {t[i]:.3f} s")

    try:
        step_times, total_steps, app_steps = _step_counts(t, rows, file_name=file.name)
    except FormatError as exc:
        sorted_back = [n for n in notes if "backward step" in n]
        if not sorted_back:
            raise
        raise FormatError(f"{exc.problem} once the times were sorted ({sorted_back[0][8:]})",
                          where=exc.where, expected="a clock that does not jump back (cut the "
                          "file where it does)") from None

    match = _NAME.match(file.name)
    placement = match.group("placement").lower() if match else "unknown"
    origin = float(match.group("start_ms")) / 1000.0 if match else None
    notes.insert(0, "Accelerometer only, m/s^2 including gravity, Android device frame "
                    "(not documented by the source).")
    if origin is not None:
        notes.append("time_origin_unix_s is the start time in the file name; its offset to "
                     "the first sample is not documented (assume ~1 s accuracy).")
    meta = SessionMeta(
        placement=placement,
        time_origin_unix_s=origin,
        source={
            "dataset": "oxford_step",
            "repository": "https://github.com/Oxford-step-counter/DataSet",
            "file": str(file),
            "user": match.group("user") if match else None,
            "first_timestamp_ns_since_boot": int(ns[0]),
        },
        notes=notes,
    )
    imu = ImuStream(accel=SensorSeries(t, rows[:, 0:3], f"{file.name} accelerometer"))
    return OxfordRecording(session=Session(meta=meta, imu=imu), placement=placement,
                           total_steps=total_steps, step_times_s=step_times, app_steps=app_steps,
                           path=file)
