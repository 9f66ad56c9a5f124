"""Export a result folder of ``hrtls track`` as GPX, OGC Moving Features JSON, GeoJSON or CSV.

The georeference and the Unix time of ``t = 0`` come from the result's ``report.json`` (as the
recording gave them). GPX needs a georeference; Moving Features needs the time origin; GeoJSON
without a georeference is the local variant (:func:`hrtls.io.geojson.write_local_geojson`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hrtls.data.session import GeoreferenceModel
from hrtls.errors import InputError
from hrtls.frames import Georeference

EXPORTS = ("gpx", "mf-json", "geojson", "csv")
"""What ``--to`` accepts."""


def _provenance(result_dir: Path) -> tuple[Georeference | None, float | None]:
    path = result_dir / "report.json"
    if not path.exists():
        return None, None
    try:
        report: Any = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON ({exc})", where=str(path),
                         expected="the report.json of `hrtls track`") from None
    source = report.get("input", {}) if isinstance(report, dict) else {}
    geo = source.get("georeference")
    origin = source.get("time_origin_unix_s")
    return (None if geo is None else GeoreferenceModel.model_validate(geo).to_georeference(),
            None if origin is None else float(origin))


def default_name(to: str, georeferenced: bool) -> str:
    """File name of an export in the result folder."""
    return {"gpx": "trajectory.gpx", "mf-json": "trajectory.mf.json",
            "geojson": "trajectory.geojson" if georeferenced else "trajectory.local.json",
            "csv": "trajectory.csv"}[to]


def export_result(result_dir: Path, *, to: str, output: Path | None = None,
                  overwrite: bool = False) -> Path:
    """Write the result's trajectory (and steps) as ``to``; returns the file written.

    Raises
    ------
    InputError
        An unknown ``--to``, a result folder without a trajectory, GPX without a georeference,
        Moving Features without a time origin, or an existing output without ``--overwrite``.
    """
    from hrtls.io.geojson import write_geojson, write_local_geojson
    from hrtls.io.gpx import write_gpx
    from hrtls.io.movingfeatures import write_movingfeatures
    from hrtls.io.tables import write_trajectory
    from hrtls.jobs.evaluate import read_estimate

    if to not in EXPORTS:
        raise InputError(f"{to!r}", where="--to", expected=" | ".join(EXPORTS))
    georeference, origin = _provenance(result_dir)
    target = output or result_dir / default_name(to, georeference is not None)
    if target.exists() and not overwrite:
        raise InputError("already exists", where=str(target), expected="a new file (or "
                         "--overwrite)")
    if to == "gpx" and georeference is None:
        raise InputError("the recording has no georeference (local metres only)",
                         where=str(result_dir), expected="a georeferenced result for GPX",
                         hint="--to geojson writes the local track, --to csv a table")
    if to == "mf-json" and origin is None:
        raise InputError("the recording's clock has no Unix time origin",
                         where=str(result_dir),
                         expected="a result whose recording gave absolute times, for "
                         "Moving Features", hint="--to geojson or --to csv keep session times")
    trajectory, steps = read_estimate(result_dir)
    if to == "gpx":
        return write_gpx(trajectory, target, georeference=georeference,
                         time_origin_unix_s=origin, steps=steps, overwrite=True)
    if to == "mf-json":
        return write_movingfeatures(trajectory, target, time_origin_unix_s=origin,
                                    georeference=georeference, overwrite=True)
    if to == "geojson":
        if georeference is None:
            return write_local_geojson(trajectory, target, steps=steps,
                                       time_origin_unix_s=origin, overwrite=True)
        return write_geojson(trajectory, target, steps=steps, georeference=georeference,
                             time_origin_unix_s=origin, overwrite=True)
    return write_trajectory(trajectory, target, georeference=georeference)
