"""The result tables of ``hrtls track``: ``trajectory.csv`` and ``steps.csv``.

``trajectory.csv``: ``t,x,y,z,heading,var_x,cov_xy,var_y,var_heading,activity[,lat,lon]``
(m, rad, m^2, rad^2; activity as a label; ``lat,lon`` in degrees when a georeference is known).
``steps.csv``: ``t_start,t_end,length,heading,dz,activity[,frequency,acc_max,acc_min]``.
Unknown numbers (NaN) are written as empty fields.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hrtls.data import StepEvents, Trajectory, activity_codes, activity_labels
from hrtls.frames import Georeference
from hrtls.io.csvtable import ColumnKind, format_table, read_table

TRAJECTORY_COLUMNS = ("t", "x", "y", "z", "heading", "var_x", "cov_xy", "var_y", "var_heading",
                      "activity")
STEP_COLUMNS = ("t_start", "t_end", "length", "heading", "dz", "activity")
STEP_EXTRA_COLUMNS = ("frequency", "acc_max", "acc_min")


def trajectory_table(trajectory: Trajectory, *, georeference: Georeference | None = None
                     ) -> str:
    """``trajectory.csv`` text (with ``lat,lon`` when a georeference is given)."""
    tr = trajectory
    cols: dict[str, np.ndarray] = {
        "t": tr.t, "x": tr.xyz[:, 0], "y": tr.xyz[:, 1], "z": tr.xyz[:, 2],
        "heading": tr.heading_rad, "var_x": tr.cov_xy[:, 0, 0], "cov_xy": tr.cov_xy[:, 0, 1],
        "var_y": tr.cov_xy[:, 1, 1], "var_heading": tr.var_heading,
        "activity": activity_labels(tr.activity),
    }
    if georeference is not None and len(tr):
        wgs = georeference.to_wgs84(tr.xyz)
        cols["lat"] = wgs[:, 0]
        cols["lon"] = wgs[:, 1]
    return format_table(cols)


def write_trajectory(trajectory: Trajectory, path: Path, *,
                     georeference: Georeference | None = None) -> Path:
    """Write ``trajectory.csv``."""
    path.write_text(trajectory_table(trajectory, georeference=georeference), encoding="utf-8")
    return path


def read_trajectory(path: Path) -> Trajectory:
    """Read ``trajectory.csv`` (``lat,lon`` columns, if any, are ignored: x, y are the truth)."""
    kinds: dict[str, ColumnKind] = dict.fromkeys(TRAJECTORY_COLUMNS, "float_or_empty")
    kinds.update({"t": "float", "x": "float", "y": "float", "z": "float", "activity": "str",
                  "lat": "float", "lon": "float"})
    table = read_table(path.read_bytes(), name=path.name, kinds=kinds,
                       required=("t", "x", "y", "z"))
    n = table.n_rows

    def col(name: str, default: float) -> np.ndarray:
        return table.float(name) if name in table.present else np.full(n, default)

    cov = np.zeros((n, 2, 2))
    cov[:, 0, 0] = np.nan_to_num(col("var_x", 0.0))
    cov[:, 1, 1] = np.nan_to_num(col("var_y", 0.0))
    cov[:, 0, 1] = cov[:, 1, 0] = np.nan_to_num(col("cov_xy", 0.0))
    activity = (activity_codes(table.str("activity"), where=f"{path.name} activity")
                if "activity" in table.present else np.full(n, -1))
    return Trajectory.build(
        t=table.float("t"),
        xyz=np.column_stack([table.float("x"), table.float("y"), table.float("z")]),
        heading_rad=col("heading", np.nan), cov_xy=cov, var_heading=col("var_heading", np.nan),
        activity=activity)


def steps_table(steps: StepEvents) -> str:
    """``steps.csv`` text."""
    cols: dict[str, np.ndarray] = {
        "t_start": steps.t_start, "t_end": steps.t_end, "length": steps.length_m,
        "heading": steps.heading_rad, "dz": steps.dz_m,
        "activity": activity_labels(steps.activity),
        "frequency": steps.frequency_hz, "acc_max": steps.acc_max, "acc_min": steps.acc_min,
    }
    return format_table(cols)


def write_steps(steps: StepEvents, path: Path) -> Path:
    """Write ``steps.csv``."""
    path.write_text(steps_table(steps), encoding="utf-8")
    return path


def read_steps(path: Path) -> StepEvents:
    """Read ``steps.csv``."""
    kinds: dict[str, ColumnKind] = dict.fromkeys(STEP_COLUMNS + STEP_EXTRA_COLUMNS,
                                                 "float_or_empty")
    kinds.update({"t_start": "float", "t_end": "float", "length": "float", "activity": "str"})
    table = read_table(path.read_bytes(), name=path.name, kinds=kinds,
                       required=("t_start", "t_end", "length"))
    n = table.n_rows

    def col(name: str) -> np.ndarray | None:
        return table.float(name) if name in table.present else None

    activity = (activity_codes(table.str("activity"), where=f"{path.name} activity")
                if "activity" in table.present else None)
    dz = col("dz")
    return StepEvents.build(
        t_start=table.float("t_start"), t_end=table.float("t_end"),
        length_m=table.float("length"), heading_rad=col("heading"),
        dz_m=None if dz is None else np.nan_to_num(dz), activity=activity,
        frequency_hz=col("frequency"), acc_max=col("acc_max"), acc_min=col("acc_min"),
    ) if n else StepEvents.empty()
