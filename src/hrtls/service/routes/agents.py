"""Agents of a mission: create (with an ingest token), read, update, check in."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException
from sqlalchemy import select

from hrtls.pipeline import PRESETS
from hrtls.service import schemas
from hrtls.service.alarms import Raised
from hrtls.service.deps import (
    AnyCaller,
    Commander,
    CommanderOrAgent,
    DbDep,
    Reader,
    ServicesDep,
    agent_or_404,
    mission_or_404,
    own_agent_or_reader,
)
from hrtls.service.models import Agent
from hrtls.service.picture import agent_json
from hrtls.service.security import issue
from hrtls.service.views import agent_out, token_out

router = APIRouter(tags=["agents"])

EMPTY_STATUS: dict[str, Any] = {"last_data_t": None, "last_seq": None, "acked_through": None,
                                "missing": [], "battery": None, "connected": False}


def _check_preset(name: str) -> None:
    if name not in PRESETS:
        raise HTTPException(400, f"preset {name!r} unknown; one of {', '.join(sorted(PRESETS))}")


@router.post("/missions/{mission_id}/agents", status_code=201,
             response_model=schemas.NewAgentOut)
def create_agent(mission_id: int, body: schemas.AgentIn, who: Commander, db: DbDep,
                 services: ServicesDep) -> schemas.NewAgentOut:
    """A new agent and its first ingest token."""
    mission_or_404(db, mission_id)
    _check_preset(body.preset)
    now = services.clock()
    agent = Agent(mission_id=mission_id, name=body.name, kind=body.kind, preset=body.preset,
                  placement=body.placement, device=dict(body.device),
                  mounting_q_bd=None if body.mounting_q_bd is None else list(body.mounting_q_bd),
                  user=body.user.model_dump(), created_at=now, status=dict(EMPTY_STATUS),
                  start_pose=None if body.start_pose is None else body.start_pose.model_dump())
    db.add(agent)
    db.flush()
    token, secret = issue(db, role="agent", label=f"agent {agent.id} {body.name}",
                          now_unix=now, mission_id=mission_id, agent_id=agent.id)
    db.commit()
    return schemas.NewAgentOut(agent=agent_out(agent), token=secret, token_id=token.id)


@router.get("/missions/{mission_id}/agents", response_model=list[schemas.AgentOut])
def list_agents(mission_id: int, who: Reader, db: DbDep,
                services: ServicesDep) -> list[dict[str, Any]]:
    """The agents of a mission with their live status."""
    mission_or_404(db, mission_id)
    rows = db.scalars(select(Agent).where(Agent.mission_id == mission_id).order_by(Agent.id))
    return [agent_json(a, services.host, services.clock()) for a in rows]


@router.get("/missions/{mission_id}/agents/{agent_id}", response_model=schemas.AgentOut)
def get_agent(mission_id: int, agent_id: int, who: AnyCaller, db: DbDep,
              services: ServicesDep) -> dict[str, Any]:
    """One agent with its live status (an agent token: only its own)."""
    own_agent_or_reader(who, mission_id, agent_id)
    return agent_json(agent_or_404(db, mission_id, agent_id), services.host, services.clock())


@router.patch("/missions/{mission_id}/agents/{agent_id}", response_model=schemas.AgentOut)
def patch_agent(mission_id: int, agent_id: int, body: schemas.AgentPatch, who: Commander,
                db: DbDep) -> schemas.AgentOut:
    """Change the given fields of an agent."""
    agent = agent_or_404(db, mission_id, agent_id)
    changes = body.model_dump(exclude_unset=True)
    for name, value in changes.items():
        if value is None and name not in ("placement", "mounting_q_bd"):
            raise HTTPException(422, f"{name} may not be null")
        if name == "preset":
            _check_preset(value)
        setattr(agent, name, value)
    db.commit()
    return agent_out(agent)


@router.post("/missions/{mission_id}/agents/{agent_id}/checkin",
             response_model=schemas.AgentOut)
def checkin(mission_id: int, agent_id: int, body: schemas.StartPoseIn,
            who: CommanderOrAgent, db: DbDep, services: ServicesDep) -> schemas.AgentOut:
    """Set the agent's known start pose (mission time); the tracker starts from it."""
    own_agent_or_reader(who, mission_id, agent_id)
    agent = agent_or_404(db, mission_id, agent_id)
    if agent.start_pose is not None:
        raise HTTPException(409, f"agent {agent_id} has checked in already")
    mission = mission_or_404(db, mission_id)
    agent.start_pose = body.model_dump()
    db.commit()
    db.close()   # the host and the event log use connections of their own: never hold two
    services.host.checked_in(agent_id)
    t = body.t if body.t is not None else services.clock() - mission.t0_unix
    services.events.emit(mission_id, agent_id, [Raised("checkin", "info", t, {})],
                         {"x": body.x, "y": body.y,
                          "floor": round(body.z / mission.floor_height_m)})
    return agent_out(agent)


@router.post("/missions/{mission_id}/agents/{agent_id}/tokens", status_code=201,
             response_model=schemas.NewTokenOut)
def new_agent_token(mission_id: int, agent_id: int, who: Commander, db: DbDep,
                    services: ServicesDep) -> schemas.NewTokenOut:
    """Another ingest token for the agent."""
    agent = agent_or_404(db, mission_id, agent_id)
    row, secret = issue(db, role="agent", label=f"agent {agent.id} {agent.name}",
                        now_unix=services.clock(), mission_id=mission_id, agent_id=agent.id)
    db.commit()
    return schemas.NewTokenOut(**token_out(row).model_dump(), token=secret)
