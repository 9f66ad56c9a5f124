"""GeoJSON (RFC 7946) output of a trajectory, its steps and landmarks, and a reader for it.

The file is a ``FeatureCollection``:

1. the trajectory as a ``LineString`` (a ``Point`` for a single sample, a null geometry for an
   empty one) with the per-vertex times ``t_s``, headings ``heading_rad`` (null where unknown)
   and activity labels in its properties;
2. optionally one ``Point`` per step, placed at the trajectory's position at the step's end
   time, with the step's times, length, heading, height change and activity;
3. optionally one ``Point`` per landmark, with the landmark's fields under ``"landmark"``.

Coordinates. RFC 7946 allows only WGS-84 longitude/latitude (with an optional ellipsoidal
height). With a :class:`~hrtls.frames.Georeference` the positions are converted and written as
``[lon, lat, height]``. Without one the file holds *local ENU metres* ``[x, y, z]`` instead; this
is outside RFC 7946 (GIS tools will put such points near lon 0, lat 0), so the top-level foreign
member ``"hrtls:crs"`` says ``{"type": "local-enu", ...}``. With a georeference ``"hrtls:crs"`` is
``{"type": "wgs84", "georeference": {...}}`` so that :func:`read_geojson` can restore the local
frame. Times are seconds on the session clock; ``"hrtls:time_origin_unix_s"`` gives the Unix
time of ``t = 0`` when known. Only the standard library's :mod:`json` is used.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Landmark, StepEvents, Trajectory, activity_codes
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.jsonstream import (
    Rows,
    float_text,
    joined_text,
    json_positions,
    materialized,
    numbers_text,
    read_json_file,
    row_text,
    write_json,
)
from hrtls.io.tables import activity_text

FloatArray = NDArray[np.float64]

CRS_MEMBER = "hrtls:crs"
"""Foreign member describing the coordinates (``local-enu`` or ``wgs84``)."""
TIME_ORIGIN_MEMBER = "hrtls:time_origin_unix_s"
"""Foreign member with the Unix time of ``t = 0``."""
LOCAL_CRS_NOTE = ("coordinates are local ENU metres [x east, y north, z up], not WGS-84 "
                  "longitude/latitude as RFC 7946 requires; write with a georeference for "
                  "a standard file")

LOCAL_TYPE = "hrtls:LocalFeatureCollection"
"""Top-level type of the local variant (:func:`write_local_geojson`): not GeoJSON on purpose."""

LandmarkInput = Mapping[str, Landmark] | Iterable[Landmark] | None


# --------------------------------------------------------------------------------------------
# shared helpers (also used by the Moving Features and GPX modules)
# --------------------------------------------------------------------------------------------
def georeference_to_json(georeference: Georeference) -> dict[str, float]:
    """The georeference as a JSON object."""
    return {"lat_deg": georeference.lat_deg, "lon_deg": georeference.lon_deg,
            "height_m": georeference.height_m, "rotation_rad": georeference.rotation_rad}


def georeference_from_json(value: Any, *, where: str) -> Georeference:
    """Inverse of :func:`georeference_to_json` (raises :class:`FormatError` on bad content)."""
    try:
        return Georeference(float(value["lat_deg"]), float(value["lon_deg"]),
                            float(value.get("height_m", 0.0)),
                            float(value.get("rotation_rad", 0.0)))
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(f"bad georeference ({exc})", where=where,
                          expected="{lat_deg, lon_deg, height_m, rotation_rad}") from None


def crs_member(georeference: Georeference | None) -> dict[str, Any]:
    """Content of the ``"hrtls:crs"`` member."""
    if georeference is None:
        return {"type": "local-enu", "units": "m", "note": LOCAL_CRS_NOTE}
    return {"type": "wgs84", "georeference": georeference_to_json(georeference)}


def parse_crs_member(value: Any, *, where: str) -> tuple[bool, Georeference | None]:
    """``(is_wgs84, georeference)`` from a ``"hrtls:crs"`` member (absent means WGS-84)."""
    if value is None:
        return True, None
    if not isinstance(value, dict) or value.get("type") not in ("local-enu", "wgs84"):
        raise FormatError(f"unknown {CRS_MEMBER} {value!r}", where=where,
                          expected='{"type": "local-enu"} or {"type": "wgs84", ...}')
    if value["type"] == "local-enu":
        return False, None
    geo = value.get("georeference")
    return True, (None if geo is None else georeference_from_json(geo, where=where))


def to_output_coordinates(xyz: FloatArray, georeference: Georeference | None) -> FloatArray:
    """Local positions (N, 3) to ``[lon, lat, h]`` rows (with a georeference) or unchanged."""
    pts = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    if georeference is None or len(pts) == 0:
        return pts
    llh = georeference.to_wgs84(pts)
    return np.column_stack([llh[:, 1], llh[:, 0], llh[:, 2]])


def from_output_coordinates(coords: FloatArray, georeference: Georeference | None,
                            *, is_wgs84: bool, where: str) -> FloatArray:
    """Inverse of :func:`to_output_coordinates`: stored coordinates to local ``[x, y, z]``."""
    pts = np.asarray(coords, dtype=np.float64).reshape(-1, 3)
    if not is_wgs84:
        return pts
    if georeference is None:
        raise InputError("coordinates are WGS-84 and no georeference is known", where=where,
                         expected="a georeference (in the file or as an argument)")
    if len(pts) == 0:
        return pts
    return georeference.from_wgs84(pts[:, 1], pts[:, 0], pts[:, 2])


def nan_to_none(values: Iterable[float]) -> list[float | None]:
    """Floats with NaN replaced by None (JSON null)."""
    return [None if not math.isfinite(v) else float(v) for v in values]


def none_to_nan(values: Any, *, where: str) -> FloatArray:
    """A JSON list of numbers or nulls as a float array (null -> NaN)."""
    if not isinstance(values, list):
        raise FormatError(f"{type(values).__name__}", where=where, expected="a list of numbers")
    try:
        return np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError("non-numeric entry", where=where, expected="numbers or null") from None


def landmark_list(landmarks: LandmarkInput) -> list[Landmark]:
    """Landmarks from a dict (by id) or an iterable."""
    if landmarks is None:
        return []
    if isinstance(landmarks, Mapping):
        return list(landmarks.values())
    return list(landmarks)


def landmark_output_position(landmark: Landmark, georeference: Georeference | None
                             ) -> list[float]:
    """Where to draw a landmark: ``[lon, lat, h]`` with a georeference, else local ``[x, y, z]``."""
    if georeference is not None:
        if landmark.wgs84 is not None:
            return [landmark.wgs84.lon, landmark.wgs84.lat, landmark.wgs84.alt]
        return to_output_coordinates(landmark.xyz()[None, :], georeference)[0].tolist()
    if landmark.position is None:
        raise InputError("landmark has only WGS-84 coordinates", where=f"landmark {landmark.id!r}",
                         expected="a georeference to write it, or a local position")
    return [float(v) for v in landmark.position]


def prepare_target(path: str | Path, overwrite: bool) -> Path:
    """Check ``path`` may be written and create its folder."""
    target = Path(path)
    if target.exists() and not overwrite:
        raise InputError("already exists", where=str(target),
                         expected="a new path (or overwrite=True)")
    if target.exists() and target.is_dir():
        raise InputError("is a folder", where=str(target), expected="a file path")
    target.parent.mkdir(parents=True, exist_ok=True)
    return target


def write_text_atomic(target: Path, text: str) -> None:
    """Write ``text`` next to ``target`` and move it into place."""
    tmp = target.with_name(target.name + ".partial")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(target)


def check_time_origin(time_origin_unix_s: float | None) -> None:
    """Raise when a given time origin is not a finite number."""
    if time_origin_unix_s is not None and not math.isfinite(time_origin_unix_s):
        raise InputError(f"time origin {time_origin_unix_s}", where="time_origin_unix_s",
                         expected="a finite Unix time in s")


# --------------------------------------------------------------------------------------------
# writer
# --------------------------------------------------------------------------------------------
def _geometry(coords: FloatArray) -> dict[str, Any] | None:
    if len(coords) == 0:
        return None
    if len(coords) == 1:
        return {"type": "Point", "coordinates": coords[0].tolist()}
    return {"type": "LineString", "coordinates": [_rows(coords)]}


def _rows(values: np.ndarray) -> Rows:
    """The items of ``values`` (rows become lists), made a slice at a time.

    Their text is made by Arrow when they are finite floats (else ``json.dumps`` refuses them).
    """
    fast = values.dtype.kind == "f" and bool(np.isfinite(values).all())
    return Rows(len(values), lambda i, j: values[i:j].tolist(),
                (lambda i, j: numbers_text(values[i:j])) if fast else None)


def _number_rows(values: FloatArray) -> Rows:
    """Numbers of ``values``, NaN as null, made a slice at a time."""
    def make(i: int, j: int) -> list[float | None]:
        part = values[i:j]
        return part.tolist() if np.isfinite(part).all() else nan_to_none(part.tolist())
    return Rows(len(values), make, lambda i, j: numbers_text(values[i:j]))


def _label_rows(codes: NDArray[np.integer]) -> Rows:
    """Activity labels of ``codes``, made a slice at a time."""
    index, labels = activity_text(codes)
    quoted = np.array([json.dumps(label) for label in labels] or [""], dtype=object)
    return Rows(len(index), lambda i, j: [labels[k] for k in index[i:j].tolist()],
                lambda i, j: ", ".join(quoted[index[i:j]].tolist()))


def geojson_document(trajectory: Trajectory, *, steps: StepEvents | None = None,
                     landmarks: LandmarkInput = None, georeference: Georeference | None = None,
                     time_origin_unix_s: float | None = None, name: str | None = None
                     ) -> dict[str, Any]:
    """The GeoJSON FeatureCollection as a Python object (see the module docstring)."""
    return materialized(_document(trajectory, steps=steps, landmarks=landmarks,
                                  georeference=georeference,
                                  time_origin_unix_s=time_origin_unix_s, name=name))


def _document(trajectory: Trajectory, *, steps: StepEvents | None,
              landmarks: LandmarkInput, georeference: Georeference | None,
              time_origin_unix_s: float | None, name: str | None) -> dict[str, Any]:
    """:func:`geojson_document` with its long arrays as :class:`~hrtls.io.jsonstream.Rows`."""
    check_time_origin(time_origin_unix_s)
    coords = to_output_coordinates(trajectory.xyz, georeference)
    track_props: dict[str, Any] = {
        "kind": "trajectory",
        "t_s": [_rows(trajectory.t)],
        "heading_rad": [_number_rows(trajectory.heading_rad)],
        "activity": [_label_rows(trajectory.activity)],
    }
    if name is not None:
        track_props["name"] = name
    features: list[Any] = [
        {"type": "Feature", "geometry": _geometry(coords), "properties": track_props}]
    if steps is not None and len(steps):
        if len(trajectory) == 0:
            raise InputError("steps given but the trajectory is empty", where="steps",
                             expected="a trajectory to place the steps on")
        step_coords = to_output_coordinates(trajectory.position_at(steps.t_end), georeference)
        labels = _label_rows(steps.activity)
        features.append(Rows(len(steps), lambda i, j: _step_features(
            steps, step_coords, labels.make(i, j), i, j), _step_text(steps, step_coords)))
    for landmark in landmark_list(landmarks):
        position = landmark_output_position(landmark, georeference)
        features.append({
            "type": "Feature",
            "id": landmark.id,
            "geometry": {"type": "Point", "coordinates": position},
            "properties": {"kind": "landmark",
                           "landmark": landmark.model_dump(
                               mode="json", exclude_none=True, exclude={"position", "wgs84"})},
        })
    doc: dict[str, Any] = {"type": "FeatureCollection", CRS_MEMBER: crs_member(georeference)}
    if time_origin_unix_s is not None:
        doc[TIME_ORIGIN_MEMBER] = float(time_origin_unix_s)
    doc["features"] = features
    return doc


def _step_features(steps: StepEvents, coords: FloatArray, labels: list[str], i: int,
                   j: int) -> list[dict[str, Any]]:
    """The Point features of steps ``i`` to ``j - 1`` (``labels``: their activities)."""
    where = coords[i:j].tolist()
    columns = zip(steps.t_start[i:j].tolist(), steps.t_end[i:j].tolist(),
                  steps.length_m[i:j].tolist(), nan_to_none(steps.heading_rad[i:j].tolist()),
                  steps.dz_m[i:j].tolist(), labels, strict=True)
    return [{"type": "Feature", "geometry": {"type": "Point", "coordinates": xyz},
             "properties": {"kind": "step", "index": k, "t_start_s": t_start, "t_end_s": t_end,
                            "length_m": length, "heading_rad": heading, "dz_m": dz,
                            "activity": label}}
            for k, xyz, (t_start, t_end, length, heading, dz, label)
            in zip(range(i, j), where, columns, strict=True)]


def _step_text(steps: StepEvents, coords: FloatArray) -> Callable[[int, int], str] | None:
    """The text of :func:`_step_features` made by Arrow; None if a number (not a heading) is NaN."""
    numbers = [coords, steps.t_start, steps.t_end, steps.length_m, steps.dz_m]
    if not all(np.isfinite(v).all() for v in numbers):
        return None
    index, labels = activity_text(steps.activity)
    quoted = np.array([json.dumps(label) for label in labels] or [""], dtype=object)

    def text(i: int, j: int) -> str:
        import pyarrow as pa
        import pyarrow.compute as pc

        rows = pc.binary_join_element_wise(
            '{"type": "Feature", "geometry": {"type": "Point", "coordinates": ',
            row_text(coords[i:j]), '}, "properties": {"kind": "step", "index": ',
            pc.cast(pa.array(np.arange(i, j, dtype=np.int64)), pa.string()), ', "t_start_s": ',
            float_text(steps.t_start[i:j]), ', "t_end_s": ', float_text(steps.t_end[i:j]),
            ', "length_m": ', float_text(steps.length_m[i:j]), ', "heading_rad": ',
            float_text(steps.heading_rad[i:j]), ', "dz_m": ', float_text(steps.dz_m[i:j]),
            ', "activity": ', pa.array(quoted[index[i:j]].tolist(), pa.string()), "}}", "")
        return joined_text(rows)
    return text


def write_geojson(trajectory: Trajectory, path: str | Path, *, steps: StepEvents | None = None,
                  landmarks: LandmarkInput = None, georeference: Georeference | None = None,
                  time_origin_unix_s: float | None = None, name: str | None = None,
                  overwrite: bool = False) -> Path:
    """Write a trajectory (plus optional steps and landmarks) as GeoJSON.

    Parameters
    ----------
    trajectory:
        The track, local ENU metres.
    path:
        Output file (``.geojson``); its folder is created.
    steps:
        Steps to mark as points at the trajectory position of each step's end.
    landmarks:
        Landmarks (dict by id or iterable); ones with only WGS-84 coordinates need a
        georeference.
    georeference:
        Anchor of the local frame; with it the file is standard RFC 7946 (WGS-84). Without it
        the coordinates are local ENU metres and ``"hrtls:crs"`` says so.
    time_origin_unix_s:
        Unix time of ``t = 0``, stored as ``"hrtls:time_origin_unix_s"`` when given.
    name:
        Optional track name.
    overwrite:
        Replace an existing file (else an existing file is an error).
    """
    target = prepare_target(path, overwrite)
    write_json(target, _document(trajectory, steps=steps, landmarks=landmarks,
                                 georeference=georeference,
                                 time_origin_unix_s=time_origin_unix_s, name=name))
    return target


def write_local_geojson(trajectory: Trajectory, path: str | Path, *,
                        steps: StepEvents | None = None, landmarks: LandmarkInput = None,
                        time_origin_unix_s: float | None = None, name: str | None = None,
                        overwrite: bool = False) -> Path:
    """The track in local ENU metres, for a recording without a georeference.

    The document is the one :func:`write_geojson` writes without a georeference, but its
    top-level ``type`` is :data:`LOCAL_TYPE`: map tools refuse it instead of drawing metres as
    degrees near lon 0, lat 0. :func:`read_geojson` reads it.
    """
    target = prepare_target(path, overwrite)
    doc = _document(trajectory, steps=steps, landmarks=landmarks, georeference=None,
                    time_origin_unix_s=time_origin_unix_s, name=name)
    doc["type"] = LOCAL_TYPE
    write_json(target, doc)
    return target


# --------------------------------------------------------------------------------------------
# reader
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class GeoJsonTrack:
    """What :func:`read_geojson` found.

    Attributes
    ----------
    coordinates:
        Track vertices as stored, (N, 3): ``[lon, lat, h]`` when ``is_wgs84`` else local
        ``[x, y, z]`` m (a missing third value reads as 0).
    is_wgs84:
        True for standard RFC 7946 coordinates.
    georeference:
        The georeference stored by hrtls, if any.
    t_s, heading_rad, activity:
        Per-vertex times (s), headings (rad, NaN = unknown) and activity codes when present.
    time_origin_unix_s:
        Unix time of ``t = 0`` when stored.
    step_coordinates:
        Step points as stored, (M, 3).
    steps:
        The steps, when the file has step features.
    landmarks:
        Landmarks, with ``position`` (local files) or ``wgs84`` (WGS-84 files).
    name:
        Track name, when stored.
    """

    coordinates: FloatArray
    is_wgs84: bool
    georeference: Georeference | None
    t_s: FloatArray | None
    heading_rad: FloatArray | None
    activity: NDArray[np.int64] | None
    time_origin_unix_s: float | None
    step_coordinates: FloatArray
    steps: StepEvents | None
    landmarks: list[Landmark] = field(default_factory=list)
    name: str | None = None

    def xyz(self, georeference: Georeference | None = None) -> FloatArray:
        """Track vertices in the local frame, m (N, 3); WGS-84 files need a georeference."""
        return from_output_coordinates(self.coordinates, georeference or self.georeference,
                                       is_wgs84=self.is_wgs84, where="geojson track")

    def to_trajectory(self, georeference: Georeference | None = None) -> Trajectory:
        """The track as a :class:`~hrtls.data.Trajectory` (needs per-vertex times)."""
        if self.t_s is None:
            raise InputError("the track has no times", where="geojson track",
                             expected="a 't_s' property as written by hrtls")
        return Trajectory.build(t=self.t_s, xyz=self.xyz(georeference),
                                heading_rad=self.heading_rad, activity=self.activity)


def _geometry_coords(geometry: Any, *, where: str) -> FloatArray:
    if geometry is None:
        return np.zeros((0, 3))
    if not isinstance(geometry, dict):
        raise FormatError("geometry is not an object", where=where, expected="a GeoJSON geometry")
    kind = geometry.get("type")
    if kind == "LineString":
        return json_positions(geometry.get("coordinates"), where=f"{where}.coordinates",
                              finite=True)
    if kind == "Point":
        return json_positions([geometry.get("coordinates")], where=f"{where}.coordinates",
                              finite=True)
    raise FormatError(f"geometry type {kind!r}", where=where, expected="LineString or Point")


def read_geojson(path: str | Path) -> GeoJsonTrack:
    """Read a GeoJSON file written by :func:`write_geojson` (or a plain LineString file).

    The track is the feature whose ``properties.kind`` is ``"trajectory"``, else the first
    ``LineString`` feature. Coordinates are returned as stored; use :meth:`GeoJsonTrack.xyz`
    for local metres.
    """
    file, doc = read_json_file(path, format_name="GeoJSON")
    features = _features(doc, where=str(file))
    is_wgs84, georeference = parse_crs_member(doc.get(CRS_MEMBER),
                                              where=f"{file.name} {CRS_MEMBER}")
    origin = doc.get(TIME_ORIGIN_MEMBER)
    if origin is not None and not isinstance(origin, int | float):
        raise FormatError(f"{origin!r}", where=f"{file.name} {TIME_ORIGIN_MEMBER}",
                          expected="a Unix time in s")
    track_index = _track_index(features, where=str(file))
    where = f"{file.name} features[{track_index}]"
    track = features[track_index]
    coords = _geometry_coords(track.get("geometry"), where=f"{where}.geometry")
    tp = _props(track)
    t_s, heading, activity = _vertex_columns(tp, len(coords), where=where)
    step_rows: list[dict[str, Any]] = []
    step_coords: list[FloatArray] = []
    landmarks: list[Landmark] = []
    for i, feature in enumerate(features):
        p = _props(feature)
        here = f"{file.name} features[{i}]"
        if p.get("kind") == "step":
            step_coords.append(_geometry_coords(feature.get("geometry"), where=f"{here}.geometry"))
            step_rows.append(p)
        elif p.get("kind") == "landmark":
            landmarks.append(_landmark(feature, p, is_wgs84=is_wgs84, where=here))
    return GeoJsonTrack(
        coordinates=coords, is_wgs84=is_wgs84, georeference=georeference, t_s=t_s,
        heading_rad=heading, activity=activity,
        time_origin_unix_s=None if origin is None else float(origin),
        step_coordinates=(np.concatenate(step_coords) if step_coords else np.zeros((0, 3))),
        steps=_steps(step_rows, where=file.name) if step_rows else None, landmarks=landmarks,
        name=str(tp["name"]) if "name" in tp else None,
    )


def _features(doc: Any, *, where: str) -> list[Any]:
    """The features of a GeoJSON document (a Feature, a FeatureCollection or the local type)."""
    if not isinstance(doc, dict):
        raise FormatError("top level is not an object", where=where, expected="GeoJSON")
    if doc.get("type") == "Feature":
        return [doc]
    if doc.get("type") in ("FeatureCollection", LOCAL_TYPE) and isinstance(
            doc.get("features"), list):
        features: list[Any] = doc["features"]
        return features
    raise FormatError(f"type {doc.get('type')!r}", where=where,
                      expected="a FeatureCollection or a Feature")


def _props(feature: Any) -> dict[str, Any]:
    """The properties of a feature ({} when it has none)."""
    value = feature.get("properties") if isinstance(feature, dict) else None
    return value if isinstance(value, dict) else {}


def _track_index(features: list[Any], *, where: str) -> int:
    """Index of the trajectory feature, else of the first LineString feature."""
    track_index = next((i for i, f in enumerate(features)
                        if _props(f).get("kind") == "trajectory"), None)
    if track_index is None:
        track_index = next((i for i, f in enumerate(features) if isinstance(f, dict)
                            and isinstance(f.get("geometry"), dict)
                            and f["geometry"].get("type") == "LineString"), None)
    if track_index is None:
        raise FormatError("no trajectory feature", where=where,
                          expected="a feature with properties.kind 'trajectory' or a LineString")
    return track_index


def _vertex_columns(tp: dict[str, Any], n: int, *, where: str
                    ) -> tuple[FloatArray | None, FloatArray | None, NDArray[np.int64] | None]:
    """Times, headings and activity codes of the track's ``n`` vertices (None when absent)."""

    def per_vertex(key: str) -> FloatArray | None:
        if key not in tp:
            return None
        arr = none_to_nan(tp[key], where=f"{where}.properties.{key}")
        if len(arr) != n:
            raise FormatError(f"{len(arr)} values for {n} vertices",
                              where=f"{where}.properties.{key}", expected="one per vertex")
        return arr

    t_s = per_vertex("t_s")
    if t_s is not None and not np.all(np.isfinite(t_s)):
        raise FormatError("null time", where=f"{where}.properties.t_s", expected="numbers")
    heading = per_vertex("heading_rad")
    activity = None
    if "activity" in tp:
        raw = tp["activity"]
        if not isinstance(raw, list) or len(raw) != n:
            raise FormatError("bad activity list", where=f"{where}.properties.activity",
                              expected="one label per vertex")
        activity = activity_codes(np.array([str(v) for v in raw], dtype=np.str_),
                                  where=f"{where}.properties.activity")
    return t_s, heading, activity


def _landmark(feature: Any, p: dict[str, Any], *, is_wgs84: bool, where: str) -> Landmark:
    """The landmark of a ``kind: landmark`` feature, placed at its Point."""
    point = _geometry_coords(feature.get("geometry"), where=f"{where}.geometry")
    data = dict(p.get("landmark") or {})
    data.pop("position", None)
    data.pop("wgs84", None)
    if len(point) != 1:
        raise FormatError("landmark without a point", where=where, expected="a Point")
    x, y, z = (float(v) for v in point[0])
    location = ({"wgs84": {"lat": y, "lon": x, "alt": z}} if is_wgs84
                else {"position": (x, y, z)})
    try:
        return Landmark(**data, **location)
    except (ValueError, TypeError) as exc:
        raise FormatError(f"bad landmark ({exc})", where=where,
                          expected="an hrtls landmark") from None


def _steps(step_rows: list[dict[str, Any]], *, where: str) -> StepEvents:
    """The step table of the ``kind: step`` features' properties."""
    try:
        return StepEvents.build(
            t_start=[r["t_start_s"] for r in step_rows],
            t_end=[r["t_end_s"] for r in step_rows],
            length_m=[r["length_m"] for r in step_rows],
            heading_rad=[np.nan if r.get("heading_rad") is None else r["heading_rad"]
                         for r in step_rows],
            dz_m=[r.get("dz_m", 0.0) for r in step_rows],
            activity=activity_codes(np.array([str(r.get("activity", "walking"))
                                              for r in step_rows], dtype=np.str_),
                                    where=f"{where} step activity"),
        )
    except (KeyError, TypeError) as exc:
        raise FormatError(f"step feature lacks {exc}", where=where,
                          expected="t_start_s, t_end_s, length_m") from None
