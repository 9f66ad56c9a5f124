"""A georeferenced mission over a web-mercator base map served on loopback.

The tile server is a real HTTP server (this test's), named with ``hrtls serve --basemap-url``.
The page must ask it for the tiles around the mission's anchor and draw local positions where
the slippy-map formulas (and, away from the anchor, the exact geodetic conversion of
``hrtls.frames.Georeference``) put them on those tiles.
"""

from __future__ import annotations

import io
import math
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import ClassVar

import pytest
from PIL import Image

from hrtls.frames import Georeference

from .conftest import login, start_service, stop_service

pytestmark = pytest.mark.slow

GEOREF = {"lat_deg": 48.137, "lon_deg": 11.575, "height_m": 0.0, "rotation_rad": 0.3}
MAX_ZOOM = 19
TILE_PATH = re.compile(r"/(\d+)/(\d+)/(\d+)\.png$")


class _Tiles(BaseHTTPRequestHandler):
    requests: ClassVar[list[tuple[int, int, int]]] = []

    def do_GET(self) -> None:
        m = TILE_PATH.search(self.path)
        if not m:
            self.send_error(404)
            return
        z, x, y = (int(v) for v in m.groups())
        type(self).requests.append((z, x, y))
        buf = io.BytesIO()
        Image.new("RGB", (256, 256), ((x * 37) % 256, (y * 59) % 256, 120)).save(buf, "PNG")
        body = buf.getvalue()
        self.send_response(200)
        self.send_header("Content-Type", "image/png")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def tiles():
    _Tiles.requests = []
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Tiles)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()


def _tile_xy(lat: float, lon: float, z: int) -> tuple[float, float]:
    n = 2.0 ** z
    phi = math.radians(lat)
    return ((lon + 180.0) / 360.0 * n,
            (1.0 - math.log(math.tan(phi) + 1.0 / math.cos(phi)) / math.pi) / 2.0 * n)


def _screen_of(page, lat: float, lon: float) -> tuple[float, float]:
    """Where (lat, lon) lies on screen, from a drawn tile's box and its z / x / y."""
    tiles = page.evaluate("""() => [...document.querySelectorAll('img.leaflet-tile')]
        .filter(t => t.complete && t.naturalWidth > 0)
        .map(t => ({src: t.src, box: t.getBoundingClientRect().toJSON()}))""")
    assert tiles, "no tile drawn"
    t = tiles[0]
    z, x, y = (int(v) for v in TILE_PATH.search(t["src"]).groups())
    fx, fy = _tile_xy(lat, lon, z)
    box = t["box"]
    return box["left"] + (fx - x) * box["width"], box["top"] + (fy - y) * box["height"]


def _centre(page, selector: str) -> tuple[float, float]:
    box = page.eval_on_selector(selector, "e => e.getBoundingClientRect().toJSON()")
    return box["left"] + box["width"] / 2, box["top"] + box["height"] / 2


def test_georeferenced_mission_on_base_map_tiles(page, page_log, tiles, tmp_path, screenshot):
    url = f"http://127.0.0.1:{tiles.server_address[1]}/{{z}}/{{x}}/{{y}}.png"
    service = start_service(tmp_path, "--basemap-url", url)
    try:
        status, cfg = service.api("GET", "/dashboard/config")
        assert status == 200 and cfg["basemap"]["url"] == url
        status, mission = service.api("POST", "/missions", {
            "name": "on the map", "georeference": GEOREF,
            "floors": [{"index": 0, "name": "Ground", "height_m": 0.0}]})
        assert status == 201, mission
        mid = int(mission["id"])
        for key, pos in (("T0", [0.0, 0.0, 0.0]), ("T1", [40.0, 0.0, 0.0])):
            status, body = service.api("POST", f"/missions/{mid}/landmarks", {
                "id": key, "kind": "rfid", "position": pos, "floor": 0})
            assert status == 201, body
        login(page, service)
        page.select_option("#mission-select", str(mid))
        page.wait_for_selector("path.landmark-T1")
        page.wait_for_function("() => [...document.querySelectorAll('img.leaflet-tile')]"
                               ".some(t => t.complete && t.naturalWidth > 0)")
        page.evaluate("() => window.hrtlsDashboard.map.map.setView([0, 0], "
                      "window.hrtlsDashboard.map.map.getZoom(), {animate: false})")
        page.wait_for_timeout(500)
        assert _Tiles.requests and all(z <= MAX_ZOOM for z, _, _ in _Tiles.requests)
        zs = {z for z, _, _ in _Tiles.requests}
        z = max(zs)
        ax, ay = _tile_xy(GEOREF["lat_deg"], GEOREF["lon_deg"], z)
        assert (z, int(ax), int(ay)) in _Tiles.requests  # the anchor's tile was fetched
        want = _screen_of(page, GEOREF["lat_deg"], GEOREF["lon_deg"])
        got = _centre(page, "path.landmark-T0")
        assert got == pytest.approx(want, abs=2.0)
        lat1, lon1, _ = Georeference(**GEOREF).to_wgs84([40.0, 0.0, 0.0])[0]
        want1 = _screen_of(page, float(lat1), float(lon1))
        got1 = _centre(page, "path.landmark-T1")
        assert got1 == pytest.approx(want1, abs=3.0)
        # 40 m along local x, 0.3 rad north of east: up and to the right on a north-up map
        assert got1[0] > got[0] and got1[1] < got[1]
        screenshot(page, "basemap")
        assert not page_log.errors and not page_log.failed and not page_log.external
    finally:
        stop_service(service)
