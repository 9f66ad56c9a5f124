"""Ranges between the dropped nodes through the service: every refusal, idempotent batches,
the live mission estimator equal to offline with them, their export and a restart."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from sqlalchemy import select

from hrtls.io.mission import read_mission
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.tracker import MissionTracker
from hrtls.pipeline import preset
from hrtls.service.client import AgentClient
from hrtls.service.db import make_engine, session_factory
from hrtls.service.missions import export_mission
from hrtls.service.models import MissionSnapshot, NetworkRangeBatch
from hrtls.service.network_sim import (
    RESCUER_PRESET,
    common_offset,
    create_network_mission,
    network_team,
    post_network_ranges,
)

from .conftest import Live, new_agent
from .streams import API, stream_agents
from .test_mission_live import _close, _offline, _runner, _same_nodes, _wait

OPTIONS = {"walk_s": 45.0, "stagger_s": 10.0, "n_nodes": 12, "n_robots": 1, "node_ranges": True}
PARAMS = {"silent_after_s": 120.0}


def _batch(seq: int = 0, **over: Any) -> dict[str, Any]:
    return {"seq": seq, "t_s": [1.0, 2.0], "node_a": ["N1", "N2"], "node_b": ["N2", "N3"],
            "range_m": [4.0, 5.5], **over}


def test_network_ranges_are_refused_unless_well_formed_and_authorised(
        live: Live, commander: httpx.Client) -> None:
    mid = commander.post(f"{API}/missions", json={"name": "n"}).json()["id"]
    url = f"{API}/missions/{mid}/network/ranges"
    r = commander.post(url, json=_batch())
    assert r.status_code == 404 and "declared no sensor network" in r.json()["detail"]
    assert commander.put(f"{API}/missions/{mid}/network",
                         json={"nodes": [{"id": n} for n in ("N1", "N2", "N3")]}
                         ).status_code == 200
    with live.client() as anon:
        assert anon.post(url, json=_batch()).status_code == 401
    agent = new_agent(commander, mid)["token"]
    viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
    for token in (agent, viewer["token"]):
        with live.client(token) as c:
            r = c.post(url, json=_batch())
            assert r.status_code == 403 and "commander" in r.json()["detail"]
    assert commander.post(f"{API}/missions/999/network/ranges", json=_batch()).status_code == 404
    for bad, field in (({"node_b": ["N2"]}, "node_b"), ({"node_a": ["N1", "N9"]}, "node_a[1]"),
                       ({"range_m": [4.0, -1.0]}, "range_m"),
                       ({"node_b": ["N1", "N3"]}, "node_b")):
        r = commander.post(url, json=_batch(**bad))
        assert r.status_code == 422 and field in r.json()["detail"], (bad, r.text)
    for bad in ({"range_m": [4.0, math.nan]}, {"t_s": []}, {"seq": -1}, {"extra": 1},
                {"t_s": [1.0] * 20001}):
        r = commander.post(url, content=json.dumps(_batch(**bad)),
                           headers={"content-type": "application/json"})
        assert r.status_code == 422, (bad, r.text)
    r = commander.post(url, content=b"x" * (live.settings.max_body_bytes + 1),
                       headers={"content-type": "application/json"})
    assert r.status_code == 413
    first = commander.post(url, json=_batch())
    assert first.status_code == 200 and first.json()["status"] == "accepted"
    again = commander.post(url, json=_batch(range_m=[9.0, 9.0]))
    assert again.status_code == 200 and again.json()["status"] == "duplicate"
    engine = make_engine(live.settings.db_url)
    try:
        with session_factory(engine)() as db:
            rows = list(db.scalars(select(NetworkRangeBatch)
                                   .where(NetworkRangeBatch.mission_id == mid)))
    finally:
        engine.dispose()
    assert [(b.seq, b.rows, b.t_first, b.t_last) for b in rows] == [(0, 2, 1.0, 2.0)]


def _setup(live: Live, seed: int) -> tuple[int, list[Any], float, NetworkRanges]:
    mission, members = network_team("inderst_hybrid_mission", seed=seed, options=OPTIONS)
    assert len(mission.network_ranges)
    with AgentClient(live.url, live.commander) as commander:
        mid, agents = create_network_mission(commander, "inderst_hybrid_mission", mission,
                                             members, params=PARAMS)
        offset = common_offset(commander, mid, members)
    return mid, agents, offset, mission.network_ranges


def _post(live: Live, mid: int, ranges: NetworkRanges, offset: float) -> None:
    with AgentClient(live.url, live.commander) as gw:
        post_network_ranges(gw, mid, ranges, speed=math.inf, t_offset_s=offset,
                            t_start_s=float(ranges.t_s[0]))


def test_live_mission_with_node_ranges_equals_offline_and_exports_them(
        make_live: Any, tmp_path: Path) -> None:
    live = make_live()
    mid, agents, offset, ranges = _setup(live, 2)
    _post(live, mid, ranges, offset)
    stream_agents(live.url, agents, offset)
    runner = _runner(live)
    _wait(runner, mid, done=False)
    _close(live, mid)
    _wait(runner, mid, done=True)
    lm = runner.missions[mid]
    assert lm.late_samples == 0 and lm.net_raw_id > 0
    with lm.lock:
        got = lm.tracker.result()
    loc = _same_nodes(got, _offline(live, mid))
    assert loc, "no node localized"
    sim = MissionTracker({str(aid): m.session for m, aid, _ in agents},
                         config=preset(RESCUER_PRESET),
                         kinds={str(aid): m.kind for m, aid, _ in agents})
    sim.feed_network(ranges)
    assert _same_nodes(got, sim.run()) == loc
    without = MissionTracker({str(aid): m.session for m, aid, _ in agents},
                             config=preset(RESCUER_PRESET),
                             kinds={str(aid): m.kind for m, aid, _ in agents}).run()
    assert {n for n, e in without.nodes.items() if e.localized} != set(loc) or any(
        not np.allclose(without.nodes[n].position_m, got.nodes[n].position_m) for n in loc)
    out = tmp_path / "export"
    export_mission(live.settings.db_url, mid, out)
    folder = read_mission(out)
    assert len(folder.network_ranges) == len(ranges)
    np.testing.assert_allclose(folder.network_ranges.t_s, ranges.t_s + offset)
    np.testing.assert_array_equal(folder.network_ranges.node_a, ranges.node_a)
    np.testing.assert_allclose(folder.network_ranges.range_m, ranges.range_m)


def test_a_restart_keeps_the_node_ranges_consumed(make_live: Any) -> None:
    first = make_live(snapshot_every_s=5.0)
    mid, agents, offset, ranges = _setup(first, 0)
    cut = offset + 30.0
    early = ranges.t_s + offset <= cut + 5.0
    _post(first, mid, NetworkRanges(t_s=ranges.t_s[early], node_a=ranges.node_a[early],
                                    node_b=ranges.node_b[early],
                                    range_m=ranges.range_m[early]), offset)
    seqs = stream_agents(first.url, agents, offset, t_to=cut)
    _wait(_runner(first), mid, done=False)
    engine = make_engine(first.settings.db_url)
    try:
        with session_factory(engine)() as db:
            deadline = time.monotonic() + 30
            snap = None
            while snap is None or snap.net_raw_id == 0:
                assert time.monotonic() < deadline, "no mission snapshot with node ranges"
                time.sleep(0.1)
                db.expire_all()
                snap = db.scalars(select(MissionSnapshot)
                                  .where(MissionSnapshot.mission_id == mid)
                                  .order_by(MissionSnapshot.horizon_s.desc())).first()
    finally:
        engine.dispose()
    first.stop()
    second = make_live(snapshot_every_s=5.0)
    late = ~early
    with AgentClient(second.url, second.commander) as gw:
        gw.request("POST", f"/missions/{mid}/network/ranges", json={
            "seq": 10_000, "t_s": (ranges.t_s[late] + offset).tolist(),
            "node_a": ranges.node_a[late].tolist(), "node_b": ranges.node_b[late].tolist(),
            "range_m": ranges.range_m[late].tolist()})
    stream_agents(second.url, agents, offset, t_from=cut, first_seq=seqs)
    runner = _runner(second)
    _wait(runner, mid, done=False)
    _close(second, mid)
    _wait(runner, mid, done=True)
    lm = runner.missions[mid]
    assert lm.restored_horizon_s is not None and lm.late_samples == 0
    with lm.lock:
        got = lm.tracker.result()
    _same_nodes(got, _offline(second, mid))


@pytest.mark.parametrize("speed", [math.inf, 50.0])
def test_gateway_posts_every_range_once_in_time_order(live: Live, speed: float) -> None:
    with AgentClient(live.url, live.commander) as c:
        mid = c.request("POST", "/missions", json={"name": "g"})["id"]
        ids = [f"N{i}" for i in range(4)]
        c.request("PUT", f"/missions/{mid}/network", json={"nodes": [{"id": n} for n in ids]})
        t = np.arange(0.0, 12.0, 0.5)
        ranges = NetworkRanges(t_s=t, node_a=np.array([ids[i % 3] for i in range(len(t))]),
                               node_b=np.array(["N3"] * len(t)), range_m=1.0 + t)
        sleeps: list[float] = []
        n = post_network_ranges(c, mid, ranges, speed=speed, t_offset_s=100.0, t_start_s=0.0,
                                sleep=sleeps.append)
    assert n == 3
    assert (not sleeps) if speed == math.inf else len(sleeps) == 2
    engine = make_engine(live.settings.db_url)
    try:
        with session_factory(engine)() as db:
            rows = list(db.scalars(select(NetworkRangeBatch).where(
                NetworkRangeBatch.mission_id == mid).order_by(NetworkRangeBatch.seq)))
    finally:
        engine.dispose()
    assert [b.seq for b in rows] == [0, 1, 2] and sum(b.rows for b in rows) == len(t)
    assert [b.t_first for b in rows] == [100.0, 105.0, 110.0]


def test_cli_streams_the_node_ranges_of_a_simulated_mission(live: Live,
                                                            commander: httpx.Client) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    out = CliRunner().invoke(app, [
        "mission", "simulate", "inderst_hybrid_mission", "--server", live.url, "--token",
        live.commander, "--speed", "0", "--seed", "4", "-O", "walk_s=30", "-O", "n_nodes=8",
        "-O", "node_ranges=true", "-O", "silent_after_s=5"])
    assert out.exit_code == 0, out.output
    mid = commander.get(f"{API}/missions").json()[-1]["id"]
    mission, _ = network_team("inderst_hybrid_mission", seed=4, options={
        "walk_s": 30.0, "n_nodes": 8, "node_ranges": True})
    engine = make_engine(live.settings.db_url)
    try:
        with session_factory(engine)() as db:
            rows = sum(db.scalars(select(NetworkRangeBatch.rows)
                                  .where(NetworkRangeBatch.mission_id == mid)))
    finally:
        engine.dispose()
    assert rows == len(mission.network_ranges) > 0
