"""Landmark versions written during a mission reach the running trackers from their time on."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from tests.service.conftest import Live, start_live
from tests.service.streams import API, mission_for, office, offline_rows, start_pose, stored
from tests.service.test_ingest import wait_idle

from hrtls.data import Landmark, Session
from hrtls.io.mission import read_mission
from hrtls.pipeline import Tracker, preset
from hrtls.service.client import AgentClient, session_batches
from hrtls.service.db import make_engine, session_factory
from hrtls.service.landmark_versions import write_version
from hrtls.service.missions import export_mission
from hrtls.service.settings import Settings


def _offline(session: Session, versions: list[dict[str, Any]]) -> Any:
    """The session tracked offline with ``versions`` queued before its data."""
    tracker = Tracker(preset("default"))
    tracker.start_session(session)
    tracker.update_landmarks([Landmark.model_validate(v) for v in versions])
    tracker.update(session)
    return tracker.finish().trajectory


def _assert_tracks_as(got: dict[str, np.ndarray], ref: Any) -> None:
    n = len(got["t"])
    assert n > 100 and got["t"][-1] >= ref.t[-1] - 8.0, (n, got["t"][-1], ref.t[-1])
    assert np.all(np.diff(got["t"]) > 0), "no duplicated estimates"
    np.testing.assert_allclose(got["t"], ref.t[:n], atol=1e-9)
    np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-9)
    np.testing.assert_allclose(got["cov"], ref.cov_xy[:n], atol=1e-9)


def _landmark(session: Session, key: str, **change: Any) -> dict[str, Any]:
    return {**session.landmarks[key].model_dump(mode="json", exclude_none=True), **change}


def test_versions_in_the_past_and_future_of_the_data_equal_offline(
        make_live: Callable[..., Live], tmp_path: Path) -> None:
    live = make_live(snapshot_every_s=5.0)
    session = office()
    batches = [b for _, b in session_batches(session, chunk_s=0.5)]
    moved = _landmark(session, "B7", position=[19.0, 15.0, 2.5], updated=20.0)
    destroyed = _landmark(session, "B8", status="destroyed", hazard="smoke", updated=35.0)
    with live.client(live.commander) as commander:
        mid, aid, token = mission_for(commander, session)
        with AgentClient(live.url, token, fmt="msgpack") as agent:
            agent.checkin(start_pose(session))
            for b in batches[:60]:   # data up to 30 s
                agent.submit(b)
            wait_idle(live)
            # 20 s lies before the data consumed (and two snapshots): the tracker re-runs
            r = commander.put(f"{API}/missions/{mid}/landmarks/B7", json=moved)
            assert r.status_code == 200 and r.json()["updated"] == 20.0, r.text
            r = commander.put(f"{API}/missions/{mid}/landmarks/B8", json=destroyed)
            assert r.status_code == 200, r.text
            r = commander.put(f"{API}/missions/{mid}/landmarks/B8",
                              json={**destroyed, "hazard": "fire"})
            assert r.status_code == 409 and "35.0" in r.json()["detail"], r.text
            for b in batches[60:]:
                agent.submit(b)
            assert agent.flush() and agent.outbox == {}
        wait_idle(live)
        got = stored(commander, mid, aid)
        history = commander.get(f"{API}/missions/{mid}/landmark-versions").json()
        current = {d["id"]: d for d in commander.get(f"{API}/missions/{mid}/landmarks").json()}
    assert [h["t"] for h in history][-2:] == [20.0, 35.0]
    assert sum(h["t"] is None for h in history) == len(session.landmarks)
    assert current["B7"]["position"] == [19.0, 15.0, 2.5]
    assert current["B8"]["status"] == "destroyed"
    ref = _offline(session, [moved, destroyed])
    _assert_tracks_as(got, ref)
    plain = offline_rows()
    n = len(got["t"])
    assert np.max(np.abs(got["xy"] - plain.xyz[:n, :2])) > 0.05, "the versions change the track"
    # the export is a mission folder that carries the versions: offline, as live
    export_mission(live.settings.db_url, mid, tmp_path / "export")
    folder = read_mission(tmp_path / "export")
    assert [v.updated for v in folder.landmark_updates] == [20.0, 35.0]


def test_delete_destroys_from_now_and_a_restart_drops_a_stale_snapshot(db_url: str) -> None:
    session = office()
    batches = [b for _, b in session_batches(session, chunk_s=0.5)]
    settings = Settings(db=db_url, snapshot_every_s=5.0)
    live = start_live(settings)
    try:
        with live.client(live.commander) as commander:
            mid, aid, token = mission_for(commander, session)
            assert commander.delete(f"{API}/missions/{mid}/landmarks/B6").status_code == 204
            with AgentClient(live.url, token, fmt="msgpack") as agent:
                agent.checkin(start_pose(session))
                for b in batches:
                    agent.submit(b)
                assert agent.flush() and agent.outbox == {}
            wait_idle(live)
            r = commander.delete(f"{API}/missions/{mid}/landmarks/B7")
            assert r.status_code == 204, r.text
            wait_idle(live)
            history = commander.get(f"{API}/missions/{mid}/landmark-versions").json()
    finally:
        live.stop()
    # B6 went before any data: gone from the start; B7 is destroyed from the server's time
    assert all(h["landmark"]["id"] != "B6" for h in history)
    gone = history[-1]
    assert gone["landmark"]["id"] == "B7" and gone["landmark"]["status"] == "destroyed"
    assert gone["t"] is not None and gone["t"] > 0.0
    start = session.with_parts(landmarks={k: v for k, v in session.landmarks.items()
                                          if k != "B6"})
    # a version committed without its re-run (as if the service died in between): the
    # snapshots after 25 s lack it, and the restarted service must not restore them
    late = _landmark(session, "B2", position=[33.0, 2.0, 2.5], updated=25.0)
    engine = make_engine(settings.db_url)
    try:
        with session_factory(engine)() as db:
            write_version(db, mid, late, now_t=1e9)
            db.commit()
    finally:
        engine.dispose()
    live = start_live(settings)
    try:
        wait_idle(live)
        with live.client(live.commander) as commander:
            got = stored(commander, mid, aid)
    finally:
        live.stop()
    _assert_tracks_as(got, _offline(start, [gone["landmark"], late]))
