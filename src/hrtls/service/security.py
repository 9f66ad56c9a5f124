"""Tokens and roles: random secrets stored as SHA-256 hashes, revocable, checked per request."""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from typing import Literal

from sqlalchemy import select
from sqlalchemy.orm import Session

from hrtls.service.models import Token

Role = Literal["commander", "viewer", "agent"]
ROLES: tuple[Role, ...] = ("commander", "viewer", "agent")
COOKIE_NAME = "hrtls_session"


def new_secret() -> str:
    """A fresh random secret (256 bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def digest(secret: str) -> str:
    """The stored form of a secret: hex SHA-256."""
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


@dataclass(frozen=True, slots=True)
class Principal:
    """Who makes a request: the token (or session) and what it may touch.

    ``parent_id`` is the token a session was opened with; ``expires_at`` the Unix time the
    token or session ends (None: until revoked).
    """

    token_id: int
    role: Role
    label: str
    mission_id: int | None
    agent_id: int | None
    is_session: bool
    parent_id: int | None = None
    expires_at: float | None = None


def issue(db: Session, *, role: Role, label: str, now_unix: float,
          mission_id: int | None = None, agent_id: int | None = None,
          kind: str = "token", parent_id: int | None = None,
          expires_at: float | None = None) -> tuple[Token, str]:
    """Store a new token (hashed) and return it with its secret (shown once)."""
    secret = new_secret()
    row = Token(secret_sha256=digest(secret), kind=kind, role=role, label=label,
                mission_id=mission_id, agent_id=agent_id, parent_id=parent_id,
                created_at=now_unix, expires_at=expires_at, revoked_at=None)
    db.add(row)
    db.flush()
    return row, secret


def lookup(db: Session, secret: str, *, now_unix: float) -> Principal | None:
    """The principal of a valid (known, not revoked, not expired) secret, else None."""
    if not secret or len(secret) > 200:
        return None
    row = db.scalars(select(Token).where(Token.secret_sha256 == digest(secret))).first()
    if row is None or row.revoked_at is not None:
        return None
    if row.expires_at is not None and row.expires_at <= now_unix:
        return None
    if row.kind == "session" and row.parent_id is not None:
        parent = db.get(Token, row.parent_id)
        if parent is None or parent.revoked_at is not None:
            return None
    role: Role = row.role  # type: ignore[assignment]
    return Principal(row.id, role, row.label, row.mission_id, row.agent_id,
                     row.kind == "session", parent_id=row.parent_id, expires_at=row.expires_at)


def has_commander(db: Session) -> bool:
    """Whether any unrevoked commander token exists."""
    return db.scalars(select(Token.id).where(Token.role == "commander", Token.kind == "token",
                                             Token.revoked_at.is_(None))).first() is not None
