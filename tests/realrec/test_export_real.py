"""`hrtls export` of a georeferenced real recording: GPX and WGS-84 GeoJSON round trips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.io.geojson import read_geojson
from hrtls.io.gpx import read_gpx
from hrtls.io.tables import read_trajectory

runner = CliRunner()


def test_ipin_result_exports_to_gpx_and_wgs84_geojson(shared_data: Path, tmp_path: Path) -> None:
    log = shared_data / "ipin2023" / "IPIN2023_T3_TrainingTrial04_repetition01.txt"
    if not log.exists():
        pytest.skip("ipin2023 recordings not available")
    out = tmp_path / "t04"
    assert runner.invoke(app, ["track", str(log), "-o", str(out), "-p", "handheld-phone"]
                         ).exit_code == 0
    res = runner.invoke(app, ["export", str(out), "--to", "gpx"])
    assert res.exit_code == 0, res.output
    estimate = read_trajectory(out / "trajectory.csv")
    gpx = read_gpx(out / "trajectory.gpx")
    geo = read_geojson(out / "trajectory.geojson")
    assert geo.is_wgs84 and geo.georeference is not None
    assert len(gpx.lat_deg) == len(estimate)
    np.testing.assert_allclose(geo.xyz()[:, :2], estimate.xyz[:, :2], atol=1e-3)
    np.testing.assert_allclose(gpx.lat_deg, geo.coordinates[:, 1], atol=1e-7)
    # Nuremberg, the venue of IPIN 2023
    assert 49.0 < np.median(gpx.lat_deg) < 49.9 and 10.5 < np.median(gpx.lon_deg) < 11.5
