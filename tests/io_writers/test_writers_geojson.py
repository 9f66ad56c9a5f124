from __future__ import annotations

import json
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

from hrtls.data import Landmark, Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.geojson import geojson_document, read_geojson, write_geojson


def test_local_file_structure_and_round_trip(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_geojson(traj, tmp_path / "out" / "track.geojson", steps=simple_steps(),
                         landmarks=simple_landmarks(), time_origin_unix_s=1.6e9, name="walk")
    doc = json.loads(path.read_text())
    assert doc["type"] == "FeatureCollection"
    assert doc["hrtls:crs"]["type"] == "local-enu"
    assert doc["hrtls:time_origin_unix_s"] == 1.6e9
    track = doc["features"][0]
    assert track["geometry"]["type"] == "LineString"
    assert track["geometry"]["coordinates"][1] == [1.0, -0.5, 0.0]
    assert track["properties"]["heading_rad"][1] is None
    assert track["properties"]["activity"][:2] == ["standing", "walking"]
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds == ["trajectory", "step", "step", "landmark", "landmark"]
    # step points sit on the trajectory at the step end
    assert doc["features"][1]["geometry"]["coordinates"] == [1.0, -0.5, 0.0]

    back = read_geojson(path)
    assert not back.is_wgs84 and back.name == "walk"
    np.testing.assert_array_equal(back.xyz(), traj.xyz)
    again = back.to_trajectory()
    np.testing.assert_array_equal(again.t, traj.t)
    np.testing.assert_array_equal(again.heading_rad, traj.heading_rad)
    np.testing.assert_array_equal(again.activity, traj.activity)
    assert back.time_origin_unix_s == 1.6e9
    assert back.steps is not None and len(back.steps) == 2
    np.testing.assert_array_equal(back.steps.length_m, [0.7, 0.72])
    assert np.isnan(back.steps.heading_rad[1])
    ids = {lm.id: lm for lm in back.landmarks}
    assert ids["TAG7"].position == (-4.0, 0.5, 0.0)
    assert ids["TAG7"].bearings_rad == (0.5, -1.0) and ids["TAG7"].kind == "rfid"


def test_wgs84_file_is_lon_lat_and_round_trips(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_geojson(traj, tmp_path / "t.geojson", georeference=GEO,
                         landmarks=simple_landmarks())
    doc = json.loads(path.read_text())
    lon, lat, h = doc["features"][0]["geometry"]["coordinates"][0]
    assert lon == pytest.approx(GEO.lon_deg) and lat == pytest.approx(GEO.lat_deg)
    assert h == pytest.approx(GEO.height_m)
    assert doc["hrtls:crs"]["type"] == "wgs84"
    back = read_geojson(path)
    assert back.is_wgs84 and back.georeference == GEO
    np.testing.assert_allclose(back.xyz(), traj.xyz, atol=1e-6)
    # a landmark's WGS-84 position resolves back to its local one
    tag = next(lm for lm in back.landmarks if lm.id == "TAG7")
    np.testing.assert_allclose(tag.resolved(GEO).xyz(), [-4.0, 0.5, 0.0], atol=1e-6)


def test_small_and_empty_tracks() -> None:
    one = Trajectory.build(t=[0.0], xyz=[[1.0, 2.0, 3.0]])
    assert geojson_document(one)["features"][0]["geometry"] == {
        "type": "Point", "coordinates": [1.0, 2.0, 3.0]}
    empty = Trajectory.build(t=np.zeros(0), xyz=np.zeros((0, 3)))
    assert geojson_document(empty)["features"][0]["geometry"] is None


def test_errors(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_geojson(traj, tmp_path / "t.geojson")
    with pytest.raises(InputError, match="already exists"):
        write_geojson(traj, path)
    write_geojson(traj, path, overwrite=True)
    only_wgs = Landmark(id="X", wgs84={"lat": 49.0, "lon": 11.0})
    with pytest.raises(InputError, match="WGS-84"):
        write_geojson(traj, tmp_path / "u.geojson", landmarks=[only_wgs])
    with pytest.raises(InputError, match="time origin"):
        geojson_document(traj, time_origin_unix_s=float("nan"))


def test_wgs84_without_georeference_cannot_give_local(tmp_path: Path) -> None:
    (tmp_path / "plain.geojson").write_text(json.dumps({
        "type": "Feature", "properties": {},
        "geometry": {"type": "LineString", "coordinates": [[11.0, 49.0], [11.001, 49.0]]}}))
    track = read_geojson(tmp_path / "plain.geojson")
    assert track.is_wgs84 and track.t_s is None
    np.testing.assert_allclose(track.coordinates[:, 2], 0.0)
    with pytest.raises(InputError, match="georeference"):
        track.xyz()
    local = track.xyz(Georeference(49.0, 11.0))
    assert local[1, 0] == pytest.approx(73.1, abs=0.2)  # 0.001 deg of longitude at 49 N


def test_reader_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.geojson"
    bad.write_text("{not json")
    with pytest.raises(FormatError, match="invalid JSON"):
        read_geojson(bad)
    bad.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"kind": "trajectory"},
         "geometry": {"type": "LineString", "coordinates": [[0, 0], ["a", 1]]}}]}))
    with pytest.raises(FormatError, match=r"coordinates\[1\]"):
        read_geojson(bad)
    bad.write_text(json.dumps({"type": "FeatureCollection", "features": []}))
    with pytest.raises(FormatError, match="no trajectory"):
        read_geojson(bad)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traj=trajectories())
def test_property_local_round_trip_is_exact(tmp_path: Path, traj: Trajectory) -> None:
    path = write_geojson(traj, tmp_path / "p.geojson", overwrite=True)
    text = path.read_text()
    assert "NaN" not in text  # strict JSON
    back = read_geojson(path).to_trajectory()
    np.testing.assert_array_equal(back.t, traj.t)
    np.testing.assert_array_equal(back.xyz, traj.xyz)
    np.testing.assert_array_equal(back.heading_rad, traj.heading_rad)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traj=trajectories(), geo=georeferences)
def test_property_wgs84_round_trip(tmp_path: Path, traj: Trajectory, geo: Georeference) -> None:
    path = write_geojson(traj, tmp_path / "g.geojson", georeference=geo, overwrite=True)
    back = read_geojson(path)
    coords = back.coordinates
    assert np.all(np.abs(coords[:, 1]) <= 90.0)
    np.testing.assert_allclose(back.xyz(), traj.xyz, atol=1e-5)
