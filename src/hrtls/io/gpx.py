"""GPX 1.1 output of a trajectory (a track of one segment) plus waypoints, and a reader.

GPX positions are WGS-84 latitude/longitude, so the writer *requires* a
:class:`~hrtls.frames.Georeference`; ``<ele>`` is the ellipsoidal height from it (GPX does
not say which height it means; most tools assume above the geoid, so treat it as approximate).
Each ``<trkpt>`` gets a ``<time>`` (ISO 8601 UTC with microseconds) when the time origin
(``meta.time_origin_unix_s``) is given, otherwise no times are written. Landmarks become
``<wpt>`` elements (``<name>`` = id, ``<type>`` = kind); steps can be added as waypoints of
type ``step`` at the trajectory position of each step's end. GPX 1.1 has no heading field, so
headings are not written. Coordinates are written with 10 decimals of a degree (about 10 um).

Written and parsed with :mod:`xml.etree.ElementTree` only. Parse only GPX files you trust:
the standard library parser does not guard against every XML bomb.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hrtls.data import StepEvents, Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.geojson import (
    LandmarkInput,
    check_time_origin,
    landmark_list,
    landmark_output_position,
    prepare_target,
    to_output_coordinates,
)
from hrtls.io.movingfeatures import iso8601_from_unix_us, unix_us_from_iso8601, unix_us_from_times

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

GPX_NS = "http://www.topografix.com/GPX/1/1"
"""XML namespace of GPX 1.1."""
_GPX10_NS = "http://www.topografix.com/GPX/1/0"
_XSI_NS = "http://www.w3.org/2001/XMLSchema-instance"
_SCHEMA_LOCATION = f"{GPX_NS} http://www.topografix.com/GPX/1/1/gpx.xsd"


def _q(tag: str) -> str:
    return f"{{{GPX_NS}}}{tag}"


def _deg(value: float) -> str:
    return f"{value:.10f}"


def _add_point(parent: ET.Element, tag: str, lon: float, lat: float, ele: float,
               time_us: int | None, name: str | None = None, kind: str | None = None) -> None:
    # child order fixed by the GPX 1.1 schema: ele, time, ..., name, ..., type
    point = ET.SubElement(parent, _q(tag), {"lat": _deg(lat), "lon": _deg(lon)})
    ET.SubElement(point, _q("ele")).text = f"{ele:.6f}"
    if time_us is not None:
        ET.SubElement(point, _q("time")).text = iso8601_from_unix_us(time_us)
    if name is not None:
        ET.SubElement(point, _q("name")).text = name
    if kind is not None:
        ET.SubElement(point, _q("type")).text = kind


def gpx_tree(trajectory: Trajectory, *, georeference: Georeference | None,
             time_origin_unix_s: float | None = None, steps: StepEvents | None = None,
             landmarks: LandmarkInput = None, name: str | None = None) -> ET.ElementTree:
    """The GPX document as an element tree (see :func:`write_gpx`)."""
    if georeference is None:
        raise InputError("no georeference", where="GPX writer",
                         expected="a georeference (GPX positions are WGS-84 lat/lon)",
                         hint="use GeoJSON for local ENU coordinates")
    check_time_origin(time_origin_unix_s)
    ET.register_namespace("", GPX_NS)
    ET.register_namespace("xsi", _XSI_NS)
    root = ET.Element(_q("gpx"), {"version": "1.1", "creator": "hrtls",
                                  f"{{{_XSI_NS}}}schemaLocation": _SCHEMA_LOCATION})
    if name is not None:
        metadata = ET.SubElement(root, _q("metadata"))
        ET.SubElement(metadata, _q("name")).text = name
    for landmark in landmark_list(landmarks):
        lon, lat, ele = landmark_output_position(landmark, georeference)
        _add_point(root, "wpt", lon, lat, ele, None, landmark.id, landmark.kind)
    if steps is not None and len(steps):
        if len(trajectory) == 0:
            raise InputError("steps given but the trajectory is empty", where="steps",
                             expected="a trajectory to place the steps on")
        coords = to_output_coordinates(trajectory.position_at(steps.t_end), georeference)
        times = (None if time_origin_unix_s is None
                 else unix_us_from_times(steps.t_end, time_origin_unix_s))
        for i, (lon, lat, ele) in enumerate(coords.tolist()):
            _add_point(root, "wpt", lon, lat, ele, None if times is None else int(times[i]),
                       f"step {i}", "step")
    track = ET.SubElement(root, _q("trk"))
    if name is not None:
        ET.SubElement(track, _q("name")).text = name
    segment = ET.SubElement(track, _q("trkseg"))
    coords = to_output_coordinates(trajectory.xyz, georeference)
    times = (None if time_origin_unix_s is None
             else unix_us_from_times(trajectory.t, time_origin_unix_s))
    if times is not None and len(times) > 1 and np.any(np.diff(times) <= 0):
        idx = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise InputError("two samples less than 1 us apart", where=f"trajectory index {idx}",
                         expected="times at least 1 us apart (GPX times have us resolution)")
    for i, (lon, lat, ele) in enumerate(coords.tolist()):
        _add_point(segment, "trkpt", lon, lat, ele, None if times is None else int(times[i]))
    tree = ET.ElementTree(root)
    ET.indent(tree, space=" ")
    return tree


def write_gpx(trajectory: Trajectory, path: str | Path, *, georeference: Georeference | None,
              time_origin_unix_s: float | None = None, steps: StepEvents | None = None,
              landmarks: LandmarkInput = None, name: str | None = None,
              overwrite: bool = False) -> Path:
    """Write a trajectory as a GPX 1.1 track.

    Parameters
    ----------
    trajectory:
        The track (local ENU metres).
    path:
        Output file (``.gpx``); its folder is created.
    georeference:
        Required: anchors the local frame on WGS-84. None raises
        :class:`~hrtls.errors.InputError`.
    time_origin_unix_s:
        Unix time of ``t = 0``; with it every point gets a ``<time>``.
    steps, landmarks:
        Optional waypoints (steps at the trajectory position of their end time).
    name:
        Track name.
    overwrite:
        Replace an existing file.
    """
    target = prepare_target(path, overwrite)
    tree = gpx_tree(trajectory, georeference=georeference, time_origin_unix_s=time_origin_unix_s,
                    steps=steps, landmarks=landmarks, name=name)
    tmp = target.with_name(target.name + ".partial")
    tree.write(tmp, encoding="UTF-8", xml_declaration=True)
    tmp.replace(target)
    return target


# --------------------------------------------------------------------------------------------
# reader
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class GpxWaypoint:
    """A ``<wpt>``: position (deg, m), optional time (us since 1970), name and type."""

    lat_deg: float
    lon_deg: float
    ele_m: float | None
    time_unix_us: int | None
    name: str | None
    kind: str | None


@dataclass(frozen=True, slots=True, eq=False)
class GpxTrack:
    """What :func:`read_gpx` found: the track points of all segments, in file order.

    Attributes
    ----------
    lat_deg, lon_deg:
        Track point coordinates, degrees, (N,).
    ele_m:
        Elevations, m, (N,), or None when no point has one (NaN for points without).
    time_unix_us:
        Times, integer microseconds since the Unix epoch, or None when no point has one.
    waypoints:
        The ``<wpt>`` elements.
    name:
        Track name, when present.
    """

    lat_deg: FloatArray
    lon_deg: FloatArray
    ele_m: FloatArray | None
    time_unix_us: IntArray | None
    waypoints: list[GpxWaypoint] = field(default_factory=list)
    name: str | None = None

    def xyz(self, georeference: Georeference) -> FloatArray:
        """Track points in the local frame of ``georeference``, m.

        A missing elevation is taken as the georeference's height.
        """
        ele = (np.full(len(self.lat_deg), georeference.height_m) if self.ele_m is None
               else np.where(np.isfinite(self.ele_m), self.ele_m, georeference.height_m))
        if len(self.lat_deg) == 0:
            return np.zeros((0, 3))
        return georeference.from_wgs84(self.lat_deg, self.lon_deg, ele)

    def t_s(self, time_origin_unix_s: float | None = None) -> FloatArray:
        """Times in s from the origin (default: the first point)."""
        if self.time_unix_us is None:
            raise InputError("the track has no times", where="GPX track",
                             expected="<time> in every track point")
        origin_us = (int(self.time_unix_us[0]) if time_origin_unix_s is None
                     else round(time_origin_unix_s * 1e6))
        return np.asarray((self.time_unix_us - origin_us) / 1e6, dtype=np.float64)


def _text(element: ET.Element, ns: str, tag: str) -> str | None:
    child = element.find(f"{{{ns}}}{tag}") if ns else element.find(tag)
    return None if child is None or child.text is None else child.text.strip()


def _point(element: ET.Element, ns: str, where: str
           ) -> tuple[float, float, float | None, int | None]:
    try:
        lat = float(element.attrib["lat"])
        lon = float(element.attrib["lon"])
    except (KeyError, ValueError):
        raise FormatError("missing or bad lat/lon", where=where,
                          expected="lat and lon attributes in degrees") from None
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0):
        raise FormatError(f"lat {lat}, lon {lon}", where=where, expected="valid degrees")
    ele_text = _text(element, ns, "ele")
    try:
        ele = None if ele_text is None else float(ele_text)
    except ValueError:
        raise FormatError(f"ele {ele_text!r}", where=where, expected="metres") from None
    time_text = _text(element, ns, "time")
    time_us = None if time_text is None else unix_us_from_iso8601(time_text, where=where)
    return lat, lon, ele, time_us


def read_gpx(path: str | Path) -> GpxTrack:
    """Read the track points and waypoints of a GPX 1.1 (or 1.0) file."""
    file = Path(path)
    if not file.is_file():
        raise InputError("file not found", where=str(file), expected="a GPX file")
    try:
        root = ET.parse(file).getroot()
    except ET.ParseError as exc:
        raise FormatError(f"invalid XML ({exc})", where=str(file), expected="GPX") from None
    ns = ""
    if root.tag.startswith("{"):
        ns = root.tag[1:].split("}", 1)[0]
    if root.tag != (f"{{{ns}}}gpx" if ns else "gpx") or ns not in ("", GPX_NS, _GPX10_NS):
        raise FormatError(f"root element {root.tag!r}", where=str(file),
                          expected="<gpx> in the GPX 1.1 namespace")

    def q(tag: str) -> str:
        return f"{{{ns}}}{tag}" if ns else tag

    lat: list[float] = []
    lon: list[float] = []
    ele: list[float] = []
    times: list[int | None] = []
    any_ele = False
    name = None
    for k, track in enumerate(root.iter(q("trk"))):
        if name is None:
            name = _text(track, ns, "name")
        for s, segment in enumerate(track.iter(q("trkseg"))):
            for i, point in enumerate(segment.iter(q("trkpt"))):
                la, lo, el, tu = _point(point, ns, f"{file.name} trk[{k}] trkseg[{s}] trkpt[{i}]")
                lat.append(la)
                lon.append(lo)
                ele.append(np.nan if el is None else el)
                any_ele = any_ele or el is not None
                times.append(tu)
    waypoints = []
    for i, point in enumerate(root.iter(q("wpt"))):
        la, lo, el, tu = _point(point, ns, f"{file.name} wpt[{i}]")
        waypoints.append(GpxWaypoint(la, lo, el, tu, _text(point, ns, "name"),
                                     _text(point, ns, "type")))
    present = [t is not None for t in times]
    time_us: IntArray | None = None
    if any(present):
        if not all(present):
            idx = present.index(False)
            raise FormatError("track point without <time>", where=f"{file.name} trkpt {idx}",
                              expected="<time> in all track points or in none")
        time_us = np.array(times, dtype=np.int64)
    return GpxTrack(lat_deg=np.asarray(lat, dtype=np.float64),
                    lon_deg=np.asarray(lon, dtype=np.float64),
                    ele_m=np.asarray(ele, dtype=np.float64) if any_ele else None,
                    time_unix_us=time_us, waypoints=waypoints, name=name)
