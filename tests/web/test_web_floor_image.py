"""A floor's plan image drawn under the plan, in the mission frame, for a signed-in reader."""

from __future__ import annotations

import io
import urllib.request

import pytest
from PIL import Image

from .conftest import login

pytestmark = pytest.mark.slow


def _png(width: int, height: int) -> bytes:
    buf = io.BytesIO()
    im = Image.new("RGB", (width, height), (40, 60, 90))
    for x in range(width):  # a white line along the bottom row: y = origin_y_m on the map
        im.putpixel((x, height - 1), (255, 255, 255))
    im.save(buf, format="PNG")
    return buf.getvalue()


def _put_image(service, mid: int, floor: int, data: bytes, **place: float) -> int:
    query = "&".join(f"{k}={v}" for k, v in place.items())
    req = urllib.request.Request(
        f"{service.url}/api/v1/missions/{mid}/floors/{floor}/image?{query}", data=data,
        method="PUT", headers={"Authorization": f"Bearer {service.token}",
                               "Content-Type": "image/png"})
    with urllib.request.urlopen(req, timeout=30) as resp:
        return int(resp.status)


def test_floor_image_overlay_follows_floor_and_placement(page, page_log, service, screenshot):
    status, mission = service.api("POST", "/missions", {
        "name": "scanned plans", "floors": [
            {"index": 0, "name": "Ground floor", "height_m": 0.0},
            {"index": 1, "name": "First floor", "height_m": 3.0}]})
    assert status == 201, mission
    mid = int(mission["id"])
    # ground floor: 200 x 100 px at 0.1 m/px from (-4, -2) m, i.e. x -4..16 m, y -2..8 m
    assert _put_image(service, mid, 0, _png(200, 100), origin_x_m=-4, origin_y_m=-2,
                      m_per_px=0.1) == 200
    login(page, service)
    page.select_option("#mission-select", str(mid))
    page.wait_for_selector("img.plan-image")
    page.wait_for_function("() => document.querySelector('img.plan-image').naturalWidth > 0")
    # the map animates its first fit: measure once the image and the map agree and are still
    page.wait_for_function("""() => {
      const img = document.querySelector('img.plan-image');
      const m = window.hrtlsDashboard.map.map;
      if (!img || m._animatingZoom || m._panAnim?._inProgress) return false;
      const b = img.getBoundingClientRect();
      const r = m.getContainer().getBoundingClientRect();
      const p = m.latLngToContainerPoint([-2, -4]);
      return Math.abs(p.x + r.left - b.left) < 1.5 && Math.abs(p.y + r.top - b.bottom) < 1.5;
    }""", timeout=10_000)
    info = page.evaluate("""() => {
      const img = document.querySelector('img.plan-image');
      return {w: img.naturalWidth, h: img.naturalHeight, box: img.getBoundingClientRect().toJSON()};
    }""")
    assert (info["w"], info["h"]) == (200, 100)
    box = info["box"]
    # drawn with the image's own aspect ratio (20 m x 10 m), as CRS.Simple keeps metres square
    assert box["width"] / box["height"] == pytest.approx(2.0, rel=0.02)
    # its lower-left corner is the map point (-4, -2) m
    corner = page.evaluate("""([x, y]) => {
      const m = window.hrtlsDashboard.map.map;
      const p = m.latLngToContainerPoint([y, x]);
      const r = m.getContainer().getBoundingClientRect();
      return {x: p.x + r.left, y: p.y + r.top};
    }""", [-4.0, -2.0])
    assert corner["x"] == pytest.approx(box["left"], abs=1.5)
    assert corner["y"] == pytest.approx(box["bottom"], abs=1.5)
    screenshot(page, "floor-image")
    # the first floor has no image
    page.click("#floors button[data-floor='1']")
    page.wait_for_selector("#floors button[data-floor='1'][aria-pressed='true']")
    page.wait_for_function("() => !document.querySelector('img.plan-image')")
    page.click("#floors button[data-floor='0']")
    page.wait_for_selector("img.plan-image")
    assert not page_log.errors and not page_log.failed and not page_log.external
