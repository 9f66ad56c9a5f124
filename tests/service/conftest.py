"""Service tests run against a real server on loopback, once on SQLite and once on PostgreSQL.

PostgreSQL comes from ``.ci/postgres.sh`` (URL in ``HRTLS_TEST_PG``, default the script's). When
it is unreachable the PostgreSQL half skips, except under ``CI=true`` where it fails.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
from sqlalchemy import create_engine, text

from hrtls.service.app import bootstrap, create_app
from hrtls.service.settings import Settings

PG_URL = os.environ.get("HRTLS_TEST_PG", "postgresql://hrtls:hrtls@127.0.0.1:5432/hrtls_test")


def _reset_postgres(url: str) -> None:
    engine = create_engine("postgresql+psycopg://" + url.split("://", 1)[1])
    try:
        with engine.begin() as c:
            c.execute(text("DROP SCHEMA public CASCADE"))
            c.execute(text("CREATE SCHEMA public"))
    finally:
        engine.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A fresh, empty database of each backend."""
    if request.param == "sqlite":
        return str(tmp_path / "service.db")
    try:
        _reset_postgres(PG_URL)
    except Exception as exc:
        message = f"PostgreSQL at {PG_URL} unreachable ({type(exc).__name__}); run .ci/postgres.sh"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(message)
        pytest.skip(message)
    return PG_URL


@dataclass
class Live:
    """A running service on loopback."""

    url: str
    settings: Settings
    commander: str
    server: uvicorn.Server
    thread: threading.Thread

    def client(self, token: str | None = None, **kwargs: Any) -> httpx.Client:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.Client(base_url=self.url, headers=headers, timeout=30.0, **kwargs)

    @property
    def ws_url(self) -> str:
        return "ws" + self.url[len("http"):]

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=30)


def start_live(settings: Settings) -> Live:
    """Bootstrap the database and run a service in a thread until stopped."""
    secret = bootstrap(settings, new_commander=True)
    assert secret is not None
    app = create_app(settings)
    config = uvicorn.Config(app, host="127.0.0.1", port=0, log_level="warning",
                            ws_max_size=settings.max_body_bytes, lifespan="on")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("service did not start")
        time.sleep(0.02)
    port = server.servers[0].sockets[0].getsockname()[1]
    return Live(f"http://127.0.0.1:{port}", settings, secret, server, thread)


@pytest.fixture
def make_live(db_url: str) -> Iterator[Callable[..., Live]]:
    """Start services on the test's database with settings overrides; stopped afterwards."""
    started: list[Live] = []

    def make(**overrides: Any) -> Live:
        live = start_live(Settings(db=db_url, **overrides))
        started.append(live)
        return live

    yield make
    for live in started:
        live.stop()


@pytest.fixture
def live(make_live: Callable[..., Live]) -> Live:
    """A service with default settings."""
    return make_live()


@pytest.fixture
def commander(live: Live) -> Iterator[httpx.Client]:
    with live.client(live.commander) as c:
        yield c


def new_mission(client: httpx.Client, **body: Any) -> dict[str, Any]:
    response = client.post("/api/v1/missions", json={"name": "test mission", **body})
    assert response.status_code == 201, response.text
    return dict(response.json())


def new_agent(client: httpx.Client, mission: int, **body: Any) -> dict[str, Any]:
    response = client.post(f"/api/v1/missions/{mission}/agents",
                           json={"name": "Rescuer A", **body})
    assert response.status_code == 201, response.text
    return dict(response.json())
