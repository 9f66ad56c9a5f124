"""``GET /dashboard/config``: the base map's tile source, for signed-in readers only."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import httpx

from .conftest import Live, new_agent, new_mission

API = "/api/v1"
TILES = "http://127.0.0.1:9/{z}/{x}/{y}.png"


def test_no_base_map_by_default(commander: httpx.Client) -> None:
    r = commander.get(f"{API}/dashboard/config")
    assert r.status_code == 200 and r.json() == {"basemap": None}


def test_base_map_named_by_the_deployment(make_live: Callable[..., Live]) -> None:
    live = make_live(basemap_url=TILES, basemap_attribution="(c) the county")
    with live.client(live.commander) as commander:
        r = commander.get(f"{API}/dashboard/config")
        assert r.status_code == 200
        assert r.json() == {"basemap": {"url": TILES, "max_zoom": 19,
                                        "attribution": "(c) the county"}}
        mid = new_mission(commander)["id"]
        agent_token = new_agent(commander, mid)["token"]
    with live.client() as anonymous:
        assert anonymous.get(f"{API}/dashboard/config").status_code == 401
    with live.client(agent_token) as agent:
        assert agent.get(f"{API}/dashboard/config").status_code == 403


def test_serve_refuses_a_bad_tile_template(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    for bad in ("tiles.local/{z}/{x}/{y}.png", "http://tiles.local/{z}/{x}.png"):
        r = CliRunner().invoke(app, ["serve", "--db", str(tmp_path / "x.db"),
                                     "--basemap-url", bad])
        assert r.exit_code == 2 and "--basemap-url" in r.output and "{z}" in r.output, r.output


def test_security_headers_on_the_page_and_the_api(make_live: Callable[..., Live]) -> None:
    live = make_live(basemap_url=TILES)
    with live.client(live.commander) as commander:
        for path in ("/", f"{API}/dashboard/config", f"{API}/missions/999"):
            r = commander.get(path)
            assert r.headers["x-content-type-options"] == "nosniff", path
            assert r.headers["x-frame-options"] == "DENY"
            assert r.headers["referrer-policy"] == "no-referrer"
            csp = r.headers["content-security-policy"]
            assert "script-src 'self';" in csp and "frame-ancestors 'none'" in csp
            assert "img-src 'self' data: blob: http://127.0.0.1:9;" in csp
        docs = commander.get(f"{API}/docs")
        assert "content-security-policy" not in docs.headers
        assert docs.headers["x-frame-options"] == "DENY"
