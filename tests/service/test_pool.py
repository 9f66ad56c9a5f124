"""Database connections per request: a route never holds two at once (so a burst of requests
cannot exhaust the pool with threads that each wait for a second connection)."""

from __future__ import annotations

import threading
from collections import Counter
from typing import Any

import httpx
from sqlalchemy import event
from tests.service.conftest import Live, new_agent, new_mission


def test_checkin_holds_one_connection_at_a_time(live: Live, commander: httpx.Client) -> None:
    mission = new_mission(commander)["id"]
    agent = new_agent(commander, mission)["agent"]["id"]
    services = live.server.config.app.state.services
    held: Counter[int] = Counter()
    most: Counter[int] = Counter()
    lock = threading.Lock()

    def checkout(*_: Any) -> None:
        with lock:
            me = threading.get_ident()
            held[me] += 1
            most[me] = max(most[me], held[me])

    def checkin(*_: Any) -> None:
        with lock:
            held[threading.get_ident()] -= 1

    pool = services.engine.pool
    event.listen(pool, "checkout", checkout)
    event.listen(pool, "checkin", checkin)
    try:
        r = commander.post(f"/api/v1/missions/{mission}/agents/{agent}/checkin",
                           json={"x": 1.0, "y": 2.0, "z": 0.0})
        assert r.status_code == 200, r.text
    finally:
        event.remove(pool, "checkout", checkout)
        event.remove(pool, "checkin", checkin)
    assert most and max(most.values()) == 1, dict(most)
