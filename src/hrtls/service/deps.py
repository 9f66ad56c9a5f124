"""Dependency injection of the routes: the service context, DB sessions and the caller."""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from typing import Annotated, Any

from fastapi import Depends, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from sqlalchemy import Engine, select
from sqlalchemy.orm import Session, sessionmaker

from hrtls.service.clock import Clock
from hrtls.service.events import EventLog
from hrtls.service.host import TrackerHost
from hrtls.service.hub import KINDS, Hub
from hrtls.service.limits import RateLimiter
from hrtls.service.mission_runner import MissionRunner, network_nodes
from hrtls.service.models import Agent, Mission
from hrtls.service.security import COOKIE_NAME, Principal, Role
from hrtls.service.settings import Settings
from hrtls.service.tokencache import TokenCache


@dataclass
class Services:
    """Everything the routes share, built once by :func:`hrtls.service.app.create_app`."""

    settings: Settings
    engine: Engine
    sessions: sessionmaker[Session]
    clock: Clock
    agent_rate: RateLimiter
    host: TrackerHost
    hub: Hub
    events: EventLog
    tokens: TokenCache
    missions: MissionRunner
    order_versions: dict[int, int] = field(default_factory=dict)
    _t0: dict[int, float] = field(default_factory=dict)

    def mission_t0(self, mission_id: int) -> float:
        """Unix time of the mission's t = 0, s."""
        if mission_id not in self._t0:
            with self.sessions() as db:
                mission = db.get(Mission, mission_id)
                self._t0[mission_id] = 0.0 if mission is None else mission.t0_unix
        return self._t0[mission_id]

    async def authenticate(self, secret: str) -> Principal | None:
        """The principal of a valid secret; the database is read only on a cache miss."""
        now = self.clock()
        who = self.tokens.cached(secret, now_unix=now)
        if who is None:
            who = await run_in_threadpool(self.tokens.principal, self.sessions, secret,
                                          now_unix=now)
        return who

    def mission_time(self, mission_id: int) -> float:
        """Mission time now, s."""
        return self.clock() - self.mission_t0(mission_id)

    def picture(self, db: Session, mission: Mission, *, t: float | None, floor: int | None,
                trail_s: float) -> dict[str, Any]:
        """Live snapshot (``t`` None) or replay at ``t``."""
        from hrtls.service.picture import picture

        out = picture(db, mission, host=self.host, now_unix=self.clock(), t=t, floor=floor,
                      trail_s=trail_s)
        nodes = network_nodes(db, mission.id)
        if nodes is not None:
            out["nodes"] = nodes
        return out

    def publish_once(self) -> list[tuple[int, dict[str, Any]]]:
        """The deltas of every mission with changes since the last call (worker thread)."""
        from hrtls.service.picture import agent_json

        now = self.clock()
        per: dict[int, dict[str, dict[Any, dict[str, Any]]]] = {}

        def slot(mission_id: int) -> dict[str, dict[Any, dict[str, Any]]]:
            return per.setdefault(mission_id, {k: {} for k in KINDS})

        changed: dict[int, int] = {}
        for live, est in self.host.take_changes():
            if self.hub.subscribers(live.mission_id) == 0:
                continue
            changed[live.agent_id] = live.mission_id
            if est is not None:
                slot(live.mission_id)["estimates"][live.agent_id] = est
        if changed:
            with self.sessions() as db:
                for row in db.scalars(select(Agent).where(Agent.id.in_(list(changed)))):
                    slot(row.mission_id)["agents"][row.id] = agent_json(row, self.host, now)
        for mission_id, kinds in self.hub.take().items():
            for kind, items in kinds.items():
                for item in items:
                    key = item.get("agent") if kind == "estimates" else item.get("id")
                    slot(mission_id)[kind][key] = item
        return [(m, {"type": "delta", "t": self.mission_time(m),
                     **{k: list(v.values()) for k, v in kinds.items()}})
                for m, kinds in per.items()]


async def get_services(request: Request) -> Services:
    """The service context of the application handling ``request``."""
    services: Services = request.app.state.services
    return services


def get_db(services: Annotated[Services, Depends(get_services)]) -> Iterator[Session]:
    """A database session for one request (the route commits)."""
    with services.sessions() as db:
        yield db


ServicesDep = Annotated[Services, Depends(get_services)]
DbDep = Annotated[Session, Depends(get_db)]

UNAUTHORIZED = {"WWW-Authenticate": "Bearer"}


def bearer_secret(authorization: str | None) -> str | None:
    """The secret of an ``Authorization: Bearer ...`` header value."""
    if not authorization:
        return None
    scheme, _, value = authorization.partition(" ")
    return value.strip() if scheme.lower() == "bearer" and value.strip() else None


async def caller(request: Request, services: ServicesDep) -> Principal:
    """The principal of the request's bearer token or session cookie; 401 without one."""
    header = request.headers.get("authorization")
    secret = bearer_secret(header)
    if header and secret is None:
        raise HTTPException(401, "Authorization header must be 'Bearer <token>'",
                            headers=UNAUTHORIZED)
    if secret is None:
        secret = request.cookies.get(COOKIE_NAME)
    if secret is None:
        raise HTTPException(401, "no token: send 'Authorization: Bearer <token>' or log in",
                            headers=UNAUTHORIZED)
    principal = await services.authenticate(secret)
    if principal is None:
        raise HTTPException(401, "token unknown, revoked or expired", headers=UNAUTHORIZED)
    return principal


CallerDep = Annotated[Principal, Depends(caller)]


def require(*roles: Role) -> Callable[[Principal], Awaitable[Principal]]:
    """A dependency admitting only callers with one of ``roles`` (403 for others)."""

    async def check(who: CallerDep) -> Principal:
        if who.role not in roles:
            raise HTTPException(403, f"role {who.role!r} may not do this (needs "
                                     f"{' or '.join(roles)})")
        return who

    return check


Commander = Annotated[Principal, Depends(require("commander"))]
Reader = Annotated[Principal, Depends(require("commander", "viewer"))]
CommanderOrAgent = Annotated[Principal, Depends(require("commander", "agent"))]
AgentCaller = Annotated[Principal, Depends(require("agent"))]
AnyCaller = CallerDep


def mission_or_404(db: Session, mission_id: int) -> Mission:
    """The mission ``mission_id`` or 404."""
    mission = db.get(Mission, mission_id)
    if mission is None:
        raise HTTPException(404, f"mission {mission_id} not found")
    return mission


def agent_or_404(db: Session, mission_id: int, agent_id: int) -> Agent:
    """The agent ``agent_id`` of mission ``mission_id`` or 404."""
    agent = db.get(Agent, agent_id)
    if agent is None or agent.mission_id != mission_id:
        raise HTTPException(404, f"agent {agent_id} not found in mission {mission_id}")
    return agent


def own_agent_or_reader(who: Principal, mission_id: int, agent_id: int) -> None:
    """Commanders and viewers pass; an agent only for its own agent record (else 403)."""
    if who.role == "agent" and (who.agent_id != agent_id or who.mission_id != mission_id):
        raise HTTPException(403, "an agent token may only access its own agent")
