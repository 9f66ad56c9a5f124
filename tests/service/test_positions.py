"""GNSS positions of phone apps (OsmAnd / Traccar Client, OwnTracks) as fixes: conversion,
numbering, duplicates, late positions, refusals and replay after a restart (both backends)."""

from __future__ import annotations

import base64
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from tests.service.conftest import Live, new_agent, new_mission
from tests.service.streams import API, stored
from tests.service.test_ingest import wait_idle

from hrtls.io.session import read_session
from hrtls.service import positions as pos
from hrtls.service.batches import BatchError
from hrtls.service.missions import export_mission
from hrtls.service.seqbook import ASSIGNED_SEQ_BASE

LAT0, LON0 = 48.0, 11.0
GEO = {"lat_deg": LAT0, "lon_deg": LON0, "height_m": 0.0, "rotation_rad": 0.0}


def _radii(lat_deg: float) -> tuple[float, float]:
    """WGS-84 meridian and prime-vertical radii of curvature, m."""
    a, f = 6378137.0, 1.0 / 298.257223563
    e2 = f * (2.0 - f)
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return a * (1.0 - e2) / (1.0 - e2 * s2) ** 1.5, a / math.sqrt(1.0 - e2 * s2)


def _local(lat: float, lon: float) -> tuple[float, float]:
    """East, north of a point near (LAT0, LON0): arc lengths on the ellipsoid (~1 mm at 200 m)."""
    m, n = _radii(LAT0)
    return (math.radians(lon - LON0) * n * math.cos(math.radians(LAT0)),
            math.radians(lat - LAT0) * m)


# ---------------------------------------------------------------------------- no server
def test_fix_is_hand_computed_local_metres_and_sigma() -> None:
    p = pos.Position("phone", 1_800_000_010.0, LAT0 + 0.001, LON0 + 0.002, accuracy_m=4.5)
    b = pos.fix_batch(p, seq=ASSIGNED_SEQ_BASE, t0_unix=1_800_000_000.0, georeference=GEO)
    assert b.fixes is not None
    x, y = _local(LAT0 + 0.001, LON0 + 0.002)
    assert abs(x - 149.25) < 0.01 and abs(y - 111.19) < 0.01   # 0.002 deg E, 0.001 deg N at 48 N
    assert b.fixes.x[0] == pytest.approx(x, abs=0.005)
    assert b.fixes.y[0] == pytest.approx(y, abs=0.005)
    assert b.fixes.t == [10.0]
    # 68 % of a circular Gaussian lies within 1.5096 sigma
    assert b.fixes.sigma_m[0] == pytest.approx(4.5 / 1.50959, rel=1e-4)
    # x axis turned to north: x = north, y = west
    turned = pos.fix_batch(p, seq=ASSIGNED_SEQ_BASE, t0_unix=1_800_000_000.0,
                           georeference={**GEO, "rotation_rad": math.pi / 2})
    assert turned.fixes is not None
    assert turned.fixes.x[0] == pytest.approx(y, abs=0.005)
    assert turned.fixes.y[0] == pytest.approx(-x, abs=0.005)


@pytest.mark.parametrize(("value", "unix"), [
    ("1800000000", 1_800_000_000.0), ("1800000000.5", 1_800_000_000.5),
    ("1800000000123", 1_800_000_000.123), ("2027-01-15T08:00:00Z", 1_800_000_000.0),
    ("2027-01-15T09:00:00+01:00", 1_800_000_000.0), ("2027-01-15 08:00:00", 1_800_000_000.0),
])
def test_osmand_timestamps(value: str, unix: float) -> None:
    parsed = pos.osmand_query([("id", "p"), ("timestamp", value), ("lat", "48"), ("lon", "11"),
                               ("accuracy", "5")])
    assert parsed.position is not None and parsed.position.time_unix == pytest.approx(unix)


def test_protocols_read_their_documented_fields() -> None:
    q = pos.osmand_query([("id", "p"), ("timestamp", "1800000000"), ("location", "48.1,11.2"),
                          ("accuracy", "5"), ("batt", "80"), ("alarm", "sos"),
                          ("speed", "1.2"), ("custom", "x")])
    assert q.position == pos.Position("p", 1.8e9, 48.1, 11.2, 5.0, battery=0.8, sos=True)
    assert q.ignored_fields == ("custom",)
    assert pos.osmand_query([("id", "p"), ("timestamp", "1800000000"), ("lat", "48"),
                             ("lon", "11"), ("accuracy", "5"), ("valid", "false")]).position \
        is None
    j = pos.osmand_json(traccar_json(1.8e9, 48.0, 11.0, 6.0))
    assert j.position == pos.Position("48241179", 1.8e9, 48.0, 11.0, 6.0, battery=0.5)
    o = pos.owntracks(owntracks_msg(1_800_000_000, 48.0, 11.0, 7))
    assert o.position == pos.Position("JJ", 1.8e9, 48.0, 11.0, 7.0, battery=0.9)
    assert pos.owntracks({"_type": "lwt", "tst": 1}).ignored_reason == \
        "_type 'lwt' carries no position"


@pytest.mark.parametrize(("pairs", "text"), [
    ([("lat", "91")], "lat = '91' must be a finite number in [-90, 90]"),
    ([("lon", "-181")], "lon = '-181'"),
    ([("lat", "nan")], "lat = 'nan'"),
    ([("accuracy", "-1")], "accuracy = '-1'"),
    ([("accuracy", "0")], "accuracy > 0"),
    ([("accuracy", "inf")], "accuracy = 'inf'"),
    ([("accuracy", "")], "accuracy: expected a number"),
    ([("timestamp", "yesterday")], "timestamp = 'yesterday'"),
    ([("altitude", "1e999")], "altitude"),
    ([("id", "")], "id (device identifier) is required"),
    ([("batt", "140")], "batt = 140"),
])
def test_osmand_query_refusals(pairs: list[tuple[str, str]], text: str) -> None:
    base = {"id": "p", "timestamp": "1800000000", "lat": "48", "lon": "11", "accuracy": "5"}
    base.update(pairs)
    with pytest.raises(BatchError) as err:
        pos.osmand_query(list(base.items()))
    assert err.value.status == 422 and text in err.value.detail


def test_osmand_query_needs_accuracy_and_single_values() -> None:
    with pytest.raises(BatchError, match=r"accuracy \(horizontal accuracy, m\) is required"):
        pos.osmand_query([("id", "p"), ("timestamp", "1800000000"), ("lat", "48"),
                          ("lon", "11")])
    with pytest.raises(BatchError, match="given twice"):
        pos.osmand_query([("id", "p"), ("id", "q")])
    with pytest.raises(BatchError, match="either location"):
        pos.osmand_query([("id", "p"), ("location", "48,11"), ("lat", "48")])


def test_json_protocols_refuse_undocumented_fields() -> None:
    body = traccar_json(1.8e9, 48.0, 11.0, 6.0)
    body["location"]["coords"]["latitud"] = 1.0
    with pytest.raises(BatchError, match=r"location\.coords: unknown field.*'latitud'"):
        pos.osmand_json(body)
    with pytest.raises(BatchError, match="one location object"):
        pos.osmand_json({"device_id": "x", "location": [body["location"]]})
    with pytest.raises(BatchError, match=r"unknown field.*'secret'"):
        pos.owntracks({**owntracks_msg(1_800_000_000, 48.0, 11.0, 7), "secret": 1})
    with pytest.raises(BatchError, match="cannot decrypt"):
        pos.owntracks({"_type": "encrypted", "data": "..."})
    with pytest.raises(BatchError, match="acc"):
        pos.owntracks({**owntracks_msg(1_800_000_000, 48.0, 11.0, 7), "acc": None})


def test_envelope_decodes_to_the_same_batch() -> None:
    text = json.dumps(owntracks_msg(1_800_000_003, 48.0005, 11.0004, 3))
    parsed = pos.parse("owntracks", text)
    assert parsed.position is not None
    seq = ASSIGNED_SEQ_BASE + 7
    body = pos.envelope("owntracks", text, seq=seq, t0_unix=1.8e9, georeference=GEO)
    assert pos.decode_position(body, pos.ENVELOPE_TYPE) == pos.fix_batch(
        parsed.position, seq=seq, t0_unix=1.8e9, georeference=GEO)
    assert pos.query_text([("id", "p"), ("token", "SECRET"), ("lat", "1")]) == "id=p&lat=1"


# ---------------------------------------------------------------------------- helpers
def traccar_json(t_unix: float, lat: float, lon: float, acc: float) -> dict[str, Any]:
    """Traccar Client 9's body (its location SDK's fields)."""
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t_unix)) + \
        f".{round((t_unix % 1) * 1000):03d}Z"
    return {"device_id": "48241179", "location": {
        "timestamp": stamp, "uuid": "a1", "is_moving": True, "odometer": 12.0,
        "event": "motionchange", "activity": {"type": "walking"}, "extras": {},
        "battery": {"level": 0.5, "is_charging": False},
        "coords": {"latitude": lat, "longitude": lon, "accuracy": acc, "speed": -1,
                   "heading": -1, "altitude": 520.0, "altitude_accuracy": 3.0}}}


def owntracks_msg(tst: int, lat: float, lon: float, acc: float) -> dict[str, Any]:
    return {"_type": "location", "tid": "JJ", "tst": tst, "lat": lat, "lon": lon, "acc": acc,
            "alt": 520, "vac": 4, "vel": 3, "cog": 90, "batt": 90, "bs": 1, "conn": "m",
            "t": "u", "m": 1, "created_at": tst, "_http": True}


def basic(token: str) -> dict[str, str]:
    return {"Authorization": "Basic " + base64.b64encode(f"rescuer:{token}".encode()).decode()}


def gnss_mission(c: httpx.Client, **body: Any) -> tuple[int, dict[str, Any], float]:
    m = new_mission(c, georeference=GEO, **body)
    return m["id"], new_agent(c, m["id"]), m["t0_unix"]


def osmand_get(http: httpx.Client, token: str, t_unix: float, lat: float, lon: float,
               acc: float = 5.0, **extra: Any) -> httpx.Response:
    return http.get(f"{API}/ingest/osmand", params={
        "id": "phone", "timestamp": repr(t_unix), "lat": repr(lat), "lon": repr(lon),
        "accuracy": acc, "token": token, **extra})


# ---------------------------------------------------------------------------- live service
def test_three_app_formats_become_fixes_numbered_by_the_service(
        live: Live, commander: httpx.Client) -> None:
    mid, a, t0 = gnss_mission(commander)
    token, aid = a["token"], a["agent"]["id"]
    t1 = t0 + 5.0
    with httpx.Client(base_url=live.url, timeout=30) as phone:
        r = osmand_get(phone, token, t1, LAT0 + 0.001, LON0 + 0.002, batt="77", custom="x")
        assert r.status_code == 200, r.text
        ack = r.json()
        assert ack["seq"] == ASSIGNED_SEQ_BASE and ack["status"] == "accepted"
        assert ack["acked_through"] == ASSIGNED_SEQ_BASE and ack["missing"] == []
        assert ack["ignored_fields"] == ["custom"] and ack["t"] == pytest.approx(5.0)
        x, y = _local(LAT0 + 0.001, LON0 + 0.002)
        assert ack["x"] == pytest.approx(x, abs=0.005) and ack["y"] == pytest.approx(y, abs=0.005)
        # the old Traccar Client: POST with a form body
        r = phone.post(f"{API}/ingest/osmand", params={"token": token},
                       data={"id": "phone", "timestamp": str(int(t0) + 7), "lat": "48.0002",
                             "lon": "11.0001", "accuracy": "8"})
        assert r.status_code == 200 and r.json()["seq"] == ASSIGNED_SEQ_BASE + 1, r.text
        # Traccar Client 9: JSON body, token as Bearer header
        r = phone.post(f"{API}/ingest/osmand", json=traccar_json(t0 + 9.25, 48.0003, 11.0, 6.0),
                       headers={"Authorization": f"Bearer {token}"})
        assert r.status_code == 200 and r.json()["seq"] == ASSIGNED_SEQ_BASE + 2, r.text
        # OwnTracks: Basic-auth password, body [] and the ack in a header
        r = phone.post(f"{API}/ingest/owntracks", headers=basic(token),
                       json=owntracks_msg(int(t0) + 11, 48.0004, 11.0, 7))
        assert r.status_code == 200 and r.json() == [], r.text
        assert json.loads(r.headers["x-hrtls-ack"])["seq"] == ASSIGNED_SEQ_BASE + 3
        r = phone.post(f"{API}/ingest/owntracks", headers=basic(token),
                       json={"_type": "transition", "event": "enter", "tst": int(t0)})
        assert r.status_code == 200 and r.json() == []
        assert json.loads(r.headers["x-hrtls-ack"]) == {
            "status": "ignored", "reason": "_type 'transition' carries no position"}
        # an hrtls client on the same agent keeps its own numbering
        r = phone.post(f"{API}/ingest", json={"seq": 0, "status": {"battery": 0.6}},
                       headers={"Authorization": f"Bearer {token}"})
        assert r.json() == {"seq": 0, "status": "accepted", "acked_through": 0, "missing": []}
        r = phone.post(f"{API}/ingest", json={"seq": ASSIGNED_SEQ_BASE + 4, "sos": True},
                       headers={"Authorization": f"Bearer {token}"})
        assert r.status_code == 422 and "numbered by the service" in r.json()["detail"]
        # Traccar Client's SOS button
        r = osmand_get(phone, token, t0 + 13.0, 48.0005, 11.0, alarm="sos")
        assert r.status_code == 200 and r.json()["seq"] == ASSIGNED_SEQ_BASE + 4, r.text
    wait_idle(live)
    status = commander.get(f"{API}/missions/{mid}/agents/{aid}").json()["status"]
    assert status["battery"] == 0.6 and status["acked_through"] == 0
    sos = commander.get(f"{API}/missions/{mid}/events", params={"kind": "sos"}).json()
    assert [(e["agent"], e["severity"]) for e in sos] == [(aid, "alarm")]


def test_duplicates_out_of_order_and_refusals(live: Live, commander: httpx.Client) -> None:
    mid, a, t0 = gnss_mission(commander)
    token = a["token"]
    other = new_agent(commander, mid, name="Rescuer B")
    bare = new_agent(commander, new_mission(commander)["id"])   # mission without georeference
    viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
    t20 = math.ceil(t0) + 20
    with httpx.Client(base_url=live.url, timeout=30) as phone:
        first = osmand_get(phone, token, t20, 48.0001, 11.0001).json()
        again = osmand_get(phone, token, t20, 48.0001, 11.0001)
        assert again.status_code == 200
        dup = {**{k: first[k] for k in ("seq", "acked_through", "missing")},
               "status": "duplicate"}
        assert again.json() == dup
        # the same fix through another app is the same fix
        r = phone.post(f"{API}/ingest/owntracks", params={"token": token},
                       json=owntracks_msg(t20, 48.0001, 11.0001, 5))
        assert json.loads(r.headers["x-hrtls-ack"]) == dup
        r = osmand_get(phone, token, t20, 48.0002, 11.0001)
        assert r.status_code == 409 and "different position" in r.json()["detail"]
        late = osmand_get(phone, token, t20 - 10, 48.0, 11.0).json()   # older: back-fill
        assert late["status"] == "accepted" and late["seq"] > first["seq"]
        before = osmand_get(phone, token, t0 - 60.0, 48.0, 11.0).json()
        assert before["status"] == "ignored" and "before the mission" in before["reason"]
        # refusals
        r = osmand_get(phone, "", t0 + 30, 48.0, 11.0)
        assert r.status_code == 401
        r = phone.get(f"{API}/ingest/osmand", params={"id": "p", "lat": 48, "lon": 11})
        assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
        assert osmand_get(phone, viewer["token"], t0 + 30, 48.0, 11.0).status_code == 403
        assert osmand_get(phone, commander.headers["authorization"].split()[1], t0 + 30, 48.0,
                          11.0).status_code == 403
        r = osmand_get(phone, bare["token"], t0 + 30, 48.0, 11.0)
        assert r.status_code == 409 and "no georeference" in r.json()["detail"]
        for bad, text in (({"lat": "91"}, "lat"), ({"accuracy": "-3"}, "accuracy"),
                          ({"accuracy": "nan"}, "accuracy")):
            r = phone.get(f"{API}/ingest/osmand", params={
                "id": "p", "timestamp": int(t0) + 30, "lat": 48, "lon": 11, "accuracy": 5,
                "token": token, **bad})
            assert r.status_code == 422 and text in r.json()["detail"], r.text
        r = osmand_get(phone, token, time.time() + 3600, 48.0, 11.0)
        assert r.status_code == 422 and "clock" in r.json()["detail"]
        r = phone.post(f"{API}/ingest/owntracks", params={"token": token},
                       content=b'{"_type": "location", "lat": NaN}',
                       headers={"Content-Type": "application/json"})
        assert r.status_code == 400 and "finite" in r.json()["detail"]
        big = {**owntracks_msg(int(t0) + 40, 48.0, 11.0, 5), "tag": "x" * 20_000}
        r = phone.post(f"{API}/ingest/owntracks", params={"token": token}, json=big)
        assert r.status_code == 413
        r = phone.post(f"{API}/ingest/osmand", params={"token": token}, content=b"lat=1",
                       headers={"Content-Type": "text/plain"})
        assert r.status_code == 415
        # a JSON body without Content-Type is still read as JSON
        r = phone.post(f"{API}/ingest/osmand", params={"token": token},
                       content=json.dumps(traccar_json(t20 + 5, 48.0, 11.0, 6.0)).encode())
        assert r.status_code == 200 and r.json()["status"] == "accepted", r.text
        # another agent's token writes to that agent only
        r = osmand_get(phone, other["token"], t0 + 50.0, 48.0, 11.0)
        assert r.status_code == 200 and r.json()["seq"] == ASSIGNED_SEQ_BASE
    wait_idle(live)
    host = live.server.config.app.state.services.host
    mine = host.agent(a["agent"]["id"])
    assert mine.assigned.highest == late["seq"] + 1 - ASSIGNED_SEQ_BASE
    assert host.agent(other["agent"]["id"]).assigned.highest == 0


def _walk(t0: float, n: int) -> list[tuple[float, float, float]]:
    """A walk east at 1.2 m/s, one GNSS position per s: (unix time, lat, lon)."""
    m, nr = _radii(LAT0)
    rng = np.random.default_rng(5)
    out = []
    for i in range(n):
        e, north = 1.2 * i + rng.normal(0, 2.0), 0.3 * i + rng.normal(0, 2.0)
        out.append((math.ceil(t0) + 2.0 + i, LAT0 + math.degrees(north / m),
                    LON0 + math.degrees(e / (nr * math.cos(math.radians(LAT0))))))
    return out


@pytest.mark.parametrize("snapshot_every_s", [1e6, 15.0])   # whole log / from a snapshot
def test_gnss_agent_tracked_restart_replays_equal_and_exports_fixes(
        make_live: Callable[..., Live], tmp_path: Path, snapshot_every_s: float) -> None:
    live = make_live(snapshot_every_s=snapshot_every_s)
    with live.client(live.commander) as c:
        mid, a, t0 = gnss_mission(c)
        aid = a["agent"]["id"]
        assert c.post(f"{API}/missions/{mid}/agents/{aid}/checkin",
                      json={"t": 2.0, "x": 0.0, "y": 0.0, "heading": 0.0}).status_code == 200
    walk = _walk(t0, 70)
    order = list(range(0, 40)) + list(range(50, 70)) + list(range(40, 50))   # a late block
    with httpx.Client(base_url=live.url, timeout=30) as phone:
        for i in order:
            t, lat, lon = walk[i]
            if i % 2:
                r = phone.post(f"{API}/ingest/owntracks", headers=basic(a["token"]),
                               json=owntracks_msg(int(t), lat, lon, 6))
                assert r.status_code == 200, r.text
            else:
                r = osmand_get(phone, a["token"], t, lat, lon, acc=6.0)
                assert r.status_code == 200 and r.json()["status"] == "accepted", r.text
    wait_idle(live)
    time.sleep(0.3)
    with live.client(live.commander) as c:
        before = stored(c, mid, aid)
    n = len(before["t"])
    assert n > 10, "a GNSS-only agent is tracked"
    last = before["xy"][-1]
    assert abs(last[0] - 1.2 * before["t"][-1] + 2.4) < 15.0   # follows the walk east
    live.stop()
    again = make_live(snapshot_every_s=snapshot_every_s)
    wait_idle(again)
    time.sleep(0.3)
    with again.client(again.commander) as c:
        after = stored(c, mid, aid)
    assert len(after["t"]) == n
    np.testing.assert_array_equal(after["t"], before["t"])
    np.testing.assert_allclose(after["xy"], before["xy"], atol=1e-9)
    np.testing.assert_allclose(after["cov"], before["cov"], atol=1e-9)
    # the export holds the fixes in time order, in mission metres
    export_mission(again.settings.db_url, mid, tmp_path / "exp")
    fixes = read_session(tmp_path / "exp" / f"agent-{aid}").fixes
    assert fixes is not None and len(fixes) == len(walk)
    np.testing.assert_allclose(fixes.t, [w[0] - t0 for w in walk], atol=1e-6)
    want = np.array([_local(lat, lon) for _, lat, lon in walk])
    np.testing.assert_allclose(fixes.xyz[:, :2], want, atol=0.01)
    np.testing.assert_allclose(fixes.sigma_m, 6.0 / 1.50959, rtol=1e-4)


def test_positions_rate_limited_with_retry_after(make_live: Callable[..., Live]) -> None:
    live = make_live(rate_per_agent_hz=0.5, rate_burst=2)
    with live.client(live.commander) as c:
        _, a, t0 = gnss_mission(c)
    with httpx.Client(base_url=live.url, timeout=30) as phone:
        codes = [osmand_get(phone, a["token"], t0 + 5 + i, 48.0, 11.0) for i in range(3)]
    assert [r.status_code for r in codes] == [200, 200, 429]
    assert int(codes[2].headers["retry-after"]) >= 1
