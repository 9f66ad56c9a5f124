"""Rows -> response bodies (one place for each shape of the contract)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from hrtls.service import schemas
from hrtls.service.models import Agent, Floor, Mission, Token


def token_out(row: Token) -> schemas.TokenOut:
    """A token without its secret."""
    return schemas.TokenOut(id=row.id, role=row.role, label=row.label,
                            created_at=row.created_at, revoked_at=row.revoked_at,
                            mission=row.mission_id, agent=row.agent_id)


def floors_of(db: Session, mission_id: int) -> list[Floor]:
    """The floors of a mission by index."""
    return list(db.scalars(select(Floor).where(Floor.mission_id == mission_id)
                           .order_by(Floor.index)))


def floor_out(row: Floor) -> schemas.FloorOut:
    """A floor (its image as where it lies and the URL of its bytes)."""
    url = f"{schemas.API_PREFIX}/missions/{row.mission_id}/floors/{row.index}/image"
    image = None if row.image_meta is None else schemas.FloorImageOut(**row.image_meta, url=url)
    return schemas.FloorOut(index=row.index, name=row.name, height_m=row.height_m,
                            plan=row.plan, image=image)


def mission_out(db: Session, row: Mission, *, now_unix: float) -> schemas.MissionOut:
    """A mission with its floors and the current mission time."""
    return schemas.MissionOut(
        id=row.id, name=row.name, status=row.status, t0_unix=row.t0_unix,
        now_t=now_unix - row.t0_unix, created_at=row.created_at,
        georeference=row.georeference, channel=row.channel, floor_height_m=row.floor_height_m,
        stale_after_s=row.stale_after_s, alarm_profile=row.alarm_profile,
        floors=[floor_out(f) for f in floors_of(db, row.id)])


def mission_summaries(db: Session) -> list[schemas.MissionSummaryOut]:
    """Every mission with its agent count, oldest first."""
    counts = {mid: int(n) for mid, n in db.execute(
        select(Agent.mission_id, func.count(Agent.id)).group_by(Agent.mission_id))}
    return [schemas.MissionSummaryOut(id=m.id, name=m.name, status=m.status,
                                      t0_unix=m.t0_unix, created_at=m.created_at,
                                      n_agents=counts.get(m.id, 0))
            for m in db.scalars(select(Mission).order_by(Mission.id))]


def agent_out(row: Agent) -> schemas.AgentOut:
    """An agent with its status."""
    return schemas.AgentOut(id=row.id, mission=row.mission_id, name=row.name, kind=row.kind,
                            preset=row.preset, placement=row.placement,
                            mounting_q_bd=row.mounting_q_bd, device=row.device,
                            user=row.user, start_pose=row.start_pose,
                            checked_in=row.start_pose is not None, created_at=row.created_at,
                            status=row.status)
