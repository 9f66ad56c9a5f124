"""Tracker snapshots: spread over the period across agents, none before a tracker exists."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from sqlalchemy import select
from tests.service.conftest import Live
from tests.service.streams import mission_for, office, start_pose

from hrtls.service.client import AgentClient, session_batches
from hrtls.service.host import snapshot_phase
from hrtls.service.models import TrackerSnapshot


def test_phases_of_consecutive_agents_spread_evenly() -> None:
    for n in (2, 10, 300):
        phases = np.sort([snapshot_phase(1 + i) for i in range(n)])
        gaps = np.diff(np.concatenate([phases, [phases[0] + 1.0]]))
        assert np.all((phases >= 0.0) & (phases < 1.0))
        assert gaps.max() < 3.0 / n, (n, gaps.max())


def test_agents_streaming_together_snapshot_at_their_own_phase(
        make_live: Callable[..., Live]) -> None:
    period_s = 10.0
    live = make_live(snapshot_every_s=period_s)
    services = live.server.config.app.state.services
    session = office(duration_s=40.0)
    batches = [b for _, b in session_batches(session, chunk_s=0.5)]
    agents = []
    with live.client(live.commander) as commander:
        for name in ("A", "B"):
            _, aid, token = mission_for(commander, session, name=name)
            agents.append((aid, AgentClient(live.url, token)))
        for _, client in agents:
            client.checkin(start_pose(session))
        for b in batches:
            for _, client in agents:
                client.submit(b)
    for _, client in agents:
        assert client.outbox == {}
        client.close()
    deadline = time.monotonic() + 120
    while not services.host.idle():
        assert time.monotonic() < deadline
        time.sleep(0.05)
    firsts = {}
    with services.sessions() as db:
        for aid, _ in agents:
            t_data = sorted(db.scalars(select(TrackerSnapshot.t_data).where(
                TrackerSnapshot.agent_id == aid)))
            assert t_data, f"agent {aid} has no snapshot"
            assert np.all(np.diff(t_data) >= period_s - 0.5 - 1e-9)
            firsts[aid] = t_data[0]
    (a, _), (b, _) = agents
    # same data, so the same first row: the first snapshots lie one period minus the agent's
    # phase after it (to a batch, 0.5 s)
    expected = period_s * (snapshot_phase(a) - snapshot_phase(b))
    assert abs(expected) > 2.0
    assert abs((firsts[b] - firsts[a]) - expected) <= 0.5 + 1e-9, (firsts, expected)
