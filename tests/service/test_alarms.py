"""Alarms judged from the IMU (hand-made signals) and the stored, pushed, acknowledged events."""

from __future__ import annotations

import json
import time

import httpx
import numpy as np
from tests.service.conftest import Live, new_agent, new_mission
from tests.service.streams import API
from websockets.sync.client import connect

from hrtls.service.alarms import AgentAlarms, AlarmProfile
from hrtls.service.batches import parse_batch


def imu_batch(seq: int, t0: float, n: int, *, moving: bool, rate_hz: float = 100.0,
              impact: bool = False) -> dict:
    rng = np.random.default_rng(seq)
    t = t0 + np.arange(n) / rate_hz
    acc = np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    if moving:
        acc[:, 2] += 2.0 * np.sin(2 * np.pi * 2.0 * (t - t0))
    if impact:
        acc[n // 2] = [0.0, 35.0, 9.81]
    return {"seq": seq, "imu": {"t": t.tolist(), "acc": acc.tolist()}}


def test_pass_prealarm_alarm_and_clear_from_imu() -> None:
    alarms = AgentAlarms(AlarmProfile(prealarm_s=20.0, alarm_s=30.0))
    raised = []
    seq = 0
    for k in range(5):   # 5 s walking
        raised += alarms.on_batch(parse_batch(imu_batch(seq, k, 100, moving=True)))
        seq += 1
    assert raised == []
    for k in range(5, 40):   # 35 s still
        raised += alarms.on_batch(parse_batch(imu_batch(seq, k, 100, moving=False)))
        seq += 1
    kinds = [(r.kind, r.clears) for r in raised]
    assert kinds == [("pass_prealarm", None), ("pass_prealarm", "pass_prealarm"),
                     ("pass_alarm", None)]
    # last motion window ends at 4.99 s: pre-alarm at still >= 20 s, alarm at >= 30 s
    assert 24.9 <= raised[0].t <= 26.0 and 34.9 <= raised[2].t <= 36.0
    raised = alarms.on_batch(parse_batch(imu_batch(seq, 40, 100, moving=True)))
    assert [(r.kind, r.clears) for r in raised] == [("pass_alarm", "pass_alarm")]
    # back-filled (older) data are not judged again
    assert alarms.on_batch(parse_batch(imu_batch(seq + 1, 10, 100,
                                                          moving=True))) == []


def test_fall_is_impact_then_no_motion() -> None:
    alarms = AgentAlarms(AlarmProfile())
    raised = []
    for k in range(3):
        raised += alarms.on_batch(parse_batch(imu_batch(k, k, 100, moving=True)))
    raised += alarms.on_batch(parse_batch(imu_batch(3, 3, 100, moving=False,
                                                             impact=True)))
    for k in range(4, 12):
        raised += alarms.on_batch(parse_batch(imu_batch(k, k, 100, moving=False)))
    falls = [r for r in raised if r.kind == "fall"]
    assert len(falls) == 1 and falls[0].clears is None
    assert abs(falls[0].detail["impact_t"] - 3.5) < 0.02 and falls[0].t >= 8.5
    # an impact followed by walking is no fall
    alarms = AgentAlarms(AlarmProfile())
    out = alarms.on_batch(parse_batch(imu_batch(0, 0, 100, moving=False, impact=True)))
    for k in range(1, 10):
        out += alarms.on_batch(parse_batch(imu_batch(k, k, 100, moving=True)))
    assert not [r for r in out if r.kind == "fall"]


def _events(c: httpx.Client, mid: int) -> list[dict]:
    return list(c.get(f"{API}/missions/{mid}/events").json())


def _wait_for(c: httpx.Client, mid: int, kind: str, timeout_s: float = 60.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for e in _events(c, mid):
            if e["kind"] == kind:
                return e
        time.sleep(0.1)
    raise AssertionError(f"no {kind} event; have {[e['kind'] for e in _events(c, mid)]}")


def test_events_stored_pushed_and_acknowledged(live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander, alarm_profile={"prealarm_s": 3, "alarm_s": 5,
                                                "silent_s": 1.0})["id"]
    a = new_agent(commander, mid)
    aid = a["agent"]["id"]
    with connect(f"{live.ws_url}{API}/missions/{mid}/ws",
                 additional_headers={"Authorization": f"Bearer {live.commander}"}) as dash:
        assert json.loads(dash.recv(timeout=30))["type"] == "hello"
        assert json.loads(dash.recv(timeout=30))["type"] == "snapshot"
        with live.client(a["token"]) as agent:
            for k in range(8):
                r = agent.post(f"{API}/ingest", json=imu_batch(k, float(k), 100,
                                                               moving=k == 0))
                assert r.status_code == 200
            agent.post(f"{API}/ingest", json={"seq": 8, "sos": True})
        alarm = _wait_for(commander, mid, "pass_alarm")
        assert alarm["severity"] == "alarm" and alarm["agent"] == aid
        assert alarm["acknowledged_by"] is None
        sos = _wait_for(commander, mid, "sos")
        assert sos["severity"] == "alarm"
        silent = _wait_for(commander, mid, "silent")
        assert silent["detail"]["silent_s"] >= 1.0
        pushed: dict[int, dict] = {}
        deadline = time.monotonic() + 30
        while not {alarm["id"], sos["id"]} <= set(pushed) and time.monotonic() < deadline:
            msg = json.loads(dash.recv(timeout=30))
            for e in msg.get("events", []):
                pushed[e["id"]] = e
        assert pushed[alarm["id"]]["kind"] == "pass_alarm"
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
        with live.client(viewer["token"]) as v:
            assert v.post(f"{API}/missions/{mid}/events/{alarm['id']}/ack").status_code == 403
        with live.client(a["token"]) as agent:
            assert agent.get(f"{API}/missions/{mid}/events").status_code == 403
        r = commander.post(f"{API}/missions/{mid}/events/{alarm['id']}/ack")
        assert r.status_code == 200
        acked = r.json()
        assert acked["acknowledged_by"] == "commander" or acked["acknowledged_by"]
        assert acked["acknowledged_at"] is not None
        again = commander.post(f"{API}/missions/{mid}/events/{alarm['id']}/ack").json()
        assert again["acknowledged_at"] == acked["acknowledged_at"]
        other = new_mission(commander)["id"]
        assert commander.post(f"{API}/missions/{other}/events/{alarm['id']}/ack"
                              ).status_code == 404
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            msg = json.loads(dash.recv(timeout=30))
            if any(e["id"] == alarm["id"] and e["acknowledged_at"] for e in
                   msg.get("events", [])):
                break
        else:
            raise AssertionError("acknowledgement not pushed")
    unacked = commander.get(f"{API}/missions/{mid}/events",
                            params={"unacknowledged": "true"}).json()
    assert alarm["id"] not in [e["id"] for e in unacked]


def test_orders_delivered_and_answered(live: Live, commander: httpx.Client) -> None:
    mid = new_mission(commander)["id"]
    robot = new_agent(commander, mid, name="Robot", kind="robot")
    rescuer = new_agent(commander, mid, name="B")
    rid = robot["agent"]["id"]
    r = commander.post(f"{API}/missions/{mid}/orders",
                       json={"kind": "goto", "agents": [rid],
                             "waypoint": {"x": 12.0, "y": 3.5, "floor": 1}})
    assert r.status_code == 201
    order = r.json()[0]
    assert order["status"] == "pending" and order["created_by"]
    infra = commander.get(f"{API}/missions/{mid}/infrastructure").json()
    assert infra["waypoints"] == [{"agent": rid, "order": order["id"], "x": 12.0, "y": 3.5,
                                   "floor": 1, "status": "pending"}]
    with live.client(robot["token"]) as agent:
        got = agent.get(f"{API}/agent/orders").json()
        assert [o["id"] for o in got] == [order["id"]] and got[0]["status"] == "delivered"
        r = agent.post(f"{API}/agent/orders/{order['id']}/receipt", json={"status": "done"})
        assert r.status_code == 200 and r.json()["status"] == "done"
        assert agent.post(f"{API}/agent/orders/{order['id']}/receipt",
                          json={"status": "accepted"}).status_code == 409
        assert agent.get(f"{API}/missions/{mid}/orders").status_code == 403
    everyone = commander.post(f"{API}/missions/{mid}/orders",
                              json={"kind": "evacuate"}).json()
    assert sorted(o["agent"] for o in everyone) == sorted([rid, rescuer["agent"]["id"]])
    with live.client(rescuer["token"]) as agent:
        r = agent.post(f"{API}/agent/orders/{order['id']}/receipt", json={"status": "done"})
        assert r.status_code == 404
    with connect(f"{live.ws_url}{API}/ingest/ws",
                 additional_headers={"Authorization": f"Bearer {rescuer['token']}"}) as ws:
        pushed = json.loads(ws.recv(timeout=30))
        assert pushed["type"] == "order" and pushed["order"]["kind"] == "evacuate"
        r = commander.post(f"{API}/missions/{mid}/orders",
                           json={"kind": "text", "text": "report", "agents": [
                               rescuer["agent"]["id"]]})
        msg = json.loads(ws.recv(timeout=30))
        assert msg["type"] == "order" and msg["order"]["text"] == "report"
        ws.send(json.dumps({"type": "receipt", "order": msg["order"]["id"],
                            "status": "accepted", "text": "on my way"}))
        assert json.loads(ws.recv(timeout=30)) == {"type": "receipt_ack",
                                                   "order": msg["order"]["id"]}
    listed = commander.get(f"{API}/missions/{mid}/orders",
                           params={"agent": rescuer["agent"]["id"]}).json()
    assert [o["status"] for o in listed] == ["delivered", "accepted"]
    assert listed[1]["answer_text"] == "on my way"
    for body in ({"kind": "text"}, {"kind": "goto", "agents": [rid]},
                 {"kind": "launch"}, {"kind": "text", "text": "x", "agents": [999999]}):
        assert commander.post(f"{API}/missions/{mid}/orders", json=body).status_code in (
            404, 422), body
    viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
    with live.client(viewer["token"]) as v:
        assert v.post(f"{API}/missions/{mid}/orders",
                      json={"kind": "evacuate"}).status_code == 403
        assert v.get(f"{API}/missions/{mid}/orders").status_code == 200
