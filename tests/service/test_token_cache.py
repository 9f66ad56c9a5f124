"""The token cache: revocations through the API act at once, unknown secrets never pass, entries
expire (real server or real database, SQLite and PostgreSQL)."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterator

import pytest
from sqlalchemy import update
from sqlalchemy.orm import Session, sessionmaker
from tests.service.conftest import Live, new_agent, new_mission
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from hrtls.service.db import make_engine, migrate, session_factory, transaction
from hrtls.service.deps import Services
from hrtls.service.models import Token
from hrtls.service.security import issue, new_secret
from hrtls.service.settings import Settings
from hrtls.service.tokencache import TokenCache

API = "/api/v1"
LONG_TTL_S = 300.0


def services_of(live: Live) -> Services:
    services: Services = live.server.config.app.state.services  # type: ignore[attr-defined]
    return services


def revoke_in_database(live: Live, token_id: int) -> None:
    """Revoke as another process on the same database would (this process is not told)."""
    engine = make_engine(live.settings.db_url)
    try:
        with transaction(session_factory(engine)) as db:
            db.execute(update(Token).where(Token.id == token_id).values(revoked_at=1.0))
    finally:
        engine.dispose()


def socket_refused(live: Live, token: str, path: str) -> bool:
    """Whether the service closes a socket opened with ``token`` before its first message."""
    with connect(live.ws_url + path,
                 additional_headers={"Authorization": f"Bearer {token}"}) as ws:
        try:
            ws.recv(timeout=10)
        except ConnectionClosed as closed:
            return closed.rcvd is not None and closed.rcvd.code == 4401
    return False


def test_api_revocation_refused_on_the_next_request(make_live: Callable[..., Live]) -> None:
    live = make_live(token_cache_ttl_s=LONG_TTL_S)
    with live.client(live.commander) as commander:
        mid = new_mission(commander)["id"]
        agent = new_agent(commander, mid)
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
        with live.client(viewer["token"]) as v, live.client(agent["token"]) as a, \
                live.client() as browser:
            assert v.get(f"{API}/missions").status_code == 200
            assert a.post(f"{API}/ingest", json={"seq": 0, "status": {"battery": 0.5}}
                          ).status_code == 200
            assert browser.post(f"{API}/auth/login",
                                json={"token": viewer["token"]}).status_code == 200
            assert browser.get(f"{API}/auth/whoami").json()["token_id"] == viewer["id"]
            assert len(services_of(live).tokens) >= 4  # commander, viewer, agent, session

            assert commander.delete(f"{API}/tokens/{agent['token_id']}").status_code == 204
            r = a.post(f"{API}/ingest", json={"seq": 1, "status": {"battery": 0.5}})
            assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
            assert socket_refused(live, agent["token"], f"{API}/ingest/ws")
            r = a.post(f"{API}/ingest/sensorlogger", json={"messageId": 0, "payload": []})
            assert r.status_code == 401

            assert commander.delete(f"{API}/tokens/{viewer['id']}").status_code == 204
            assert v.get(f"{API}/missions").status_code == 401
            assert socket_refused(live, viewer["token"], f"{API}/missions/{mid}/ws")
            # the session opened with the viewer token ends with it
            assert browser.get(f"{API}/missions").status_code == 401
            assert browser.post(f"{API}/auth/login",
                                json={"token": viewer["token"]}).status_code == 401
        assert commander.get(f"{API}/missions").status_code == 200


def test_logout_refused_on_the_next_request(make_live: Callable[..., Live]) -> None:
    live = make_live(token_cache_ttl_s=LONG_TTL_S)
    with live.client(live.commander) as commander, live.client() as browser:
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
        assert browser.post(f"{API}/auth/login",
                            json={"token": viewer["token"]}).status_code == 200
        cookie = browser.cookies["hrtls_session"]
        assert browser.get(f"{API}/missions").status_code == 200
        assert browser.post(f"{API}/auth/logout").status_code == 204
        browser.cookies.set("hrtls_session", cookie)
        assert browser.get(f"{API}/missions").status_code == 401
        with live.client(viewer["token"]) as v:  # the token itself stays valid
            assert v.get(f"{API}/missions").status_code == 200


def test_unknown_secret_never_accepted(make_live: Callable[..., Live]) -> None:
    live = make_live(token_cache_ttl_s=LONG_TTL_S)
    with live.client(live.commander) as commander:
        for _ in range(3):
            assert commander.get(f"{API}/missions").status_code == 200
        stored = hashlib.sha256(live.commander.encode()).hexdigest()
        for secret in (new_secret(), live.commander[:-1], live.commander + "x", stored,
                       live.commander.upper()):
            with live.client(secret) as c:
                assert c.get(f"{API}/missions").status_code == 401, secret
                assert c.post(f"{API}/auth/login", json={"token": secret}).status_code == 401
            assert socket_refused(live, secret, f"{API}/missions/1/ws")


def test_out_of_band_revocation_seen_after_the_ttl(make_live: Callable[..., Live]) -> None:
    cached = make_live(token_cache_ttl_s=LONG_TTL_S)
    with cached.client(cached.commander) as commander:
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "v"}).json()
    with cached.client(viewer["token"]) as v:
        assert v.get(f"{API}/missions").status_code == 200
        revoke_in_database(cached, viewer["id"])
        assert v.get(f"{API}/missions").status_code == 200  # trusted until the TTL ends
    cached.stop()
    uncached = make_live(token_cache_ttl_s=0.0)
    with uncached.client(uncached.commander) as commander:
        viewer = commander.post(f"{API}/tokens", json={"role": "viewer", "label": "w"}).json()
    with uncached.client(viewer["token"]) as v:
        assert v.get(f"{API}/missions").status_code == 200
        revoke_in_database(uncached, viewer["id"])
        assert v.get(f"{API}/missions").status_code == 401
    assert len(services_of(uncached).tokens) == 0


# ---------------------------------------------------------------------- the cache on a database
@pytest.fixture
def sessions(db_url: str) -> Iterator[sessionmaker[Session]]:
    engine = make_engine(Settings(db=db_url).db_url)
    migrate(engine)
    try:
        yield session_factory(engine)
    finally:
        engine.dispose()


def new_token(sessions: sessionmaker[Session], *, now_unix: float, kind: str = "token",
              parent_id: int | None = None, expires_at: float | None = None) -> tuple[int, str]:
    with transaction(sessions) as db:
        row, secret = issue(db, role="viewer", label="t", now_unix=now_unix, kind=kind,
                            parent_id=parent_id, expires_at=expires_at)
        return row.id, secret


def revoke(sessions: sessionmaker[Session], token_id: int) -> None:
    with transaction(sessions) as db:
        db.execute(update(Token).where(Token.id == token_id).values(revoked_at=1.0))


def test_entries_expire_after_the_ttl(sessions: sessionmaker[Session]) -> None:
    t0 = 1000.0
    cache = TokenCache(ttl_s=5.0, max_entries=100)
    tid, secret = new_token(sessions, now_unix=t0)
    who = cache.principal(sessions, secret, now_unix=t0)
    assert who is not None and who.token_id == tid
    revoke(sessions, tid)
    assert cache.principal(sessions, secret, now_unix=t0 + 4.9) == who
    assert cache.principal(sessions, secret, now_unix=t0 + 5.0) is None
    assert len(cache) == 0


def test_entries_end_with_the_token_itself(sessions: sessionmaker[Session]) -> None:
    t0 = 1000.0
    cache = TokenCache(ttl_s=LONG_TTL_S, max_entries=100)
    parent, _ = new_token(sessions, now_unix=t0)
    sid, secret = new_token(sessions, now_unix=t0, kind="session", parent_id=parent,
                            expires_at=t0 + 2.0)
    who = cache.principal(sessions, secret, now_unix=t0)
    assert who is not None and who.token_id == sid and who.parent_id == parent
    assert cache.cached(secret, now_unix=t0 + 1.9) == who
    assert cache.cached(secret, now_unix=t0 + 2.0) is None
    assert cache.principal(sessions, secret, now_unix=t0 + 2.0) is None


def test_forget_drops_the_token_and_its_sessions(sessions: sessionmaker[Session]) -> None:
    t0 = 1000.0
    cache = TokenCache(ttl_s=LONG_TTL_S, max_entries=100)
    parent, parent_secret = new_token(sessions, now_unix=t0)
    _, session_secret = new_token(sessions, now_unix=t0, kind="session", parent_id=parent)
    _, other_secret = new_token(sessions, now_unix=t0)
    for secret in (parent_secret, session_secret, other_secret):
        assert cache.principal(sessions, secret, now_unix=t0) is not None
    revoke(sessions, parent)
    cache.forget(parent)
    assert cache.principal(sessions, parent_secret, now_unix=t0) is None
    assert cache.principal(sessions, session_secret, now_unix=t0) is None
    assert cache.cached(other_secret, now_unix=t0) is not None
    assert len(cache) == 1


def test_lookup_overtaken_by_a_revocation_is_not_kept(sessions: sessionmaker[Session]) -> None:
    t0 = 1000.0
    cache = TokenCache(ttl_s=LONG_TTL_S, max_entries=100)
    tid, secret = new_token(sessions, now_unix=t0)

    class Racing(Session):
        """Closes after the lookup read the row; then the API revokes the token."""

        def close(self) -> None:
            super().close()
            revoke(sessions, tid)
            cache.forget(tid)

    racing = sessionmaker(sessions.kw["bind"], class_=Racing)
    assert cache.principal(racing, secret, now_unix=t0) is not None  # read before the revoke
    assert len(cache) == 0
    assert cache.principal(sessions, secret, now_unix=t0) is None


def test_unknown_secrets_are_not_kept_and_size_is_bounded(
        sessions: sessionmaker[Session]) -> None:
    t0 = 1000.0
    cache = TokenCache(ttl_s=LONG_TTL_S, max_entries=2)
    known = [new_token(sessions, now_unix=t0)[1] for _ in range(3)]
    for secret in (new_secret(), "", "x" * 201):
        assert cache.principal(sessions, secret, now_unix=t0) is None
    assert len(cache) == 0
    for secret in known:
        assert cache.principal(sessions, secret, now_unix=t0) is not None
    assert len(cache) == 2
    assert cache.cached(known[0], now_unix=t0) is None       # least recently used went first
    assert cache.principal(sessions, known[0], now_unix=t0) is not None  # still valid
