from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from _writer_strategies import GEO, georeferences, simple_trajectory, trajectories
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.data import Trajectory
from hrtls.errors import FormatError, InputError
from hrtls.frames import Georeference
from hrtls.io.movingfeatures import (
    iso8601_from_unix_us,
    movingfeatures_document,
    read_movingfeatures,
    unix_us_from_iso8601,
    write_movingfeatures,
)

ISO_UTC = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z$")


def test_iso8601_hand_cases() -> None:
    assert iso8601_from_unix_us(0) == "1970-01-01T00:00:00.000000Z"
    assert iso8601_from_unix_us(1_607_605_064_733_000) == "2020-12-10T12:57:44.733000Z"
    assert unix_us_from_iso8601("2020-12-10T13:57:44.733+01:00", where="x") == \
        1_607_605_064_733_000
    assert unix_us_from_iso8601("1970-01-01T00:00:01", where="x") == 1_000_000  # naive = UTC
    with pytest.raises(FormatError, match="ISO 8601"):
        unix_us_from_iso8601("yesterday", where="x")


def test_document_structure() -> None:
    traj = simple_trajectory()
    doc = movingfeatures_document(traj, time_origin_unix_s=1607605064.733, name="walk")
    assert doc["type"] == "Feature"
    geom = doc["temporalGeometry"]
    assert geom["type"] == "MovingPoint" and geom["interpolation"] == "Linear"
    assert geom["datetimes"][0] == "2020-12-10T12:57:44.733000Z"
    assert geom["datetimes"][1] == "2020-12-10T12:57:45.233000Z"
    assert all(ISO_UTC.match(d) for d in geom["datetimes"])
    assert len(geom["coordinates"]) == len(traj)
    assert doc["crs"]["properties"]["name"] == "hrtls:local-enu"
    assert doc["hrtls:crs"]["type"] == "local-enu"
    assert doc["time"] == [geom["datetimes"][0], geom["datetimes"][-1]]
    heading = doc["temporalProperties"][0]
    assert len(heading["datetimes"]) == len(traj) - 1  # the NaN heading is left out
    assert heading["heading_rad"]["form"] == "rad"
    geo_doc = movingfeatures_document(traj, time_origin_unix_s=0.0, georeference=GEO)
    assert geo_doc["crs"]["properties"]["name"] == "urn:ogc:def:crs:OGC:1.3:CRS84"
    lon, lat, _ = geo_doc["temporalGeometry"]["coordinates"][0]
    assert lon == pytest.approx(GEO.lon_deg) and lat == pytest.approx(GEO.lat_deg)


def test_needs_time_origin_and_samples(tmp_path: Path) -> None:
    traj = simple_trajectory()
    with pytest.raises(InputError, match="time origin"):
        write_movingfeatures(traj, tmp_path / "m.json", time_origin_unix_s=None)
    empty = Trajectory.build(t=np.zeros(0), xyz=np.zeros((0, 3)))
    with pytest.raises(InputError, match="empty"):
        write_movingfeatures(empty, tmp_path / "m.json", time_origin_unix_s=0.0)
    close = Trajectory.build(t=[0.0, 2e-7], xyz=np.zeros((2, 3)))
    with pytest.raises(InputError, match="1 us"):
        write_movingfeatures(close, tmp_path / "m.json", time_origin_unix_s=0.0)


def test_round_trip_with_heading(tmp_path: Path) -> None:
    traj = simple_trajectory()
    path = write_movingfeatures(traj, tmp_path / "m.json", time_origin_unix_s=1.6e9,
                                georeference=GEO, name="walk")
    back = read_movingfeatures(path)
    assert back.is_wgs84 and back.georeference == GEO and back.name == "walk"
    assert back.time_origin_unix_s == 1.6e9
    again = back.to_trajectory()
    np.testing.assert_allclose(again.t, traj.t, atol=1e-6)
    np.testing.assert_allclose(again.xyz, traj.xyz, atol=1e-6)
    np.testing.assert_array_equal(np.isnan(again.heading_rad), np.isnan(traj.heading_rad))
    np.testing.assert_allclose(again.heading_rad, traj.heading_rad)
    # times relative to the first sample when asked for another origin
    np.testing.assert_allclose(back.t_s(1.6e9 + 0.5), traj.t - 0.5, atol=1e-6)


def test_reader_accepts_collections_and_rejects_bad_files(tmp_path: Path) -> None:
    doc = movingfeatures_document(simple_trajectory(), time_origin_unix_s=10.0)
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [doc]}))
    assert len(read_movingfeatures(path).time_unix_us) == 5
    doc["temporalGeometry"]["datetimes"][2] = doc["temporalGeometry"]["datetimes"][1]
    path.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match=r"datetimes\[2\]"):
        read_movingfeatures(path)
    path.write_text(json.dumps({"type": "Feature", "geometry": None, "properties": {}}))
    with pytest.raises(FormatError, match="MovingPoint"):
        read_movingfeatures(path)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(traj=trajectories(), origin=st.floats(min_value=0.0, max_value=4.0e9),
       geo=st.one_of(st.none(), georeferences))
def test_property_round_trip(tmp_path: Path, traj: Trajectory, origin: float,
                             geo: Georeference | None) -> None:
    path = write_movingfeatures(traj, tmp_path / "p.json", time_origin_unix_s=origin,
                                georeference=geo, overwrite=True)
    back = read_movingfeatures(path).to_trajectory()
    np.testing.assert_allclose(back.t, traj.t, atol=1e-6, rtol=0)
    np.testing.assert_allclose(back.xyz, traj.xyz, atol=1e-5 if geo else 0.0, rtol=0)
    np.testing.assert_array_equal(np.isnan(back.heading_rad), np.isnan(traj.heading_rad))
