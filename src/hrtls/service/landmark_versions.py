"""Landmark versions in the service: which version of a landmark holds from which mission time.

A landmark written before any agent of the mission has sent data belongs to the mission's start
(version time None). A landmark written later (POST, PUT, or DELETE, which writes a ``destroyed``
version) holds for readings from its ``updated`` time (mission s) when the body gives one,
otherwise from the mission time at which the server received it; the stored version carries that
time in ``updated``. The agents' trackers take the start landmarks and queue the timed versions
(:meth:`hrtls.pipeline.Tracker.update_landmarks`), and the tracker host re-runs each running
tracker from the version's time (:meth:`hrtls.service.host.TrackerHost.landmarks_changed`), so
a live mission ends as the same mission tracked offline with the same versions.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import delete, select
from sqlalchemy.orm import Session as DbSession

from hrtls.service.models import Agent, LandmarkRow, LandmarkVersionRow, RawBatch


class VersionConflict(ValueError):
    """The landmark already has a version at that time (answer 409)."""


def mission_has_data(db: DbSession, mission_id: int) -> bool:
    """Whether any agent of the mission has sent timed data."""
    q = select(RawBatch.id).join(Agent, Agent.id == RawBatch.agent_id).where(
        Agent.mission_id == mission_id, RawBatch.t_first.is_not(None)).limit(1)
    return db.scalars(q).first() is not None


def write_version(db: DbSession, mission_id: int, data: dict[str, Any], *,
                  now_t: float) -> float | None:
    """Store ``data`` (Landmark JSON) as the landmark's current version and in its history.

    Returns the time the version holds from (None: the mission's start). Does not commit.
    """
    key = str(data["id"])
    t = data.get("updated")
    if t is None and mission_has_data(db, mission_id):
        t = now_t
    current = db.scalars(select(LandmarkRow).where(LandmarkRow.mission_id == mission_id,
                                                   LandmarkRow.key == key)).first()
    if t is None:
        db.execute(delete(LandmarkVersionRow).where(LandmarkVersionRow.mission_id == mission_id,
                                                    LandmarkVersionRow.key == key,
                                                    LandmarkVersionRow.t.is_(None)))
    else:
        t = float(t)
        clash = db.scalars(select(LandmarkVersionRow.id).where(
            LandmarkVersionRow.mission_id == mission_id, LandmarkVersionRow.key == key,
            LandmarkVersionRow.t == t)).first()
        if clash is not None:
            raise VersionConflict(f"landmark {key!r} already has a version at {t} s "
                                  "(give another 'updated')")
        data = {**data, "updated": t}
    db.add(LandmarkVersionRow(mission_id=mission_id, key=key, t=t, data=data))
    if current is None:
        db.add(LandmarkRow(mission_id=mission_id, key=key, data=data))
    else:
        current.data = data
    return t


def remove_landmark(db: DbSession, current: LandmarkRow, *, now_t: float) -> float | None:
    """Remove a landmark (DELETE): gone from the start before any data, else destroyed now.

    Returns the time of the destroyed version (None: removed from the start). Does not commit.
    """
    mission_id, key = current.mission_id, current.key
    db.delete(current)
    if not mission_has_data(db, mission_id):
        db.execute(delete(LandmarkVersionRow).where(LandmarkVersionRow.mission_id == mission_id,
                                                    LandmarkVersionRow.key == key))
        return None
    db.add(LandmarkVersionRow(mission_id=mission_id, key=key, t=now_t,
                              data={**current.data, "status": "destroyed", "updated": now_t}))
    return now_t


def versions_of(db: DbSession, mission_id: int) -> tuple[tuple[dict[str, Any], ...],
                                                         tuple[dict[str, Any], ...]]:
    """The mission's start landmarks and its timed versions in time order (Landmark JSON)."""
    rows = db.scalars(select(LandmarkVersionRow).where(LandmarkVersionRow.mission_id
                                                       == mission_id)
                      .order_by(LandmarkVersionRow.t, LandmarkVersionRow.id)).all()
    start = tuple(r.data for r in rows if r.t is None)
    timed = tuple(r.data for r in rows if r.t is not None)
    return start, timed
