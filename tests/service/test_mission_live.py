"""The mission estimator live in the service: same result as offline, nodes in the picture,
the socket deltas, the infrastructure endpoint and the export; restart from a snapshot."""

from __future__ import annotations

import contextlib
import json
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from sqlalchemy import func, select
from websockets.sync.client import connect

from hrtls.io.mission import read_mission
from hrtls.mission.tracker import MissionResult, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline import snapshot as codec
from hrtls.service.client import AgentClient
from hrtls.service.db import make_engine, session_factory
from hrtls.service.mission_runner import MissionRunner, offline_tracker
from hrtls.service.missions import export_mission
from hrtls.service.models import MissionSnapshot
from hrtls.service.network_sim import (
    RESCUER_PRESET,
    common_offset,
    create_network_mission,
    network_team,
)

from .conftest import Live
from .streams import API, stream_agents

OPTIONS = {"walk_s": 45.0, "stagger_s": 10.0, "n_nodes": 12, "n_robots": 1}
PARAMS = {"silent_after_s": 120.0}   # no agent is taken as silent: the end is the close


def _runner(live: Live) -> MissionRunner:
    runner: MissionRunner = live.server.config.app.state.services.missions
    return runner


def _close(live: Live, mid: int) -> None:
    """End the mission: its last windows are processed."""
    with live.client(live.commander) as c:
        assert c.patch(f"{API}/missions/{mid}", json={"status": "closed"}).status_code == 200


def _wait(runner: MissionRunner, mid: int, *, done: bool, timeout_s: float = 300.0) -> None:
    """Until the estimator consumed every batch (``done``: and processed every window)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        lm = runner.missions.get(mid)
        if lm is not None and runner.caught_up(mid):
            tr = lm.tracker
            if not done or (tr.t0 is not None
                            and tr.horizon_s > max(b.t_last for b in tr.buffers.values())):
                return
        time.sleep(0.1)
    raise AssertionError(f"mission {mid} not done: {runner.errors}")


def _offline(live: Live, mid: int) -> MissionResult:
    engine = make_engine(live.settings.db_url)
    try:
        return offline_tracker(session_factory(engine), mid).run()
    finally:
        engine.dispose()


def _same_nodes(a: MissionResult, b: MissionResult) -> list[str]:
    loc = sorted(n for n, e in a.nodes.items() if e.localized)
    assert loc == sorted(n for n, e in b.nodes.items() if e.localized)
    for n in loc:
        np.testing.assert_allclose(a.nodes[n].position_m, b.nodes[n].position_m, atol=1e-12,
                                   rtol=0)
        np.testing.assert_allclose(a.nodes[n].covariance_m2, b.nodes[n].covariance_m2,
                                   atol=1e-12, rtol=0)
    assert set(a.node_history) == set(b.node_history)
    for n, h in a.node_history.items():
        np.testing.assert_array_equal(h.t, b.node_history[n].t)
    return loc


def _setup(live: Live, seed: int) -> tuple[int, list[Any], float]:
    mission, members = network_team("inderst_hybrid_mission", seed=seed, options=OPTIONS)
    with AgentClient(live.url, live.commander) as commander:
        mid, agents = create_network_mission(commander, "inderst_hybrid_mission", mission,
                                             members, params=PARAMS)
        offset = common_offset(commander, mid, members)
    return mid, agents, offset


def test_live_mission_estimator_equals_offline_and_is_published(
        make_live: Any, db_url: str, tmp_path: Path) -> None:
    """Seed 1 (three rescuers, a robot); on PostgreSQL the per-agent trackers run in worker
    processes (the mission estimator is in the service process either way)."""
    engine = "processes" if db_url.startswith("postgresql") else "local"
    live = make_live(engine=engine, process_shards=1)
    mid, agents, offset = _setup(live, 1)
    with live.client(live.commander) as c, connect(
            f"{live.ws_url}{API}/missions/{mid}/ws",
            additional_headers={"Authorization": f"Bearer {live.commander}"},
            ping_interval=None) as dash:
        assert json.loads(dash.recv(timeout=30))["type"] == "hello"
        assert json.loads(dash.recv(timeout=30))["type"] == "snapshot"
        stream_agents(live.url, agents, offset)
        runner = _runner(live)
        _wait(runner, mid, done=False)
        lm = runner.missions[mid]
        assert lm.tracker.horizon_s <= max(b.t_last for b in lm.tracker.buffers.values())
        _close(live, mid)
        _wait(runner, mid, done=True)
        lm = runner.missions[mid]
        assert lm.late_samples == 0
        with lm.lock:
            got = lm.tracker.result()
        want = _offline(live, mid)
        loc = _same_nodes(got, want)
        assert loc, "no node localized"
        assert offset == 0.0        # a fresh mission keeps the simulator's times: the live
        sim = MissionTracker(       # estimates are those of the simulated mission offline
            {str(aid): m.session for m, aid, _ in agents}, config=preset(RESCUER_PRESET),
            kinds={str(aid): m.kind for m, aid, _ in agents}).run()
        assert lm.tracker.config is not None
        assert lm.tracker.config.attitude.heading_source == "gyro+compass"
        assert _same_nodes(got, sim) == loc
        for k, r in want.agents.items():
            np.testing.assert_array_equal(r.trajectory.t, got.agents[k].trajectory.t)
            np.testing.assert_allclose(r.trajectory.xyz, got.agents[k].trajectory.xyz,
                                       atol=1e-12, rtol=0)
        pushed: dict[str, dict[str, Any]] = {}     # the newest state of each node pushed
        deadline = time.monotonic() + 60
        with contextlib.suppress(TimeoutError):     # until the deltas stop
            while time.monotonic() < deadline:
                for n in json.loads(dash.recv(timeout=3))["nodes"]:
                    pushed[n["id"]] = n
        assert set(loc) <= set(pushed)
        for n in loc:
            assert pushed[n]["localized"]
            np.testing.assert_allclose(pushed[n]["position"], got.nodes[n].position_m)
        infra = c.get(f"{API}/missions/{mid}/infrastructure").json()
        by_id = {n["id"]: n for n in infra["nodes"]}
        assert set(by_id) >= set(want.nodes)
        for n in loc:
            np.testing.assert_allclose(by_id[n]["position"], got.nodes[n].position_m)
            assert by_id[n]["localized"] and by_id[n]["sigma_m"] > 0
        pic = c.get(f"{API}/missions/{mid}/snapshot").json()
        assert {n["id"] for n in pic["nodes"] if n["localized"]} == set(loc)
    out = tmp_path / "export"
    export_mission(live.settings.db_url, mid, out)
    net = json.loads((out / "network.json").read_text())
    est = {n["id"]: n.get("service", {}) for n in net["nodes"]}
    for n in loc:
        np.testing.assert_allclose(est[n]["position"], got.nodes[n].position_m)
    folder = read_mission(out)
    assert set(folder.nodes) == set(est)


def test_network_declaration_is_checked(live: Live, commander: httpx.Client) -> None:
    mid = commander.post(f"{API}/missions", json={"name": "n"}).json()["id"]
    r = commander.put(f"{API}/missions/{mid}/network",
                      json={"nodes": [{"id": "N1"}, {"id": "N1"}]})
    assert r.status_code == 422 and "N1" in r.json()["detail"]
    r = commander.put(f"{API}/missions/{mid}/network",
                      json={"nodes": [{"id": "N1"}], "params": {"chunk": 5}})
    assert r.status_code == 422 and "params.chunk" in r.json()["detail"]
    r = commander.put(f"{API}/missions/{mid}/network",
                      json={"nodes": [{"id": "N1"}], "params": {"chunk_s": -1}})
    assert r.status_code == 422 and "chunk_s" in r.json()["detail"]
    for bad, field in (({"smoother": "fast"}, "smoother"), ({"smoother": 1}, "params.smoother"),
                       ({"chunk_s": "5"}, "params.chunk_s")):
        r = commander.put(f"{API}/missions/{mid}/network",
                          json={"nodes": [{"id": "N1"}], "params": bad})
        assert r.status_code == 422 and field in r.json()["detail"], (bad, r.text)
    assert commander.get(f"{API}/missions/{mid}/network").status_code == 404
    assert commander.put(f"{API}/missions/{mid}/network",
                         json={"nodes": [{"id": "N1"}]}).status_code == 200
    got = commander.get(f"{API}/missions/{mid}/network").json()
    assert [n["id"] for n in got["nodes"]] == ["N1"] and not got["nodes"][0]["localized"]
    assert got["params"]["smoother"] in ("off", "nodes", "feedback")
    r = commander.put(f"{API}/missions/{mid}/network",
                      json={"nodes": [{"id": "N1"}], "params": {"smoother": "feedback"}})
    assert r.status_code == 200 and r.json()["params"]["smoother"] == "feedback"
    assert commander.get(f"{API}/missions/{mid}/network").json()["params"]["smoother"] == \
        "feedback"
    assert commander.put(f"{API}/missions/999/network",
                         json={"nodes": []}).status_code == 404


def _age_snapshots(db_url: str, mid: int) -> None:
    """Rewrite the mission's snapshots as an older version wrote them (``mission_version`` 2)."""
    engine = make_engine(db_url)
    try:
        with session_factory(engine)() as db:
            for snap in db.scalars(select(MissionSnapshot)
                                   .where(MissionSnapshot.mission_id == mid)):
                state = codec.unpack(snap.state)
                state["mission_version"] = 2
                snap.state = codec.pack(state)
            db.commit()
    finally:
        engine.dispose()


@pytest.mark.parametrize("older", [False, True], ids=["current", "older-version"])
def test_a_restart_restores_the_newest_snapshot_and_replays_the_rest(
        make_live: Any, older: bool) -> None:
    """A restart continues from the newest snapshot; one it cannot read (an older version's)
    is logged and the mission replayed from its raw log: the same estimates either way."""
    first = make_live(snapshot_every_s=5.0)
    mid, agents, offset = _setup(first, 0)
    cut = offset + 30.0
    seqs = stream_agents(first.url, agents, offset, t_to=cut)
    _wait(_runner(first), mid, done=False)
    engine = make_engine(first.settings.db_url)
    try:
        with session_factory(engine)() as db:
            deadline = time.monotonic() + 30
            while not db.scalar(select(func.count(MissionSnapshot.id))
                                .where(MissionSnapshot.mission_id == mid)):
                assert time.monotonic() < deadline, "no mission snapshot"
                time.sleep(0.1)
                db.expire_all()
            snap = db.scalars(select(MissionSnapshot).where(MissionSnapshot.mission_id == mid)
                              .order_by(MissionSnapshot.horizon_s.desc())).first()
            assert snap is not None and snap.raw_id > 0 and snap.horizon_s > offset
    finally:
        engine.dispose()
    with first.client(first.commander) as c:
        r = c.put(f"{API}/missions/{mid}/network", json={"nodes": []})
        assert r.status_code == 409 and "started" in r.json()["detail"]
    first.stop()
    if older:
        _age_snapshots(first.settings.db_url, mid)
    second = make_live(snapshot_every_s=5.0)
    stream_agents(second.url, agents, offset, t_from=cut, first_seq=seqs)
    runner = _runner(second)
    _wait(runner, mid, done=False)
    _close(second, mid)
    _wait(runner, mid, done=True)
    lm = runner.missions[mid]
    assert lm.late_samples == 0
    with lm.lock:
        got = lm.tracker.result()
    want = _offline(second, mid)
    _same_nodes(got, want)
    if older:
        assert lm.restored_horizon_s is None
        for k, r in want.agents.items():
            np.testing.assert_allclose(r.trajectory.xyz, got.agents[k].trajectory.xyz,
                                       atol=1e-12, rtol=0)
        return
    assert lm.restored_horizon_s is not None and lm.restored_horizon_s >= snap.horizon_s
    for k, r in want.agents.items():        # rows after the restored snapshot
        t = got.agents[k].trajectory.t
        i = int(np.searchsorted(r.trajectory.t, t[0]))
        if lm.tracker.kinds[k] == "rescuer":     # a robot's snapshot holds its rows
            assert i > 0, k
        np.testing.assert_array_equal(r.trajectory.t[i:], t)
        np.testing.assert_allclose(r.trajectory.xyz[i:], got.agents[k].trajectory.xyz,
                                   atol=1e-12, rtol=0)


def test_cli_streams_a_networked_mission(live: Live, commander: httpx.Client) -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    args = ["mission", "simulate", "inderst_hybrid_mission", "--server", live.url, "--token",
            live.commander, "--speed", "0", "--seed", "4", "-O", "walk_s=30", "-O", "n_nodes=8",
            "-O", "silent_after_s=5"]
    out = CliRunner().invoke(app, args)
    assert out.exit_code == 0, out.output
    assert "8 nodes" in out.output and "unacknowledged: 0" in out.output
    mid = commander.get(f"{API}/missions").json()[-1]["id"]
    net = commander.get(f"{API}/missions/{mid}/network").json()
    assert net["params"]["silent_after_s"] == 5.0 and len(net["nodes"]) >= 8
    bad = CliRunner().invoke(app, [*args[:9], "-O", "walk=30"])
    assert bad.exit_code != 0 and "walk" in bad.output and "walk_s" in bad.output


def test_a_landmark_version_written_live_reaches_the_mission_estimator(make_live: Any) -> None:
    live = make_live()
    mid, agents, offset = _setup(live, 0)
    seqs = stream_agents(live.url, agents, offset, t_to=offset + 12.0)
    runner = _runner(live)
    _wait(runner, mid, done=False)
    with live.client(live.commander) as c:
        tag = c.get(f"{API}/missions/{mid}/landmarks").json()[0]
        x, y, z = tag["position"]
        moved = {**tag, "position": [x + 2.0, y, z], "updated": offset + 30.0}
        r = c.put(f"{API}/missions/{mid}/landmarks/{tag['id']}", json=moved)
        assert r.status_code == 200, r.text
    deadline = time.monotonic() + 30
    lm = runner.missions[mid]
    while not lm.tracker.landmark_updates:
        assert time.monotonic() < deadline, "the version did not reach the estimator"
        time.sleep(0.1)
    assert lm.tracker.horizon_s < offset + 30.0 and not lm.late_versions
    stream_agents(live.url, agents, offset, t_from=offset + 12.0, first_seq=seqs)
    _wait(runner, mid, done=False)
    _close(live, mid)
    _wait(runner, mid, done=True)
    with lm.lock:
        got = lm.tracker.result()
    want = _offline(live, mid)               # the version given at the start
    _same_nodes(got, want)
    for k, r in want.agents.items():
        np.testing.assert_allclose(r.trajectory.xyz, got.agents[k].trajectory.xyz, atol=1e-12,
                                   rtol=0)


def test_heard_and_delocalized_nodes_are_published_as_the_estimator_has_them(
        make_live: Any) -> None:
    """Seed 48 of a small mission (tags at the entrance only, no robot): nodes heard but never
    localized, and N10 localized mid-way then refused at the end (a check failed on its final
    readings); the network, the snapshot and the socket must give each node's state as the
    estimator has it, not its last localized estimate."""
    live = make_live()
    mission, members = network_team("inderst_hybrid_mission", seed=48, options={
        "walk_s": 30.0, "stagger_s": 5.0, "n_nodes": 10, "n_rescuers": 2, "n_robots": 0,
        "tag_layout": "entrance"},
        rescuer_preset="default")   # a case with a node localized, then refused
    with AgentClient(live.url, live.commander) as commander:
        mid, agents = create_network_mission(commander, "small", mission, members,
                                             params=PARAMS)
        offset = common_offset(commander, mid, members)
    runner = _runner(live)
    with live.client(live.commander) as c, connect(
            f"{live.ws_url}{API}/missions/{mid}/ws",
            additional_headers={"Authorization": f"Bearer {live.commander}"},
            ping_interval=None) as dash:
        assert json.loads(dash.recv(timeout=30))["type"] == "hello"
        assert json.loads(dash.recv(timeout=30))["type"] == "snapshot"
        stream_agents(live.url, agents, offset)
        _wait(runner, mid, done=False)
        _close(live, mid)
        _wait(runner, mid, done=True)
        tr = runner.missions[mid].tracker
        with runner.missions[mid].lock:
            history = {n: [h[0] for h in rows] for n, rows in tr.history.items()}
            final = {n: (e.localized, len(tr.readings[n].r)) for n, e in tr.estimates.items()}
            heard = {n: len(r.r) for n, r in tr.readings.items()}
        assert any(not final[n][0] for n in history), "no node lost its localization"
        assert any(n not in history for n in heard), "no node heard and never localized"
        time.sleep(1.0)                     # the last poll's delta is pushed
        pushed: dict[str, dict[str, Any]] = {}
        with contextlib.suppress(TimeoutError):
            while True:
                for n in json.loads(dash.recv(timeout=2))["nodes"]:
                    pushed[n["id"]] = n
        net = c.get(f"{API}/missions/{mid}/network").json()
        pic = c.get(f"{API}/missions/{mid}/snapshot").json()
    by_id = {n["id"]: n for n in net["nodes"]}
    assert {n["id"] for n in pic["nodes"]} == set(by_id)
    assert {n for n, v in by_id.items() if v["declared"]} == set(mission.node_truth_m)
    for n, v in by_id.items():
        if n not in heard:
            assert (v["readings"], v["passes"], v["t"], v["reason"]) == (0, 0, None, "never heard")
            assert not v["localized"] and v["position"] is None
            continue
        assert v["readings"] == heard[n] and v["passes"] >= 1
        assert v["localized"] == (n in final and final[n][0]), n
        assert (v["position"] is None) == (not v["localized"]) == (v["reason"] != "")
        assert pushed[n]["localized"] == v["localized"] and pushed[n]["readings"] == heard[n]
        assert pushed[n]["declared"] == v["declared"]


def test_a_two_floor_mission_live_equals_offline(make_live: Any, db_url: str) -> None:
    """The two-floor building (``n_floors = 2``, no robot): the service's estimator gives the
    offline run of the simulated sessions, the nodes' floors included."""
    live = make_live(engine="local")
    mission, members = network_team("inderst_hybrid_mission", seed=4, options={
        **OPTIONS, "walk_s": 60.0, "n_robots": 0, "n_rescuers": 2, "n_floors": 2})
    with AgentClient(live.url, live.commander) as commander:
        mid, agents = create_network_mission(commander, "inderst_hybrid_mission", mission,
                                             members, params=PARAMS)
        offset = common_offset(commander, mid, members)
    assert offset == 0.0
    stream_agents(live.url, agents, offset)
    runner = _runner(live)
    _wait(runner, mid, done=False)
    _close(live, mid)
    _wait(runner, mid, done=True)
    lm = runner.missions[mid]
    with lm.lock:
        got = lm.tracker.result()
    sim = MissionTracker({str(aid): m.session for m, aid, _ in agents},
                         config=preset(RESCUER_PRESET),
                         kinds={str(aid): m.kind for m, aid, _ in agents}).run()
    loc = _same_nodes(got, sim)
    assert any(mission.node_floor[n] == 1 for n in loc), "no floor-1 node localized"
    assert got.node_floor == sim.node_floor
    assert {mission.node_floor[n] for n in loc} == {got.node_floor[n] for n in loc} == {0, 1}
    with live.client(live.commander) as c:
        infra = c.get(f"{API}/missions/{mid}/infrastructure").json()
    by_id = {n["id"]: n for n in infra["nodes"]}
    assert all(by_id[n]["floor"] == got.node_floor[n] for n in loc)
    for k, r in sim.agents.items():
        np.testing.assert_array_equal(r.trajectory.t, got.agents[k].trajectory.t)
        np.testing.assert_allclose(r.trajectory.xyz, got.agents[k].trajectory.xyz,
                                   atol=1e-12, rtol=0)
