"""An agent's raw log back to a session (the inverse of streaming), and its stored estimates."""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session as DbSession

from hrtls.data import Landmark, Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, SensorSeries
from hrtls.data.session import SessionMeta
from hrtls.service.host import DECODERS
from hrtls.service.landmark_versions import versions_of
from hrtls.service.models import Agent, EstimateRow, Mission, RawBatch


def _cat(parts: list[Any], name: str) -> np.ndarray:
    return np.concatenate([np.asarray(getattr(p, name), dtype=object if name in
                                      ("anchor", "tag", "node") else np.float64)
                           for p in parts])


def agent_session(db: DbSession, mission: Mission, agent: Agent) -> Session | None:
    """Every stored batch of ``agent`` in time order as one session (None without data)."""
    rows = db.execute(select(RawBatch.source, RawBatch.content_type, RawBatch.body)
                      .where(RawBatch.agent_id == agent.id, RawBatch.t_first.is_not(None))
                      .order_by(RawBatch.t_first, RawBatch.seq)).all()
    batches = [DECODERS[r.source](r.body, r.content_type) for r in rows]
    if not batches:
        return None
    parts: dict[str, Any] = {}
    imus = [b.imu for b in batches if b.imu is not None]
    if imus:
        t = _cat(imus, "t")
        acc = SensorSeries(t, np.concatenate([np.asarray(i.acc) for i in imus]), "accelerometer")
        gyr = None if any(i.gyr is None for i in imus) else SensorSeries(
            t, np.concatenate([np.asarray(i.gyr) for i in imus]), "gyroscope")
        mag = None if any(i.mag is None for i in imus) else SensorSeries(
            t, np.concatenate([np.asarray(i.mag) for i in imus]), "magnetometer")
        parts["imu"] = ImuStream(acc, gyr, mag, check_units=False)
    baro = [b.baro for b in batches if b.baro is not None]
    if baro:
        parts["pressure"] = SensorSeries(_cat(baro, "t"), _cat(baro, "p_pa")[:, None],
                                         "pressure")
    rss = [b.rss for b in batches if b.rss is not None]
    if rss:
        parts["rss"] = RssReadings(_cat(rss, "t"), _cat(rss, "anchor").astype(str),
                                   _cat(rss, "rss_dbm"))
    tags = [b.tags for b in batches if b.tags is not None]
    if tags:
        parts["tags"] = TagDetections(_cat(tags, "t"), _cat(tags, "tag").astype(str))
    ranges = [b.ranges for b in batches if b.ranges is not None]
    if ranges:
        sigma = _cat(ranges, "sigma_m")
        parts["ranges"] = RangeMeasurements(_cat(ranges, "t"), _cat(ranges, "node").astype(str),
                                            _cat(ranges, "range_m"), sigma)
    fixes = [b.fixes for b in batches if b.fixes is not None]
    odo = [b.odometry for b in batches if b.odometry is not None]
    if fixes:
        has_z = all(f.z is not None for f in fixes)
        z = np.concatenate([np.asarray(f.z if f.z is not None else [0.0] * len(f.t))
                            for f in fixes])
        parts["fixes"] = PositionFixes(_cat(fixes, "t"), np.column_stack(
            [_cat(fixes, "x"), _cat(fixes, "y"), z]), _cat(fixes, "sigma_m"), has_z=has_z)
    elif odo:
        t = _cat(odo, "t")
        parts["fixes"] = PositionFixes(t, np.column_stack([_cat(odo, "x"), _cat(odo, "y"),
                                                           np.zeros(len(t))]),
                                       _cat(odo, "sigma_m"))
    if not any(k in parts for k in ("imu", "fixes", "rss", "tags", "ranges")):
        return None
    meta = SessionMeta.model_validate({
        "start_pose": agent.start_pose, "placement": agent.placement,
        "mounting_q_bd": agent.mounting_q_bd, "user": agent.user,
        "floor_height_m": mission.floor_height_m, "channel": mission.channel,
        "georeference": mission.georeference, "time_origin_unix_s": mission.t0_unix,
        "source": {"format": "hrtls service export", "mission": mission.id,
                   "agent": agent.id, "name": agent.name}})
    start, _ = versions_of(db, mission.id)
    landmarks = {d["id"]: Landmark.model_validate(d) for d in start}
    return Session(meta=meta, landmarks=landmarks, **parts)


ESTIMATE_COLUMNS = ("t", "x", "y", "z", "floor", "cxx", "cxy", "cyy", "heading_rad",
                    "var_heading", "activity", "since_correction_s")
"""Columns of ``service_estimates.csv``: the ``estimates`` table of :mod:`hrtls.io.schema`."""


def estimates_csv(db: DbSession, agent_id: int) -> str:
    """The agent's stored estimates as CSV (mission time), by the session tables' writer."""
    from hrtls.io.tables import encode_table

    fields = [getattr(EstimateRow, c) for c in ESTIMATE_COLUMNS]
    rows = db.execute(select(*fields).where(EstimateRow.agent_id == agent_id)
                      .order_by(EstimateRow.t)).all()
    columns: dict[str, np.ndarray] = {}
    for k, name in enumerate(ESTIMATE_COLUMNS):
        values = [r[k] for r in rows]
        columns[name] = (np.array(values, dtype=np.str_) if name == "activity" else
                         np.array([np.nan if v is None else v for v in values],
                                  dtype=np.float64))
    return encode_table(columns, table="estimates", suffix=".csv").decode("utf-8")
