"""Engine, sessions and migrations: SQLite in WAL mode or PostgreSQL through psycopg."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.orm import Session, sessionmaker

from hrtls.errors import InputError

POOL_SIZE = 48
"""Connections kept open: at least the request thread pool (40 threads) plus the tracker and
publisher threads, so that a busy service reuses connections instead of opening new ones."""


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite files get WAL mode, foreign keys and a busy timeout."""
    if url.startswith("sqlite"):
        if url in ("sqlite://", "sqlite:///:memory:"):
            raise InputError(url, where="--db",
                             expected="a database file path (an in-memory SQLite database "
                                      "is lost when the service stops)")
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30},
                               pool_size=POOL_SIZE, max_overflow=16)

        @event.listens_for(engine, "connect")
        def _pragmas(dbapi_connection: Any, _record: Any) -> None:
            cur = dbapi_connection.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=NORMAL")  # WAL: durable against process crashes
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute("PRAGMA busy_timeout=30000")
            cur.close()

        return engine
    if url.startswith("postgresql"):
        return create_engine(url, pool_size=POOL_SIZE, max_overflow=16, pool_pre_ping=True)
    raise InputError(url, where="--db",
                     expected="a SQLite file path or postgresql://user:pass@host/dbname")


def migrate(engine: Engine) -> None:
    """Bring the schema to the newest revision (Alembic, idempotent)."""
    cfg = Config()
    cfg.set_main_option("script_location", "hrtls.service:migrations")
    with engine.begin() as connection:
        cfg.attributes["connection"] = connection
        command.upgrade(cfg, "head")


def session_factory(engine: Engine) -> sessionmaker[Session]:
    """Sessions that keep loaded objects usable after commit."""
    return sessionmaker(engine, expire_on_commit=False)


@contextmanager
def transaction(factory: sessionmaker[Session]) -> Iterator[Session]:
    """A session committed on success and rolled back on error."""
    with factory() as db, db.begin():
        yield db
