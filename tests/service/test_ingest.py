"""Ingest over HTTP and WebSocket, tracking, estimates, live deltas and back-fill."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from typing import Any

import httpx
import msgpack
import numpy as np
import pytest
from tests.service.conftest import Live, new_agent, new_mission
from tests.service.streams import API, mission_for, office, offline_rows, start_pose, stored
from websockets.sync.client import connect

from hrtls.service.client import AgentClient, session_batches


def wait_idle(live: Live, timeout_s: float = 120.0) -> None:
    host = live.server.config.app.state.services.host
    deadline = time.monotonic() + timeout_s
    time.sleep(0.1)
    while not host.idle():
        assert time.monotonic() < deadline, "tracker host did not finish"
        time.sleep(0.05)


IMU = {"t": [1.0, 1.01], "acc": [[0, 0, 9.8], [0, 0, 9.8]]}


def post_json(agent: AgentClient, batch: dict[str, Any]) -> httpx.Response:
    """POST a batch; after a 429 (rate limit or full queue) wait as told and send it again.

    Bounded: a service that keeps refusing for 300 tries fails the test.
    """
    for _ in range(300):
        r = agent.http.post(f"{API}/ingest", json=batch)
        if r.status_code != 429:
            return r
        time.sleep(float(r.headers["retry-after"]))
    raise AssertionError(f"still 429 after 300 tries: {r.text}")


def test_ingest_acks_duplicates_and_gaps(live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    a = new_agent(commander, mid)
    with live.client(a["token"]) as agent:
        r = agent.post(f"{API}/ingest", json={"seq": 0, "imu": IMU})
        assert r.status_code == 200
        assert r.json() == {"seq": 0, "status": "accepted", "acked_through": 0, "missing": []}
        again = agent.post(f"{API}/ingest", json={"seq": 0, "imu": IMU})
        assert again.json() == {"seq": 0, "status": "duplicate", "acked_through": 0,
                                "missing": []}
        body = msgpack.packb({"seq": 3, "imu": {**IMU, "t": [2.0, 2.01]}})
        r = agent.post(f"{API}/ingest", content=body,
                       headers={"Content-Type": "application/msgpack"})
        assert r.json() == {"seq": 3, "status": "accepted", "acked_through": 0,
                            "missing": [[1, 2]]}
        r = agent.post(f"{API}/ingest", json={"seq": 1, "status": {"battery": 0.5}})
        assert r.json()["acked_through"] == 1 and r.json()["missing"] == [[2, 2]]
    status = commander.get(f"{API}/missions/{mid}/agents/{a['agent']['id']}").json()["status"]
    assert status["last_seq"] == 3 and status["acked_through"] == 1
    assert status["missing"] == [[2, 2]] and status["battery"] == 0.5


@pytest.mark.parametrize(("content", "ctype", "status", "text"), [
    (b'{"seq": 0, "imu": ', "application/json", 400, "not valid"),
    (b'{"seq": 0}', "text/plain", 415, "Content-Type"),
    (b'[1, 2]', "application/json", 400, "object"),
    (b'{"seq": 0}', "application/json", 422, "at least one"),
    (b'{"seq": -1, "sos": true}', "application/json", 422, "seq"),
    (b'{"seq": 0, "sos": true, "extra": 1}', "application/json", 422, "extra"),
    (b'{"seq": 0, "imu": {"t": [1, NaN], "acc": [[0,0,9.8],[0,0,9.8]]}}',
     "application/json", 400, "finite"),
    (b'{"seq": 0, "imu": {"t": [1, 1], "acc": [[0,0,9.8],[0,0,9.8]]}}',
     "application/json", 422, "increase"),
    (b'{"seq": 0, "imu": {"t": [1, 2], "acc": [[0,0,9.8]]}}', "application/json", 422, "rows"),
    (b'{"seq": 0, "baro": {"t": [1], "p_pa": [1013.0]}}', "application/json", 422, "hPa"),
    (b'{"seq": 0, "fixes": {"t": [1], "x": [0], "y": [0], "sigma_m": [0]}}',
     "application/json", 422, "sigma"),
])
def test_ingest_refusals(live: Live, commander: httpx.Client, content: bytes, ctype: str,
                         status: int, text: str) -> None:
    mid = new_mission(commander)["id"]
    a = new_agent(commander, mid)
    with live.client(a["token"]) as agent:
        r = agent.post(f"{API}/ingest", content=content, headers={"Content-Type": ctype})
    assert r.status_code == status, r.text
    assert text in r.json()["detail"]


def test_ingest_only_for_agent_tokens(live: Live, commander: httpx.Client) -> None:
    r = commander.post(f"{API}/ingest", json={"seq": 0, "sos": True})
    assert r.status_code == 403


def test_ingest_rate_limit_answers_429_with_retry_after(
        make_live: Callable[..., Live]) -> None:
    live = make_live(rate_per_agent_hz=0.5, rate_burst=2)
    with live.client(live.commander) as c:
        mid = new_mission(c)["id"]
        a = new_agent(c, mid)
    with live.client(a["token"]) as agent:
        codes = [agent.post(f"{API}/ingest", json={"seq": i, "sos": True}) for i in range(3)]
    assert [r.status_code for r in codes] == [200, 200, 429]
    assert int(codes[2].headers["retry-after"]) >= 1
    assert "requests/s" in codes[2].json()["detail"]


def test_ingest_body_limit(make_live: Callable[..., Live]) -> None:
    live = make_live(max_body_kib=2)
    with live.client(live.commander) as c:
        a = new_agent(c, new_mission(c)["id"])
    n = 200
    batch = {"seq": 0, "imu": {"t": [i * 0.01 for i in range(n)], "acc": [[0, 0, 9.8]] * n}}
    with live.client(a["token"]) as agent:
        r = agent.post(f"{API}/ingest", json=batch)
    assert r.status_code == 413


def test_live_tracking_equals_offline_and_survives_redelivery(
        live: Live, commander: httpx.Client) -> None:
    session = office()
    mid, aid, token = mission_for(commander, session)
    with AgentClient(live.url, token, fmt="msgpack") as agent:
        agent.checkin(start_pose(session))
        batches = list(session_batches(session, chunk_s=0.5))
        for _, b in batches:
            agent.submit(b)
        assert agent.outbox == {}
        # a client that lost its acks resends: nothing changes
        for seq in (0, 5, len(batches) - 1):
            while True:  # the burst above may have used up the rate limit: wait as told
                r = agent.http.post(f"{API}/ingest", content=msgpack.packb(
                    {**batches[seq][1], "seq": seq}),
                    headers={"Content-Type": "application/msgpack"})
                if r.status_code != 429:
                    break
                time.sleep(float(r.headers["retry-after"]))
            assert r.json()["status"] == "duplicate", (r.status_code, r.text)
    wait_idle(live)
    got = stored(commander, mid, aid)
    ref = offline_rows()
    n = len(got["t"])
    assert n > 100 and got["t"][-1] >= ref.t[-1] - 8.0, (n, got["t"][-1], ref.t[-1])
    np.testing.assert_allclose(got["t"], ref.t[:n], atol=1e-9)
    np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-9)
    np.testing.assert_allclose(got["cov"], ref.cov_xy[:n], atol=1e-9)
    snap = commander.get(f"{API}/missions/{mid}/snapshot").json()
    assert [e["agent"] for e in snap["estimates"]] == [aid]
    est = snap["estimates"][0]
    assert est["t"] >= got["t"][-1] and set(est) >= {"cov_xy", "heading_rad", "activity",
                                                       "since_correction_s", "floor", "stale"}
    assert snap["trails"][str(aid)], "trail of the last 300 s"
    trail = commander.get(f"{API}/missions/{mid}/agents/{aid}/trail",
                          params={"max_points": 10}).json()
    assert len(trail) == 10 and trail[0]["t"] == got["t"][0] and trail[-1]["t"] == got["t"][-1]
    replay = commander.get(f"{API}/missions/{mid}/replay", params={"t": 20.0}).json()
    assert replay["t"] == 20.0 and replay["estimates"][0]["t"] <= 20.0
    assert all(p["t"] <= 20.0 for p in replay["trails"][str(aid)])


def test_backfill_after_gap_reruns_and_marks_stale(live: Live, commander: httpx.Client) -> None:
    session = office()
    mid, aid, token = mission_for(commander, session)
    batches = [b for _, b in session_batches(session, chunk_s=0.5)]
    gap = range(30, 40)
    with AgentClient(live.url, token, fmt="json") as agent:
        agent.checkin(start_pose(session))
        for seq, b in enumerate(batches):
            if seq not in gap:
                r = post_json(agent, {**b, "seq": seq})
                assert r.status_code == 200, r.text
        wait_idle(live, timeout_s=60)
        snap = commander.get(f"{API}/missions/{mid}/snapshot").json()
        assert snap["estimates"][0]["stale"] is True
        status = snap["agents"][0]["status"]
        assert status["missing"] == [[gap.start, gap.stop - 1]]
        for seq in gap:
            assert post_json(agent, {**batches[seq], "seq": seq}).status_code == 200
    wait_idle(live)
    got = stored(commander, mid, aid)
    ref = offline_rows()
    n = len(got["t"])
    assert n > 100 and got["t"][-1] >= ref.t[-1] - 8.0, (n, got["t"][-1], ref.t[-1])
    np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-9)
    snap = commander.get(f"{API}/missions/{mid}/snapshot").json()
    assert snap["agents"][0]["status"]["missing"] == []


def _ws_json(ws: Any, timeout: float = 30.0) -> dict[str, Any]:
    raw = ws.recv(timeout=timeout)
    return dict(json.loads(raw) if isinstance(raw, str) else msgpack.unpackb(raw))


def test_websockets_agent_in_dashboard_out(live: Live, commander: httpx.Client) -> None:
    session = office()
    mid, aid, token = mission_for(commander, session)
    commander.post(f"{API}/missions/{mid}/agents/{aid}/checkin", json=start_pose(session))
    viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "wall"}).json()
    with connect(f"{live.ws_url}{API}/missions/{mid}/ws") as dash, \
            connect(f"{live.ws_url}{API}/ingest/ws",
                    additional_headers={"Authorization": f"Bearer {token}"}) as agent_ws:
        dash.send(json.dumps({"type": "auth", "token": viewer["token"]}))
        hello = _ws_json(dash)
        assert hello["type"] == "hello" and hello["role"] == "viewer" and hello["mission"] == mid
        first = _ws_json(dash)
        assert first["type"] == "snapshot" and first["agents"][0]["id"] == aid
        acks = []
        for seq, (_, b) in enumerate(session_batches(session, chunk_s=0.5)):
            binary = seq % 2 == 0
            frame = {"type": "batch", "batch": {**b, "seq": seq}}
            while True:  # back-pressure (429 with retry_after_s) when tracking lags: resend
                agent_ws.send(msgpack.packb(frame) if binary else json.dumps(frame))
                reply = _ws_json(agent_ws)
                if reply.get("status") != 429:
                    break
                assert reply["retry_after_s"] > 0
                time.sleep(reply["retry_after_s"])
            acks.append(reply)
        assert all(a["type"] == "ack" and a["status"] == "accepted" for a in acks)
        assert acks[-1]["acked_through"] == len(acks) - 1
        while True:  # the rate limit may answer first after the burst above
            agent_ws.send(json.dumps({"type": "batch", "batch": {"seq": 0, "bogus": 1}}))
            err = _ws_json(agent_ws)
            if err.get("status") != 429:
                break
            time.sleep(err["retry_after_s"])
        assert err["type"] == "error" and err["status"] == 422
        agent_ws.send(json.dumps({"type": "ping"}))
        assert _ws_json(agent_ws)["type"] == "pong"
        wait_idle(live)
        ts = []
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            d = _ws_json(dash)
            assert d["type"] == "delta" and set(d) >= {"agents", "estimates", "events", "orders"}
            ts += [e["t"] for e in d["estimates"] if e["agent"] == aid]
            if ts and ts[-1] >= stored(commander, mid, aid)["t"][-1]:
                break
        assert ts and all(math.isfinite(t) for t in ts)
        dash.send(json.dumps({"type": "subscribe", "floor": 5}))
        snap = _ws_json(dash)
        while snap["type"] != "snapshot":
            snap = _ws_json(dash)
        assert snap["estimates"] == [] and len(snap["agents"]) == 1


def test_websocket_refusals(live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    a = new_agent(commander, mid)
    cases = [
        (f"{API}/missions/{mid}/ws", {"type": "auth", "token": "wrong"}, 4401),
        (f"{API}/missions/{mid}/ws", {"type": "auth", "token": a["token"]}, 4403),
        (f"{API}/missions/999999/ws", {"type": "auth", "token": live.commander}, 4404),
        (f"{API}/ingest/ws", {"type": "auth", "token": live.commander}, 4403),
        (f"{API}/ingest/ws", {"type": "hello"}, 4401),
    ]
    for path, first, code in cases:
        with connect(f"{live.ws_url}{path}") as ws:
            ws.send(json.dumps(first))
            with pytest.raises(Exception) as info:
                while True:
                    ws.recv(timeout=10)
            assert getattr(info.value, "rcvd", None) is not None, path
            assert info.value.rcvd.code == code, (path, info.value)
    # cookie from another origin is refused
    r = httpx.post(f"{live.url}{API}/auth/login", json={"token": live.commander})
    cookie = r.cookies["hrtls_session"]
    with connect(f"{live.ws_url}{API}/missions/{mid}/ws", origin="https://evil.example",
                 additional_headers={"Cookie": f"hrtls_session={cookie}"}) as ws:
        with pytest.raises(Exception) as info:
            ws.recv(timeout=10)
        assert info.value.rcvd.code == 4403
