from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from _writer_strategies import (
    GEO,
    georeferences,
    simple_landmarks,
    simple_steps,
    simple_trajectory,
    trajectories,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.data import Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.gpx import GPX_NS, read_gpx, write_gpx

NS = {"g": GPX_NS}


def test_structure(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_gpx(traj, tmp_path / "t.gpx", georeference=GEO, time_origin_unix_s=1.6e9,
                     landmarks=simple_landmarks(), steps=simple_steps(), name="walk")
    root = ET.parse(path).getroot()
    assert root.tag == f"{{{GPX_NS}}}gpx" and root.attrib["version"] == "1.1"
    points = root.findall("g:trk/g:trkseg/g:trkpt", NS)
    assert len(points) == len(traj)
    first = points[0]
    assert float(first.attrib["lat"]) == pytest.approx(GEO.lat_deg)
    assert float(first.attrib["lon"]) == pytest.approx(GEO.lon_deg)
    assert [c.tag.split("}")[1] for c in first] == ["ele", "time"]
    assert first.find("g:time", NS).text == "2020-09-13T12:26:40.000000Z"  # type: ignore[union-attr]
    # children of <gpx> in schema order: metadata, wpt*, trk
    tags = [c.tag.split("}")[1] for c in root]
    assert tags == ["metadata", "wpt", "wpt", "wpt", "wpt", "trk"]
    wpt = root.find("g:wpt", NS)
    assert wpt is not None and wpt.find("g:name", NS).text == "BLE1"  # type: ignore[union-attr]
    assert [c.tag.split("}")[1] for c in wpt] == ["ele", "name", "type"]


def test_requires_georeference_and_optional_times(tmp_path: Path) -> None:
    traj = simple_trajectory()
    with pytest.raises(InputError, match="georeference"):
        write_gpx(traj, tmp_path / "a.gpx", georeference=None)
    path = write_gpx(traj, tmp_path / "b.gpx", georeference=GEO)
    back = read_gpx(path)
    assert back.time_unix_us is None
    with pytest.raises(InputError, match="no times"):
        back.t_s()
    np.testing.assert_allclose(back.xyz(GEO), traj.xyz, atol=1e-4)


def test_round_trip_with_waypoints(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_gpx(traj, tmp_path / "t.gpx", georeference=GEO, time_origin_unix_s=1.6e9,
                     landmarks=simple_landmarks(), steps=simple_steps(), name="walk")
    back = read_gpx(path)
    assert back.name == "walk"
    np.testing.assert_allclose(back.t_s(1.6e9), traj.t, atol=1e-6)
    np.testing.assert_allclose(back.t_s(), traj.t - traj.t[0], atol=1e-6)
    np.testing.assert_allclose(back.xyz(GEO), traj.xyz, atol=1e-4)
    names = [w.name for w in back.waypoints]
    assert names == ["BLE1", "TAG7", "step 0", "step 1"]
    ble = back.waypoints[0]
    local = GEO.from_wgs84(ble.lat_deg, ble.lon_deg, ble.ele_m)[0]
    np.testing.assert_allclose(local, [1.0, 2.0, 3.0], atol=1e-4)
    assert back.waypoints[2].kind == "step" and back.waypoints[2].time_unix_us is not None


def test_reader_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.gpx"
    bad.write_text("<gpx><trk>")
    with pytest.raises(FormatError, match="invalid XML"):
        read_gpx(bad)
    bad.write_text('<kml xmlns="http://www.opengis.net/kml/2.2"/>')
    with pytest.raises(FormatError, match="root element"):
        read_gpx(bad)
    bad.write_text(f'<gpx xmlns="{GPX_NS}"><trk><trkseg><trkpt lat="91" lon="0"/>'
                   "</trkseg></trk></gpx>")
    with pytest.raises(FormatError, match="trkpt"):
        read_gpx(bad)
    bad.write_text(f'<gpx xmlns="{GPX_NS}"><trk><trkseg>'
                   '<trkpt lat="1" lon="0"><time>2020-01-01T00:00:00Z</time></trkpt>'
                   '<trkpt lat="1" lon="0"/></trkseg></trk></gpx>')
    with pytest.raises(FormatError, match="without <time>"):
        read_gpx(bad)


def test_gpx10_without_elevation(tmp_path: Path) -> None:
    path = tmp_path / "old.gpx"
    path.write_text('<gpx xmlns="http://www.topografix.com/GPX/1/0" version="1.0"><trk>'
                    '<trkseg><trkpt lat="49.0" lon="11.0"/><trkpt lat="49.0" lon="11.001"/>'
                    "</trkseg></trk></gpx>")
    back = read_gpx(path)
    assert back.ele_m is None
    xyz = back.xyz(Georeference(49.0, 11.0))
    assert xyz[1, 0] == pytest.approx(73.1, abs=0.2)


@settings(max_examples=50, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traj=trajectories(), geo=georeferences,
       origin=st.one_of(st.none(), st.floats(min_value=0.0, max_value=4.0e9)))
def test_property_round_trip(tmp_path: Path, traj: Trajectory, geo: Georeference,
                             origin: float | None) -> None:
    path = write_gpx(traj, tmp_path / "p.gpx", georeference=geo, time_origin_unix_s=origin,
                     overwrite=True)
    back = read_gpx(path)
    np.testing.assert_allclose(back.xyz(geo), traj.xyz, atol=1e-4, rtol=0)
    if origin is None:
        assert back.time_unix_us is None
    else:
        np.testing.assert_allclose(back.t_s(origin), traj.t, atol=1e-6, rtol=0)
