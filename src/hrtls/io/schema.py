"""The columns of every table hrtls reads and writes: kind, unit and which are required.

One definition serves the CSV reader, the Parquet reader and writer (the units go into the
Parquet schema metadata) and the Arrow-table API of :mod:`hrtls.io.tables`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from hrtls.io.csvtable import ColumnKind

UNIT_KEY = b"unit"
"""Field metadata key holding a column's unit (``"s"``, ``"m/s^2"``, ...; ``""`` for labels)."""
TABLE_KEY = b"hrtls.table"
"""Schema metadata key holding the table's name (``"imu"``, ``"trajectory"``, ...)."""


@dataclass(frozen=True, slots=True)
class TableSpec:
    """Allowed columns of one table (in writing order), their kind and unit; required columns."""

    kinds: Mapping[str, ColumnKind]
    units: Mapping[str, str]
    required: tuple[str, ...]


def _spec(columns: tuple[tuple[str, ColumnKind, str], ...], required: tuple[str, ...]
          ) -> TableSpec:
    return TableSpec({c: k for c, k, _ in columns}, {c: u for c, _, u in columns}, required)


def _vector(prefix: str, unit: str) -> tuple[tuple[str, ColumnKind, str], ...]:
    return tuple((prefix + a, "float", unit) for a in "xyz")


_T: tuple[str, ColumnKind, str] = ("t", "float", "s")

TABLES: dict[str, TableSpec] = {
    "imu": _spec((_T, *_vector("a", "m/s^2"), *_vector("g", "rad/s"), *_vector("m", "uT")),
                 ("t", "ax", "ay", "az")),
    "gyro": _spec((_T, *_vector("g", "rad/s")), ("t", "gx", "gy", "gz")),
    "mag": _spec((_T, *_vector("m", "uT")), ("t", "mx", "my", "mz")),
    "pressure": _spec((_T, ("pressure_pa", "float", "Pa")), ("t", "pressure_pa")),
    "orientation": _spec((_T, ("qw", "float", "1"), ("qx", "float", "1"), ("qy", "float", "1"),
                          ("qz", "float", "1")), ("t", "qw", "qx", "qy", "qz")),
    "fixes": _spec((_T, ("x", "float", "m"), ("y", "float", "m"), ("z", "float", "m"),
                    ("sigma", "float", "m")), ("t", "x", "y", "sigma")),
    "rss": _spec((_T, ("anchor", "str", ""), ("rss_dbm", "float", "dBm")),
                 ("t", "anchor", "rss_dbm")),
    "tags": _spec((_T, ("tag", "str", "")), ("t", "tag")),
    "ranges": _spec((_T, ("node", "str", ""), ("range", "float", "m"),
                     ("sigma", "float_or_empty", "m")), ("t", "node", "range")),
    "truth": _spec((_T, ("x", "float", "m"), ("y", "float", "m"), ("z", "float", "m"),
                    ("heading", "float", "rad")), ("t", "x", "y", "z")),
    "checkpoints": _spec((_T, ("x", "float", "m"), ("y", "float", "m"), ("z", "float", "m"),
                          ("label", "str", "")), ("t", "x", "y", "z")),
    "trajectory": _spec((_T, ("x", "float", "m"), ("y", "float", "m"), ("z", "float", "m"),
                         ("heading", "float_or_empty", "rad"),
                         ("var_x", "float_or_empty", "m^2"), ("cov_xy", "float_or_empty", "m^2"),
                         ("var_y", "float_or_empty", "m^2"),
                         ("var_heading", "float_or_empty", "rad^2"), ("activity", "str", ""),
                         ("lat", "float", "deg"), ("lon", "float", "deg")),
                        ("t", "x", "y", "z")),
    "steps": _spec((("t_start", "float", "s"), ("t_end", "float", "s"),
                    ("length", "float", "m"), ("heading", "float_or_empty", "rad"),
                    ("dz", "float_or_empty", "m"), ("activity", "str", ""),
                    ("frequency", "float_or_empty", "Hz"), ("acc_max", "float_or_empty", "m/s^2"),
                    ("acc_min", "float_or_empty", "m/s^2")),
                   ("t_start", "t_end", "length")),
    "estimates": _spec((_T, ("x", "float", "m"), ("y", "float", "m"), ("z", "float", "m"),
                        ("floor", "float", "1"), ("cxx", "float", "m^2"), ("cxy", "float", "m^2"),
                        ("cyy", "float", "m^2"), ("heading_rad", "float_or_empty", "rad"),
                        ("var_heading", "float_or_empty", "rad^2"), ("activity", "str", ""),
                        ("since_correction_s", "float_or_empty", "s")),
                       ("t", "x", "y", "z")),
    "nodes": _spec((("id", "str", ""), ("x", "float_or_empty", "m"), ("y", "float_or_empty", "m"),
                    ("z", "float_or_empty", "m"), ("var_x", "float_or_empty", "m^2"),
                    ("cov_xy", "float_or_empty", "m^2"), ("var_y", "float_or_empty", "m^2"),
                    ("localized", "str", ""), ("readings", "float", "1"),
                    ("contributors", "str", ""), ("status", "str", "")),
                   ("id", "localized", "readings")),
}
"""Every table by name; a session's ``imu`` table is ``imu.csv`` or ``imu.parquet``."""

SESSION_TABLES = ("imu", "gyro", "mag", "pressure", "orientation", "fixes", "rss", "tags",
                  "ranges", "truth", "checkpoints")
"""The tables of a session folder, in writing order."""

TABLE_SUFFIXES = (".csv", ".parquet")
"""File suffixes of a table: CSV (interchange, readable) or Parquet (typed, compressed)."""
