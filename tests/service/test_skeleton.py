"""Missions, agents, landmarks, floors, tokens and every refusal of the skeleton API."""

from __future__ import annotations

import hashlib
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import select
from tests.service.conftest import Live, new_agent, new_mission

from hrtls.service.db import make_engine, session_factory
from hrtls.service.models import Base, Token

API = "/api/v1"

PLAN = {"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"kind": "room", "name": "R1"},
     "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]]}},
]}


def test_health_needs_no_token(live: Live) -> None:
    with live.client() as c:
        r = c.get(f"{API}/health")
    assert r.status_code == 200
    assert r.json()["status"] == "ok"
    assert r.json()["db"] == live.settings.backend


def test_schema_of_migrations_equals_models(live: Live) -> None:
    engine = make_engine(live.settings.db_url)
    try:
        with engine.connect() as conn:
            diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    finally:
        engine.dispose()
    assert diff == []


def test_mission_floor_landmark_agent_crud(commander: httpx.Client) -> None:
    m = new_mission(commander, floors=[{"index": 0, "name": "Ground", "height_m": 0.0,
                                        "plan": PLAN}],
                    georeference={"lat_deg": 48.1, "lon_deg": 11.5})
    assert m["floors"][0]["plan"] == PLAN
    assert m["georeference"]["lat_deg"] == 48.1
    assert m["alarm_profile"]["prealarm_s"] == 20.0
    assert 0.0 <= m["now_t"] < 60.0
    mid = m["id"]
    listed = commander.get(f"{API}/missions").json()
    assert [x["id"] for x in listed] == [mid] and listed[0]["n_agents"] == 0

    r = commander.patch(f"{API}/missions/{mid}", json={"name": "renamed", "stale_after_s": 5})
    assert r.status_code == 200 and r.json()["name"] == "renamed"
    assert r.json()["stale_after_s"] == 5.0

    r = commander.put(f"{API}/missions/{mid}/floors/1", json={"name": "First", "height_m": 3.2})
    assert r.status_code == 200
    floors = commander.get(f"{API}/missions/{mid}").json()["floors"]
    assert [(f["index"], f["name"]) for f in floors] == [(0, "Ground"), (1, "First")]
    assert commander.delete(f"{API}/missions/{mid}/floors/1").status_code == 204
    assert commander.delete(f"{API}/missions/{mid}/floors/1").status_code == 404

    tag = {"id": "T1", "kind": "rfid", "position": [3.0, 4.0, 0.0], "floor": 0,
           "bearings_rad": [0.0], "accuracy_m": 1.0}
    r = commander.post(f"{API}/missions/{mid}/landmarks", json=tag)
    assert r.status_code == 201 and r.json()["position"] == [3.0, 4.0, 0.0]
    assert commander.post(f"{API}/missions/{mid}/landmarks", json=tag).status_code == 409
    moved = {**tag, "position": [5.0, 4.0, 0.0]}
    assert commander.put(f"{API}/missions/{mid}/landmarks/T1", json=moved).status_code == 200
    got = commander.get(f"{API}/missions/{mid}/landmarks").json()
    assert len(got) == 1 and got[0]["position"] == [5.0, 4.0, 0.0]
    infra = commander.get(f"{API}/missions/{mid}/infrastructure").json()
    assert infra["landmarks"] == got and infra["nodes"] == [] and infra["waypoints"] == []
    assert commander.delete(f"{API}/missions/{mid}/landmarks/T1").status_code == 204
    assert commander.get(f"{API}/missions/{mid}/landmarks").json() == []

    created = new_agent(commander, mid, kind="robot", preset="default",
                        device={"model": "Pixel 7"}, user={"height_m": 1.8})
    agent = created["agent"]
    assert agent["checked_in"] is False and agent["kind"] == "robot"
    aid = agent["id"]
    r = commander.patch(f"{API}/missions/{mid}/agents/{aid}", json={"name": "Robot 1"})
    assert r.status_code == 200 and r.json()["name"] == "Robot 1"
    pose = {"t": 1.0, "x": 2.0, "y": 3.0, "heading": 0.5}
    r = commander.post(f"{API}/missions/{mid}/agents/{aid}/checkin", json=pose)
    assert r.status_code == 200 and r.json()["checked_in"] is True
    assert r.json()["start_pose"]["x"] == 2.0
    assert commander.post(f"{API}/missions/{mid}/agents/{aid}/checkin",
                          json=pose).status_code == 409
    assert [a["id"] for a in commander.get(f"{API}/missions/{mid}/agents").json()] == [aid]
    assert commander.get(f"{API}/missions").json()[0]["n_agents"] == 1


def test_tokens_are_stored_as_hashes_and_revocable(live: Live, commander: httpx.Client) -> None:
    r = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "ops desk"})
    assert r.status_code == 201
    secret, tid = r.json()["token"], r.json()["id"]
    listed = commander.get(f"{API}/tokens").json()
    assert all("token" not in t for t in listed)
    assert any(t["id"] == tid and t["role"] == "viewer" for t in listed)
    engine = make_engine(live.settings.db_url)
    try:
        with session_factory(engine)() as db:
            rows = list(db.scalars(select(Token)))
    finally:
        engine.dispose()
    assert all(secret not in repr(vars(row)) for row in rows)
    assert any(row.secret_sha256 == hashlib.sha256(secret.encode()).hexdigest() for row in rows)

    with live.client(secret) as viewer:
        assert viewer.get(f"{API}/missions").status_code == 200
        assert commander.delete(f"{API}/tokens/{tid}").status_code == 204
        r = viewer.get(f"{API}/missions")
        assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert commander.delete(f"{API}/tokens/999999").status_code == 404


def test_refusals_without_valid_token(live: Live) -> None:
    with live.client() as c:
        r = c.get(f"{API}/missions")
        assert r.status_code == 401 and "token" in r.json()["detail"]
        assert c.get(f"{API}/missions", headers={"Authorization": "Basic abc"}).status_code == 401
        assert c.get(f"{API}/missions",
                     headers={"Authorization": "Bearer not-a-token"}).status_code == 401
        assert c.post(f"{API}/missions", json={"name": "x"}).status_code == 401
        assert c.get(f"{API}/missions/1/snapshot").status_code == 401
        assert c.post(f"{API}/ingest", json={"seq": 0}).status_code == 401


def test_role_refusals(live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    other_mid = new_mission(commander, name="other")["id"]
    a = new_agent(commander, mid)
    b = new_agent(commander, mid, name="Rescuer B")
    c_other = new_agent(commander, other_mid, name="Rescuer C")
    viewer_secret = commander.post(f"{API}/tokens",
                                   json={"role": "viewer", "label": "v"}).json()["token"]
    with live.client(viewer_secret) as viewer:
        assert viewer.get(f"{API}/missions/{mid}").status_code == 200
        for method, path, body in (
                ("POST", "/missions", {"name": "x"}),
                ("PATCH", f"/missions/{mid}", {"name": "x"}),
                ("PUT", f"/missions/{mid}/floors/0", {"name": "G", "height_m": 0}),
                ("POST", f"/missions/{mid}/agents", {"name": "x"}),
                ("POST", f"/missions/{mid}/landmarks", {"id": "T", "position": [0, 0, 0]}),
                ("POST", "/tokens", {"role": "viewer", "label": "x"}),
                ("GET", "/tokens", None),
                ("POST", f"/missions/{mid}/agents/{a['agent']['id']}/checkin", {}),
        ):
            r = viewer.request(method, API + path, json=body)
            assert r.status_code == 403, (method, path, r.text)
            assert "role 'viewer'" in r.json()["detail"]
    aid, bid = a["agent"]["id"], b["agent"]["id"]
    with live.client(a["token"]) as agent:
        assert agent.get(f"{API}/missions/{mid}/agents/{aid}").status_code == 200
        assert agent.get(f"{API}/missions/{mid}/agents/{bid}").status_code == 403
        assert agent.get(f"{API}/missions/{other_mid}/agents/"
                         f"{c_other['agent']['id']}").status_code == 403
        assert agent.get(f"{API}/missions").status_code == 403
        assert agent.get(f"{API}/missions/{mid}").status_code == 403
        assert agent.get(f"{API}/missions/{mid}/agents").status_code == 403
        assert agent.get(f"{API}/missions/{mid}/landmarks").status_code == 403
        assert agent.post(f"{API}/missions/{mid}/agents/{bid}/checkin",
                          json={"x": 0, "y": 0}).status_code == 403
        assert agent.post(f"{API}/missions/{mid}/agents/{aid}/checkin",
                          json={"x": 0, "y": 0, "t": 0}).status_code == 200
        assert agent.post(f"{API}/auth/login", json={"token": a["token"]}).status_code == 403


def test_not_found_and_conflicts(commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    other = new_mission(commander, name="other")["id"]
    aid = new_agent(commander, mid)["agent"]["id"]
    assert commander.get(f"{API}/missions/999999").status_code == 404
    assert commander.get(f"{API}/missions/{other}/agents/{aid}").status_code == 404
    assert commander.get(f"{API}/nonsense").status_code == 404
    assert commander.delete(f"{API}/missions/{mid}/landmarks/nope").status_code == 404


@pytest.mark.parametrize(("body", "field"), [
    ({"name": "x", "colour": "red"}, "colour"),
    ({"name": ""}, "name"),
    ({"name": "x", "floor_height_m": -1}, "floor_height_m"),
    ({"name": "x", "alarm_profile": {"prealarm_s": 30, "alarm_s": 20}}, "alarm_profile"),
    ({"name": "x", "floors": [{"index": 0, "name": "G", "height_m": 0},
                              {"index": 0, "name": "H", "height_m": 3}]}, "floors"),
    ({"name": "x", "floors": [{"index": 0, "name": "G", "height_m": 0,
                               "plan": {"type": "Feature"}}]}, "plan"),
    ({"name": "x", "floors": [{"index": 0, "name": "G", "height_m": 0, "plan": {
        "type": "FeatureCollection", "features": [{"type": "Feature", "properties": {},
                                                   "geometry": {"type": "Polygon",
                                                                "coordinates": "x"}}]}}]},
     "geometry"),
])
def test_strict_schema_refusals(commander: httpx.Client, body: dict, field: str) -> None:
    r = commander.post(f"{API}/missions", json=body)
    assert r.status_code == 422, r.text
    assert field in r.json()["detail"]
    assert isinstance(r.json()["errors"], list)


@pytest.mark.parametrize("number", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_refused(commander: httpx.Client, number: str) -> None:
    r = commander.post(f"{API}/missions", content=f'{{"name": "x", "stale_after_s": {number}}}',
                       headers={"Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    mid = new_mission(commander)["id"]
    r = commander.post(f"{API}/missions/{mid}/landmarks",
                       content=f'{{"id": "T", "position": [0, {number}, 0]}}',
                       headers={"Content-Type": "application/json"})
    assert r.status_code == 422, r.text


def test_bad_values_refused(commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    r = commander.post(f"{API}/missions/{mid}/agents", json={"name": "x", "preset": "nope"})
    assert r.status_code == 400 and "preset 'nope' unknown" in r.json()["detail"]
    r = commander.post(f"{API}/missions/{mid}/landmarks", json={"id": "T"})
    assert r.status_code == 422 and "position" in r.json()["detail"]
    r = commander.put(f"{API}/missions/{mid}/landmarks/T2",
                      json={"id": "T3", "position": [0, 0, 0]})
    assert r.status_code == 422
    r = commander.post(f"{API}/missions", content=b"{not json",
                       headers={"Content-Type": "application/json"})
    assert r.status_code == 422


def test_body_size_limit(make_live) -> None:  # type: ignore[no-untyped-def]
    live = make_live(max_body_kib=4)
    with live.client(live.commander) as c:
        big = {"name": "x" * 100, "floors": [{"index": 0, "name": "G", "height_m": 0, "plan": {
            "type": "FeatureCollection", "features": [
                {"type": "Feature", "properties": {"kind": "wall"},
                 "geometry": {"type": "LineString", "coordinates": [[i, 0], [i, 1]]}}
                for i in range(200)]}}]}
        r = c.post(f"{API}/missions", json=big)
        assert r.status_code == 413 and "limit of 4096 bytes" in r.json()["detail"]

        def chunks():  # type: ignore[no-untyped-def]
            for _ in range(10):
                yield b" " * 1000

        r = c.post(f"{API}/missions", content=chunks(),
                   headers={"Content-Type": "application/json"})
        assert r.status_code == 413
        assert c.post(f"{API}/missions", json={"name": "small"}).status_code == 201


def test_cors_closed_by_default_and_open_to_named_origin(make_live) -> None:  # type: ignore[no-untyped-def]
    closed = make_live()
    with closed.client(closed.commander) as c:
        r = c.options(f"{API}/missions", headers={"Origin": "https://evil.example",
                                                  "Access-Control-Request-Method": "GET"})
        assert "access-control-allow-origin" not in r.headers
        r = c.get(f"{API}/missions", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in r.headers
    opened = make_live(cors_origins=("https://ops.example",))
    with opened.client(opened.commander) as c:
        r = c.get(f"{API}/missions", headers={"Origin": "https://ops.example"})
        assert r.headers["access-control-allow-origin"] == "https://ops.example"
        r = c.get(f"{API}/missions", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in r.headers


def test_browser_session_cookie(live: Live, commander: httpx.Client) -> None:
    viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "wall"}).json()
    with live.client() as browser:
        r = browser.post(f"{API}/auth/login", json={"token": "wrong"})
        assert r.status_code == 401
        r = browser.post(f"{API}/auth/login", json={"token": viewer["token"]})
        assert r.status_code == 200 and r.json()["role"] == "viewer"
        cookie = r.headers["set-cookie"]
        assert "hrtls_session=" in cookie and "HttpOnly" in cookie
        assert "samesite=strict" in cookie.lower()
        assert viewer["token"] not in cookie
        who = browser.get(f"{API}/auth/whoami").json()
        assert who == {"role": "viewer", "token_id": viewer["id"], "label": "wall",
                       "mission": None, "agent": None, "mission_t": None}
        assert browser.get(f"{API}/missions").status_code == 200
        assert browser.post(f"{API}/missions", json={"name": "x"}).status_code == 403
        assert browser.post(f"{API}/auth/logout").status_code == 204
        browser.cookies.clear()
        browser.cookies.set("hrtls_session", cookie.split("hrtls_session=")[1].split(";")[0])
        assert browser.get(f"{API}/missions").status_code == 401
        # a session ends with the token it was opened with
        browser.cookies.clear()
        assert browser.post(f"{API}/auth/login",
                            json={"token": viewer["token"]}).status_code == 200
        assert browser.get(f"{API}/missions").status_code == 200
        assert commander.delete(f"{API}/tokens/{viewer['id']}").status_code == 204
        assert browser.get(f"{API}/missions").status_code == 401


def test_planned_routes_answer_501_after_authorisation(live: Live,
                                                       commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    a = new_agent(commander, mid)
    with live.client(a["token"]) as agent:
        assert agent.get(f"{API}/missions/{mid}/snapshot").status_code == 403
    r = commander.get(f"{API}/missions/{mid}/snapshot")
    assert r.status_code in (200, 501)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_hrtls_serve_prints_url_and_first_commander_token(tmp_path: Path) -> None:
    port = _free_port()
    db = tmp_path / "cli.db"
    cmd = [sys.executable, "-m", "hrtls.cli.app", "serve", "--db", str(db), "--port", str(port)]
    proc = subprocess.Popen([*cmd[:1], "-c", "from hrtls.cli.app import main; main()",
                             *cmd[3:]], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        url_line = proc.stdout.readline() if proc.stdout else ""
        token_line = proc.stdout.readline() if proc.stdout else ""
        assert f"http://127.0.0.1:{port}/" in url_line
        token = token_line.rsplit(" ", 1)[-1].strip()
        assert "commander token" in token_line and len(token) >= 40
        deadline = time.monotonic() + 60
        while True:
            try:
                r = httpx.get(f"http://127.0.0.1:{port}/api/v1/auth/whoami",
                              headers={"Authorization": f"Bearer {token}"})
                break
            except httpx.TransportError:
                assert time.monotonic() < deadline and proc.poll() is None
                time.sleep(0.2)
        assert r.status_code == 200 and r.json()["role"] == "commander"
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    # second start: no new secret printed
    proc = subprocess.Popen([sys.executable, "-c", "from hrtls.cli.app import main; main()",
                             "serve", "--db", str(db), "--port", str(port)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert "dashboard" in (proc.stdout.readline() if proc.stdout else "")
    finally:
        proc.terminate()
        out = proc.communicate(timeout=30)[0]
    assert "commander token" not in out


def test_serve_refuses_bad_flags(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    r = CliRunner().invoke(app, ["serve", "--db", str(tmp_path / "x.db"), "--cors-origin", "*"])
    assert r.exit_code != 0 and "--cors-origin" in r.output and "'*'" in r.output
    r = CliRunner().invoke(app, ["serve", "--ssl-certfile", "a.pem"])
    assert r.exit_code != 0 and "--ssl-keyfile" in r.output


def test_dashboard_served_at_root_when_installed(live: Live) -> None:
    from hrtls.web import asset_root

    with live.client() as c:
        r = c.get("/")
    if (asset_root() / "index.html").is_file():
        assert r.status_code == 200 and "<html" in r.text.lower()
    else:
        assert r.status_code == 404
