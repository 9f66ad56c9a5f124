"""The floor selector against floors the live service reports (not only the ground floor).

Two robots stream wheel odometry to a real ``hrtls serve``: one checked in on the ground floor,
one on the first floor (z = the mission's floor height). The service's live estimates carry
each one's floor (``floor = round(z / floor_height_m)``); the dashboard must show each robot on
its own floor only and count them per floor.
"""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.service.client import AgentClient

from .conftest import login

pytestmark = pytest.mark.slow

FLOOR_HEIGHT_M = 3.0
# the live tracker of an agent without IMU starts after 30 s of data (service runner)
BACKLOG_S = 35.0


def _odometry(t0: float, seconds: float, x0: float, y0: float) -> dict[str, list[float]]:
    t = t0 + np.arange(0.0, seconds, 0.5)
    x = x0 + 0.3 * (t - t0)
    return {"t": t.tolist(), "x": x.tolist(), "y": [y0] * len(t),
            "heading_rad": [0.0] * len(t), "sigma_m": [0.2] * len(t)}


def _plan(width_m: float) -> dict[str, object]:
    ring = [[-2.0, -2.0], [width_m, -2.0], [width_m, 2.0], [-2.0, 2.0], [-2.0, -2.0]]
    return {"type": "FeatureCollection", "features": [{
        "type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {"kind": "corridor", "name": "corridor"}}]}


def _floors_shown(page) -> dict[int, set[int]]:
    out = {}
    for floor in (0, 1):
        page.click(f"#floors button[data-floor='{floor}']")
        page.wait_for_selector(f"#floors button[data-floor='{floor}'][aria-pressed='true']")
        page.wait_for_timeout(300)
        out[floor] = set(page.evaluate("() => [...document.querySelectorAll('path.agent-dot')]"
                                       ".map(e => Number(e.dataset.agent))"))
    return out


def test_floor_selector_follows_the_floors_of_the_live_estimates(page, page_log, service,
                                                                  screenshot):
    status, mission = service.api("POST", "/missions", {
        "name": "two floors", "floor_height_m": FLOOR_HEIGHT_M, "floors": [
            {"index": 0, "name": "Ground floor", "height_m": 0.0, "plan": _plan(20.0)},
            {"index": 1, "name": "First floor", "height_m": FLOOR_HEIGHT_M, "plan": _plan(30.0)}]})
    assert status == 201, mission
    mid = int(mission["id"])
    _, m = service.api("GET", f"/missions/{mid}")
    t0 = float(m["now_t"]) - BACKLOG_S
    robots = {}
    for name, floor in (("Ground robot", 0), ("Upstairs robot", 1)):
        status, out = service.api("POST", f"/missions/{mid}/agents", {"name": name,
                                                                      "kind": "robot"})
        assert status == 201, out
        robots[floor] = (int(out["agent"]["id"]), str(out["token"]))
    for floor, (_, token) in robots.items():
        with AgentClient(service.url, token) as client:
            client.checkin({"t": t0, "x": 0.0, "y": 0.0, "z": floor * FLOOR_HEIGHT_M,
                            "heading": 0.0, "sigma_xy_m": 0.3, "sigma_heading_rad": 0.1})
            client.submit({"odometry": _odometry(t0, BACKLOG_S, 0.0, 0.0)})
            assert client.flush(max_wait_s=30)

    def service_floors() -> dict[int, int]:
        _, snap = service.api("GET", f"/missions/{mid}/snapshot")
        return {int(e["agent"]): int(e["floor"]) for e in snap["estimates"]}

    login(page, service)
    page.goto(f"{service.url}/?mission={mid}")
    page.wait_for_selector("#app:not([hidden])")
    page.wait_for_function("() => window.hrtlsDashboard.agents.size === 2 && "
                           "[...window.hrtlsDashboard.agents.values()].every(a => a.est)",
                           timeout=90_000)
    by_agent = service_floors()
    assert by_agent == {robots[0][0]: 0, robots[1][0]: 1}, by_agent
    shown = _floors_shown(page)
    assert shown == {0: {robots[0][0]}, 1: {robots[1][0]}}
    for floor in (0, 1):
        button = f"#floors button[data-floor='{floor}']"
        assert page.get_attribute(button, "data-count") == "1"
    assert page.locator("#agents li", has_text="F1").count() == 1
    screenshot(page, "floors_live")
    page_log.assert_clean()
