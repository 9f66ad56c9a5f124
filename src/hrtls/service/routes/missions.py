"""Missions, floors, landmarks and the infrastructure view."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, Query, Request, Response
from sqlalchemy import select
from sqlalchemy.orm import Session, undefer

from hrtls.service import schemas
from hrtls.service.deps import Commander, DbDep, Reader, ServicesDep, mission_or_404
from hrtls.service.floor_image import IMAGE_TYPES, check_floor_image
from hrtls.service.landmark_versions import (
    VersionConflict,
    remove_landmark,
    versions_of,
    write_version,
)
from hrtls.service.mission_runner import network_nodes
from hrtls.service.models import Floor, LandmarkRow, Mission, OrderRow
from hrtls.service.views import floor_out, mission_out, mission_summaries

router = APIRouter(tags=["missions"])


@router.post("/missions", status_code=201, response_model=schemas.MissionOut)
def create_mission(body: schemas.MissionIn, who: Commander, db: DbDep,
                   services: ServicesDep) -> schemas.MissionOut:
    """A new mission; its clock (``t0_unix``) starts now."""
    now = services.clock()
    mission = Mission(name=body.name, status="active", t0_unix=now, created_at=now,
                      georeference=None if body.georeference is None
                      else body.georeference.model_dump(),
                      channel=None if body.channel is None else body.channel.model_dump(),
                      floor_height_m=body.floor_height_m, stale_after_s=body.stale_after_s,
                      alarm_profile=body.alarm_profile.model_dump())
    db.add(mission)
    db.flush()
    for f in body.floors:
        db.add(Floor(mission_id=mission.id, index=f.index, name=f.name, height_m=f.height_m,
                     plan=f.plan))
    db.commit()
    return mission_out(db, mission, now_unix=now)


@router.get("/missions", response_model=list[schemas.MissionSummaryOut])
def list_missions(who: Reader, db: DbDep) -> list[schemas.MissionSummaryOut]:
    """Every mission, oldest first."""
    return mission_summaries(db)


@router.get("/missions/{mission_id}", response_model=schemas.MissionOut)
def get_mission(mission_id: int, who: Reader, db: DbDep,
                services: ServicesDep) -> schemas.MissionOut:
    """One mission with its floors and plans."""
    return mission_out(db, mission_or_404(db, mission_id), now_unix=services.clock())


@router.patch("/missions/{mission_id}", response_model=schemas.MissionOut)
def patch_mission(mission_id: int, body: schemas.MissionPatch, who: Commander, db: DbDep,
                  services: ServicesDep) -> schemas.MissionOut:
    """Change the given fields of a mission."""
    mission = mission_or_404(db, mission_id)
    for name, value in body.model_dump(exclude_unset=True).items():
        if value is None and name not in ("georeference", "channel"):
            raise HTTPException(422, f"{name} may not be null")
        setattr(mission, name, value)
    db.commit()
    services.host.mission_changed(mission_id)
    return mission_out(db, mission, now_unix=services.clock())


@router.put("/missions/{mission_id}/floors/{index}", response_model=schemas.FloorOut)
def put_floor(mission_id: int, index: int, body: schemas.FloorIn, who: Commander,
              db: DbDep, services: ServicesDep) -> schemas.FloorOut:
    """Create or replace floor ``index``."""
    mission_or_404(db, mission_id)
    if not -20 <= index <= 300:
        raise HTTPException(422, f"floor index {index} outside -20..300")
    row = db.scalars(select(Floor).where(Floor.mission_id == mission_id,
                                         Floor.index == index)).first()
    if row is None:
        row = Floor(mission_id=mission_id, index=index)
        db.add(row)
    row.name, row.height_m, row.plan = body.name, body.height_m, body.plan
    db.commit()
    services.events.plans_changed(mission_id)
    return floor_out(row)


@router.delete("/missions/{mission_id}/floors/{index}", status_code=204)
def delete_floor(mission_id: int, index: int, who: Commander, db: DbDep,
                 services: ServicesDep) -> None:
    """Remove floor ``index``."""
    mission_or_404(db, mission_id)
    row = db.scalars(select(Floor).where(Floor.mission_id == mission_id,
                                         Floor.index == index)).first()
    if row is None:
        raise HTTPException(404, f"floor {index} not found in mission {mission_id}")
    db.delete(row)
    db.commit()
    services.events.plans_changed(mission_id)


def _floor_or_404(db: Session, mission_id: int, index: int, *, with_image: bool = False
                  ) -> Floor:
    mission_or_404(db, mission_id)
    query = select(Floor).where(Floor.mission_id == mission_id, Floor.index == index)
    if with_image:
        query = query.options(undefer(Floor.image))
    row = db.scalars(query).first()
    if row is None:
        raise HTTPException(404, f"floor {index} not found in mission {mission_id}")
    return row


@router.put("/missions/{mission_id}/floors/{index}/image", response_model=schemas.FloorOut,
            openapi_extra={"requestBody": {"required": True, "content": {
                t: {"schema": {"type": "string", "format": "binary"}} for t in IMAGE_TYPES}}})
async def put_floor_image(
        mission_id: int, index: int, request: Request, who: Commander, db: DbDep,
        origin_x_m: float = Query(ge=-1e5, le=1e5, description="x of the lower-left corner, m"),
        origin_y_m: float = Query(ge=-1e5, le=1e5, description="y of the lower-left corner, m"),
        m_per_px: float = Query(gt=0.0, le=100.0, description="metres per pixel")
) -> schemas.FloorOut:
    """Set the plan image of an existing floor (body: the PNG or JPEG bytes)."""
    media_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    data = await request.body()
    meta = check_floor_image(data, media_type)
    row = _floor_or_404(db, mission_id, index)
    row.image = data
    row.image_meta = {**meta, "origin_x_m": origin_x_m, "origin_y_m": origin_y_m,
                      "m_per_px": m_per_px}
    db.commit()
    return floor_out(row)


@router.get("/missions/{mission_id}/floors/{index}/image", response_class=Response,
            responses={200: {"content": {t: {} for t in IMAGE_TYPES}}})
def get_floor_image(mission_id: int, index: int, who: Reader, db: DbDep) -> Response:
    """The plan image of a floor (404 when it has none)."""
    row = _floor_or_404(db, mission_id, index, with_image=True)
    if row.image is None or row.image_meta is None:
        raise HTTPException(404, f"floor {index} of mission {mission_id} has no image")
    return Response(row.image, media_type=row.image_meta["media_type"],
                    headers={"Cache-Control": "private, max-age=60"})


@router.delete("/missions/{mission_id}/floors/{index}/image", status_code=204)
def delete_floor_image(mission_id: int, index: int, who: Commander, db: DbDep) -> None:
    """Remove the plan image of a floor."""
    row = _floor_or_404(db, mission_id, index)
    row.image, row.image_meta = None, None
    db.commit()


def landmarks_of(db: DbDep, mission_id: int) -> list[dict[str, Any]]:
    """The landmarks of a mission as JSON objects, by id."""
    rows = db.scalars(select(LandmarkRow).where(LandmarkRow.mission_id == mission_id)
                      .order_by(LandmarkRow.key))
    return [r.data for r in rows]


def _landmark_or_none(db: DbDep, mission_id: int, landmark_id: str) -> LandmarkRow | None:
    return db.scalars(select(LandmarkRow).where(LandmarkRow.mission_id == mission_id,
                                                LandmarkRow.key == landmark_id)).first()


def _write(db: DbDep, services: ServicesDep, mission: Mission,
           body: schemas.LandmarkIn) -> dict[str, Any]:
    """Store a version (:mod:`hrtls.service.landmark_versions`); trackers re-run from its time."""
    try:
        t = write_version(db, mission.id, body.model_dump(mode="json"),
                          now_t=services.clock() - mission.t0_unix)
    except VersionConflict as exc:
        raise HTTPException(409, str(exc)) from exc
    db.commit()
    services.host.landmarks_changed(mission.id, t)
    row = _landmark_or_none(db, mission.id, body.id)
    assert row is not None
    return row.data


@router.post("/missions/{mission_id}/landmarks", status_code=201)
def create_landmark(mission_id: int, body: schemas.LandmarkIn, who: Commander, db: DbDep,
                    services: ServicesDep) -> dict[str, Any]:
    """Add a landmark; 409 when its id exists."""
    mission = mission_or_404(db, mission_id)
    if _landmark_or_none(db, mission_id, body.id) is not None:
        raise HTTPException(409, f"landmark {body.id!r} exists in mission {mission_id} "
                                 "(PUT replaces it)")
    return _write(db, services, mission, body)


@router.get("/missions/{mission_id}/landmarks")
def list_landmarks(mission_id: int, who: Reader, db: DbDep) -> list[dict[str, Any]]:
    """The landmarks of a mission (each in its current version)."""
    mission_or_404(db, mission_id)
    return landmarks_of(db, mission_id)


@router.get("/missions/{mission_id}/landmark-versions")
def list_landmark_versions(mission_id: int, who: Reader, db: DbDep) -> list[dict[str, Any]]:
    """Every stored version: the start landmarks (``t`` null), then the later ones by time."""
    mission_or_404(db, mission_id)
    start, timed = versions_of(db, mission_id)
    return [{"t": None, "landmark": d} for d in start] \
        + [{"t": d["updated"], "landmark": d} for d in timed]


@router.put("/missions/{mission_id}/landmarks/{landmark_id}")
def put_landmark(mission_id: int, landmark_id: str, body: schemas.LandmarkIn, who: Commander,
                 db: DbDep, services: ServicesDep) -> dict[str, Any]:
    """Create or replace a landmark (the path id must equal the body id)."""
    mission = mission_or_404(db, mission_id)
    if body.id != landmark_id:
        raise HTTPException(422, f"body id {body.id!r} differs from the path id "
                                 f"{landmark_id!r}")
    return _write(db, services, mission, body)


@router.delete("/missions/{mission_id}/landmarks/{landmark_id}", status_code=204)
def delete_landmark(mission_id: int, landmark_id: str, who: Commander, db: DbDep,
                    services: ServicesDep) -> None:
    """Remove a landmark: from the start before any data, else destroyed from now on."""
    mission = mission_or_404(db, mission_id)
    row = _landmark_or_none(db, mission_id, landmark_id)
    if row is None:
        raise HTTPException(404, f"landmark {landmark_id!r} not found in mission {mission_id}")
    t = remove_landmark(db, row, now_t=services.clock() - mission.t0_unix)
    db.commit()
    services.host.landmarks_changed(mission_id, t)


@router.get("/missions/{mission_id}/infrastructure", response_model=schemas.InfrastructureOut)
def infrastructure(mission_id: int, who: Reader, db: DbDep) -> schemas.InfrastructureOut:
    """Landmarks, sensor nodes (the declared network's, live estimates) and go-to way points."""
    mission_or_404(db, mission_id)
    orders = db.scalars(select(OrderRow).where(
        OrderRow.mission_id == mission_id, OrderRow.kind == "goto",
        OrderRow.status.in_(("pending", "delivered", "accepted"))).order_by(OrderRow.id))
    waypoints = [schemas.WaypointOut(agent=o.agent_id, order=o.id, status=o.status,
                                     **(o.waypoint or {})) for o in orders if o.waypoint]
    nodes = [schemas.NodeOut(id=n["id"], position=n["position"], floor=n["floor"],
                             sigma_m=n["sigma_m"], seed=n["seed"], localized=n["localized"])
             for n in network_nodes(db, mission_id) or []]
    return schemas.InfrastructureOut(landmarks=landmarks_of(db, mission_id), nodes=nodes,
                                     waypoints=waypoints)
