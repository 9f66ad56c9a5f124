"""OGC Moving Features JSON (MF-JSON) output of a trajectory as a ``MovingPoint``, and a reader.

The file is one ``Feature`` (OGC 19-045r3, "MF-JSON Trajectory" form)::

    {"type": "Feature",
     "crs": {...}, "trs": {...},
     "temporalGeometry": {"type": "MovingPoint", "datetimes": [...], "coordinates": [...],
                          "interpolation": "Linear"},
     "temporalProperties": [{"datetimes": [...], "heading_rad": {"type": "Measure",
                             "form": "rad", "values": [...], "interpolation": "Discrete"}}],
     "geometry": {"type": "LineString", ...}, "properties": {...}, "time": [first, last]}

Datetimes are ISO 8601 in UTC with microseconds (``2020-12-10T12:57:44.733000Z``); they need
the absolute time of ``t = 0`` (``meta.time_origin_unix_s`` of the session, passed as
``time_origin_unix_s``) -- without it the writer raises :class:`~hrtls.errors.InputError`.
Times are rounded to whole microseconds (integer arithmetic, so a round trip is exact to
0.5 us); two samples that fall on the same microsecond are rejected.

Coordinates are WGS-84 ``[lon, lat, ellipsoidal height]`` with a georeference (``crs`` names
OGC CRS84, the MF-JSON default, whose optional third value is the height as in GeoJSON), else
local ENU metres with ``crs`` named ``"hrtls:local-enu"`` and the same
``"hrtls:crs"`` foreign member as the GeoJSON writer. Headings go into a temporal property with
its own datetimes, so samples with unknown heading are simply left out. Standard library
:mod:`json` only.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data import Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.geojson import (
    CRS_MEMBER,
    TIME_ORIGIN_MEMBER,
    check_time_origin,
    crs_member,
    from_output_coordinates,
    parse_crs_member,
    prepare_target,
    to_output_coordinates,
    write_text_atomic,
)
from hrtls.io.jsonstream import json_positions, read_json_file

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
_US = timedelta(microseconds=1)
CRS84 = "urn:ogc:def:crs:OGC:1.3:CRS84"
"""OGC name of WGS-84 longitude/latitude (degrees), the MF-JSON default; as in GeoJSON a third
value is the ellipsoidal height in m."""
LOCAL_CRS_NAME = "hrtls:local-enu"
"""Name written in ``crs`` for local ENU metres (not a registered CRS)."""
GREGORIAN_TRS = "http://www.opengis.net/def/uom/ISO-8601/0/Gregorian"
"""OGC identifier of the ISO 8601 Gregorian calendar used for datetimes."""


# --------------------------------------------------------------------------------------------
# ISO 8601 times (shared with the GPX module)
# --------------------------------------------------------------------------------------------
def unix_us_from_times(t_s: ArrayLike, time_origin_unix_s: float) -> IntArray:
    """Integer microseconds since the Unix epoch of session times ``t_s`` (s from the origin)."""
    check_time_origin(time_origin_unix_s)
    t = np.asarray(t_s, dtype=np.float64)
    return np.asarray(round(time_origin_unix_s * 1e6) + np.round(t * 1e6).astype(np.int64),
                      dtype=np.int64)


def iso8601_from_unix_us(us: int) -> str:
    """``YYYY-MM-DDTHH:MM:SS.ffffffZ`` of a time in microseconds since the Unix epoch."""
    try:
        stamp = _EPOCH + timedelta(microseconds=int(us))
    except OverflowError:
        raise InputError(f"time {us} us since 1970 is out of range", where="datetime",
                         expected="a date between years 1 and 9999") from None
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def unix_us_from_iso8601(text: Any, *, where: str) -> int:
    """Microseconds since the Unix epoch of an ISO 8601 date-time (naive times are UTC)."""
    if not isinstance(text, str):
        raise FormatError(f"{text!r}", where=where, expected="an ISO 8601 date-time string")
    try:
        stamp = datetime.fromisoformat(text.strip())
    except ValueError:
        raise FormatError(f"{text!r}", where=where,
                          expected="an ISO 8601 date-time such as 2020-01-01T12:00:00.5Z"
                          ) from None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=UTC)
    return (stamp - _EPOCH) // _US


def iso8601_times(t_s: FloatArray, time_origin_unix_s: float) -> list[str]:
    """ISO 8601 UTC strings of session times; raises when two fall on the same microsecond."""
    us = unix_us_from_times(t_s, time_origin_unix_s)
    if len(us) > 1 and np.any(np.diff(us) <= 0):
        idx = int(np.flatnonzero(np.diff(us) <= 0)[0]) + 1
        raise InputError("two samples less than 1 us apart", where=f"trajectory index {idx}",
                         expected="times at least 1 us apart (datetimes have us resolution)")
    return [iso8601_from_unix_us(int(v)) for v in us]


# --------------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------------
def movingfeatures_document(trajectory: Trajectory, *, time_origin_unix_s: float | None,
                            georeference: Georeference | None = None,
                            name: str | None = None) -> dict[str, Any]:
    """The MF-JSON Feature as a Python object (see the module docstring)."""
    if time_origin_unix_s is None:
        raise InputError("no absolute time origin", where="moving features writer",
                         expected="time_origin_unix_s (the session's meta.time_origin_unix_s)",
                         hint="MF-JSON datetimes are absolute UTC times; pass the Unix time "
                              "of t = 0 explicitly when the session does not know it")
    if len(trajectory) == 0:
        raise InputError("empty trajectory", where="moving features writer",
                         expected="at least one sample for a MovingPoint")
    datetimes = iso8601_times(trajectory.t, time_origin_unix_s)
    coords = to_output_coordinates(trajectory.xyz, georeference)
    crs_name = LOCAL_CRS_NAME if georeference is None else CRS84
    doc: dict[str, Any] = {
        "type": "Feature",
        "crs": {"type": "Name", "properties": {"name": crs_name}},
        "trs": {"type": "Link", "properties": {"type": "OGCDEF", "href": GREGORIAN_TRS}},
        CRS_MEMBER: crs_member(georeference),
        TIME_ORIGIN_MEMBER: float(time_origin_unix_s),
        "time": [datetimes[0], datetimes[-1]],
        "geometry": (None if len(coords) < 2
                     else {"type": "LineString", "coordinates": coords.tolist()}),
        "properties": {} if name is None else {"name": name},
        "temporalGeometry": {
            "type": "MovingPoint",
            "datetimes": datetimes,
            "coordinates": coords.tolist(),
            "interpolation": "Linear",
        },
    }
    known = np.isfinite(trajectory.heading_rad)
    if np.any(known):
        doc["temporalProperties"] = [{
            "datetimes": [d for d, k in zip(datetimes, known.tolist(), strict=True) if k],
            "heading_rad": {"type": "Measure", "form": "rad",
                            "values": trajectory.heading_rad[known].tolist(),
                            "interpolation": "Discrete"},
        }]
    return doc


def write_movingfeatures(trajectory: Trajectory, path: str | Path, *,
                         time_origin_unix_s: float | None,
                         georeference: Georeference | None = None, name: str | None = None,
                         overwrite: bool = False) -> Path:
    """Write a trajectory as an OGC MF-JSON MovingPoint feature.

    Parameters
    ----------
    trajectory:
        The track (local ENU metres, times in s from the time origin).
    path:
        Output file (``.json``); its folder is created.
    time_origin_unix_s:
        Unix time of ``t = 0`` (required; None raises :class:`~hrtls.errors.InputError`).
    georeference:
        With it the coordinates are WGS-84 (CRS84 + height); without, local ENU metres.
    name:
        Optional feature name.
    overwrite:
        Replace an existing file.
    """
    target = prepare_target(path, overwrite)
    doc = movingfeatures_document(trajectory, time_origin_unix_s=time_origin_unix_s,
                                  georeference=georeference, name=name)
    write_text_atomic(target, json.dumps(doc, allow_nan=False) + "\n")
    return target


# --------------------------------------------------------------------------------------------
# reader
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class MovingPointTrack:
    """What :func:`read_movingfeatures` found.

    Attributes
    ----------
    time_unix_us:
        Sample times, integer microseconds since the Unix epoch, (N,).
    coordinates:
        Positions as stored, (N, 3): ``[lon, lat, h]`` if ``is_wgs84`` else local ``[x, y, z]``.
    is_wgs84:
        True unless the file says its coordinates are local ENU.
    georeference:
        The georeference stored by hrtls, if any.
    heading_rad:
        Heading per sample (NaN where the file has none), or None without a heading property.
    time_origin_unix_s:
        The stored time origin (``"hrtls:time_origin_unix_s"``), or None.
    name:
        Feature name, when stored.
    """

    time_unix_us: IntArray
    coordinates: FloatArray
    is_wgs84: bool
    georeference: Georeference | None
    heading_rad: FloatArray | None
    time_origin_unix_s: float | None
    name: str | None = None

    def t_s(self, time_origin_unix_s: float | None = None) -> FloatArray:
        """Times in s from ``time_origin_unix_s`` (default: the stored origin, else sample 0)."""
        origin = time_origin_unix_s if time_origin_unix_s is not None else self.time_origin_unix_s
        origin_us = (int(self.time_unix_us[0]) if origin is None or len(self.time_unix_us) == 0
                     else round(origin * 1e6))
        return np.asarray((self.time_unix_us - origin_us) / 1e6, dtype=np.float64)

    def xyz(self, georeference: Georeference | None = None) -> FloatArray:
        """Positions in the local frame, m; WGS-84 files need a georeference."""
        return from_output_coordinates(self.coordinates, georeference or self.georeference,
                                       is_wgs84=self.is_wgs84, where="moving point")

    def to_trajectory(self, georeference: Georeference | None = None,
                      time_origin_unix_s: float | None = None) -> Trajectory:
        """The track as a :class:`~hrtls.data.Trajectory`."""
        return Trajectory.build(t=self.t_s(time_origin_unix_s), xyz=self.xyz(georeference),
                                heading_rad=self.heading_rad)


def _find_moving_point(doc: Any, where: str) -> tuple[dict[str, Any], dict[str, Any]]:
    features: Sequence[Any]
    if isinstance(doc, dict) and doc.get("type") == "FeatureCollection":
        features = doc.get("features") or []
    else:
        features = [doc]
    for feature in features:
        if isinstance(feature, dict):
            geom = feature.get("temporalGeometry")
            if isinstance(geom, dict) and geom.get("type") == "MovingPoint":
                return feature, geom
    raise FormatError("no MovingPoint temporalGeometry", where=where,
                      expected="an MF-JSON Feature with temporalGeometry.type 'MovingPoint'")


def read_movingfeatures(path: str | Path) -> MovingPointTrack:
    """Read the first MovingPoint of an MF-JSON Feature or FeatureCollection."""
    file, doc = read_json_file(path, format_name="MF-JSON", article="an")
    feature, geom = _find_moving_point(doc, str(file))
    where = f"{file.name} temporalGeometry"
    raw_times = geom.get("datetimes")
    if not isinstance(raw_times, list):
        raise FormatError("no datetimes list", where=where, expected="ISO 8601 datetimes")
    us = np.array([unix_us_from_iso8601(v, where=f"{where}.datetimes[{i}]")
                   for i, v in enumerate(raw_times)], dtype=np.int64)
    coords = json_positions(geom.get("coordinates"), where=f"{where}.coordinates", finite=False)
    if len(coords) != len(us):
        raise FormatError(f"{len(coords)} coordinates for {len(us)} datetimes", where=where,
                          expected="one position per datetime")
    if len(us) > 1 and np.any(np.diff(us) <= 0):
        idx = int(np.flatnonzero(np.diff(us) <= 0)[0]) + 1
        raise FormatError("datetimes not increasing", where=f"{where}.datetimes[{idx}]",
                          expected="strictly increasing datetimes")
    crs_value = feature.get(CRS_MEMBER, doc.get(CRS_MEMBER) if isinstance(doc, dict) else None)
    if crs_value is None:
        crs_name = (feature.get("crs") or {}).get("properties", {}).get("name")
        is_wgs84, georeference = crs_name != LOCAL_CRS_NAME, None
    else:
        is_wgs84, georeference = parse_crs_member(crs_value, where=f"{file.name} {CRS_MEMBER}")
    heading = None
    for j, prop in enumerate(feature.get("temporalProperties") or []):
        if not isinstance(prop, dict) or "heading_rad" not in prop:
            continue
        here = f"{file.name} temporalProperties[{j}]"
        p_us = np.array([unix_us_from_iso8601(v, where=f"{here}.datetimes[{i}]")
                         for i, v in enumerate(prop.get("datetimes") or [])], dtype=np.int64)
        values = (prop["heading_rad"] or {}).get("values")
        if not isinstance(values, list) or len(values) != len(p_us):
            raise FormatError("heading values do not match datetimes", where=here,
                              expected="one value per datetime")
        pos = np.searchsorted(us, p_us)
        ok = (pos < len(us)) & (us[np.minimum(pos, len(us) - 1)] == p_us)
        if not np.all(ok):
            raise FormatError("heading at a time without a position", where=here,
                              expected="datetimes that are among the MovingPoint's")
        heading = np.full(len(us), np.nan)
        heading[pos] = np.asarray(values, dtype=np.float64)
        break
    origin = feature.get(TIME_ORIGIN_MEMBER)
    name = (feature.get("properties") or {}).get("name")
    return MovingPointTrack(time_unix_us=us, coordinates=coords, is_wgs84=is_wgs84,
                            georeference=georeference, heading_rad=heading,
                            time_origin_unix_s=None if origin is None else float(origin),
                            name=None if name is None else str(name))
