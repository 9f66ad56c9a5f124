"""Login, logout, whoami and commander/viewer tokens."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request, Response
from sqlalchemy import select

from hrtls.service import schemas
from hrtls.service.deps import AnyCaller, Commander, DbDep, ServicesDep
from hrtls.service.models import Token
from hrtls.service.security import COOKIE_NAME, digest, issue
from hrtls.service.views import token_out

router = APIRouter(tags=["auth"])


def _whoami(token_id: int, role: str, label: str, mission: int | None,
            agent: int | None) -> schemas.WhoamiOut:
    return schemas.WhoamiOut(role=role, token_id=token_id, label=label, mission=mission,
                             agent=agent)


@router.post("/auth/login", response_model=schemas.WhoamiOut)
def login(body: schemas.LoginIn, response: Response, db: DbDep,
          services: ServicesDep) -> schemas.WhoamiOut:
    """Exchange a commander/viewer token for a browser session cookie."""
    now = services.clock()
    who = services.tokens.principal(services.sessions, body.token, now_unix=now)
    if who is None:
        raise HTTPException(401, "token unknown, revoked or expired",
                            headers={"WWW-Authenticate": "Bearer"})
    if who.role == "agent" or who.is_session:
        raise HTTPException(403, "only commander and viewer tokens can open a browser session")
    hours = services.settings.session_hours
    _, secret = issue(db, role=who.role, label=who.label, now_unix=now, kind="session",
                      parent_id=who.token_id, expires_at=now + hours * 3600.0)
    db.commit()
    response.set_cookie(COOKIE_NAME, secret, max_age=int(hours * 3600), httponly=True,
                        samesite="strict", secure=services.settings.tls, path="/")
    return _whoami(who.token_id, who.role, who.label, None, None)


@router.post("/auth/logout", status_code=204)
def logout(request: Request, response: Response, db: DbDep, services: ServicesDep) -> None:
    """End the browser session (revoke its cookie)."""
    secret = request.cookies.get(COOKIE_NAME)
    if secret:
        row = db.scalars(select(Token).where(Token.secret_sha256 == digest(secret),
                                             Token.kind == "session")).first()
        if row is not None and row.revoked_at is None:
            row.revoked_at = services.clock()
            db.commit()
        if row is not None:
            services.tokens.forget(row.id)
    response.delete_cookie(COOKIE_NAME, path="/", httponly=True, samesite="strict",
                           secure=services.settings.tls)


@router.get("/auth/whoami", response_model=schemas.WhoamiOut)
def whoami(who: AnyCaller, services: ServicesDep) -> schemas.WhoamiOut:
    """The caller (for a session: the token it was opened with; for an agent: mission time)."""
    token_id = who.parent_id if who.is_session and who.parent_id is not None else who.token_id
    out = _whoami(token_id, who.role, who.label, who.mission_id, who.agent_id)
    if who.mission_id is not None:
        out.mission_t = services.mission_time(who.mission_id)
    return out


@router.post("/tokens", status_code=201, response_model=schemas.NewTokenOut)
def create_token(body: schemas.TokenIn, who: Commander, db: DbDep,
                 services: ServicesDep) -> schemas.NewTokenOut:
    """A new commander or viewer token (its secret is shown once)."""
    row, secret = issue(db, role=body.role, label=body.label, now_unix=services.clock())
    db.commit()
    return schemas.NewTokenOut(**token_out(row).model_dump(), token=secret)


@router.get("/tokens", response_model=list[schemas.TokenOut])
def list_tokens(who: Commander, db: DbDep) -> list[schemas.TokenOut]:
    """Every token (no secrets), sessions excluded."""
    rows = db.scalars(select(Token).where(Token.kind == "token").order_by(Token.id))
    return [token_out(r) for r in rows]


@router.delete("/tokens/{token_id}", status_code=204)
def revoke_token(token_id: int, who: Commander, db: DbDep, services: ServicesDep) -> None:
    """Revoke a token; its sessions end with it."""
    row = db.get(Token, token_id)
    if row is None or row.kind != "token":
        raise HTTPException(404, f"token {token_id} not found")
    if row.revoked_at is None:
        row.revoked_at = services.clock()
        db.commit()
    services.tokens.forget(token_id)
