"""Database tables (SQLAlchemy 2, typed).

The schema itself is created by the Alembic migrations in :mod:`hrtls.service.migrations`; a
test checks that both agree.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column


class Base(DeclarativeBase):
    """Declarative base of the service's tables."""


class Mission(Base):
    """One deployment of a team: frame, floors, alarm profile."""

    __tablename__ = "missions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    status: Mapped[str] = mapped_column(String(16), default="active")
    t0_unix: Mapped[float] = mapped_column(Float)
    created_at: Mapped[float] = mapped_column(Float)
    georeference: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    floor_height_m: Mapped[float] = mapped_column(Float, default=3.0)
    channel: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    stale_after_s: Mapped[float] = mapped_column(Float, default=10.0)
    alarm_profile: Mapped[dict[str, Any]] = mapped_column(JSON)


class Floor(Base):
    """A floor of a mission with its optional plan (GeoJSON in local metres)."""

    __tablename__ = "floors"
    __table_args__ = (UniqueConstraint("mission_id", "index", name="uq_floor_index"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    index: Mapped[int] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(200))
    height_m: Mapped[float] = mapped_column(Float)
    plan: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    image: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True, deferred=True)
    """A scanned or drawn plan of the floor (PNG or JPEG bytes), placed by ``image_meta``."""
    image_meta: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    """``media_type``, ``width_px``, ``height_px``, ``origin_x_m``, ``origin_y_m`` (local
    metres of the image's lower-left corner) and ``m_per_px``."""


class LandmarkRow(Base):
    """A landmark (location message) of a mission, as :class:`hrtls.data.Landmark` JSON."""

    __tablename__ = "landmarks"
    __table_args__ = (UniqueConstraint("mission_id", "key", name="uq_landmark_key"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    key: Mapped[str] = mapped_column(String(200))
    data: Mapped[dict[str, Any]] = mapped_column(JSON)


class LandmarkVersionRow(Base):
    """One written version of a landmark, with the mission time it holds from.

    ``t`` NULL: a landmark of the mission's start (written before any agent's data); otherwise
    the version holds for readings from ``t`` on and running trackers re-run from there.
    """

    __tablename__ = "landmark_versions"
    __table_args__ = (Index("ix_landmark_version_mission", "mission_id", "t"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    key: Mapped[str] = mapped_column(String(200))
    t: Mapped[float | None] = mapped_column(Float, nullable=True)
    data: Mapped[dict[str, Any]] = mapped_column(JSON)


class Agent(Base):
    """A rescuer or robot of a mission."""

    __tablename__ = "agents"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"),
                                            index=True)
    name: Mapped[str] = mapped_column(String(200))
    kind: Mapped[str] = mapped_column(String(16))
    preset: Mapped[str] = mapped_column(String(64))
    placement: Mapped[str | None] = mapped_column(String(64), nullable=True)
    mounting_q_bd: Mapped[list[float] | None] = mapped_column(JSON, nullable=True)
    device: Mapped[dict[str, Any]] = mapped_column(JSON)
    user: Mapped[dict[str, Any]] = mapped_column(JSON)
    start_pose: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    created_at: Mapped[float] = mapped_column(Float)
    status: Mapped[dict[str, Any]] = mapped_column(JSON)


class Token(Base):
    """A bearer token or browser session, stored as the SHA-256 of its secret."""

    __tablename__ = "tokens"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    secret_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    kind: Mapped[str] = mapped_column(String(16))  # token | session
    role: Mapped[str] = mapped_column(String(16))
    label: Mapped[str] = mapped_column(String(200))
    mission_id: Mapped[int | None] = mapped_column(
        ForeignKey("missions.id", ondelete="CASCADE"), nullable=True)
    agent_id: Mapped[int | None] = mapped_column(
        ForeignKey("agents.id", ondelete="CASCADE"), nullable=True)
    parent_id: Mapped[int | None] = mapped_column(Integer, nullable=True)
    created_at: Mapped[float] = mapped_column(Float)
    expires_at: Mapped[float | None] = mapped_column(Float, nullable=True)
    revoked_at: Mapped[float | None] = mapped_column(Float, nullable=True)


class RawBatch(Base):
    """Append-only raw input log: every accepted batch of an agent, as received."""

    __tablename__ = "raw_batches"
    __table_args__ = (UniqueConstraint("agent_id", "seq", name="uq_batch_seq"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    agent_id: Mapped[int] = mapped_column(ForeignKey("agents.id", ondelete="CASCADE"))
    seq: Mapped[int] = mapped_column(Integer)
    received_unix: Mapped[float] = mapped_column(Float)
    t_first: Mapped[float | None] = mapped_column(Float, nullable=True)
    t_last: Mapped[float | None] = mapped_column(Float, nullable=True)
    source: Mapped[str] = mapped_column(String(32))
    content_type: Mapped[str] = mapped_column(String(64))
    body: Mapped[bytes] = mapped_column(LargeBinary)


class TrackerSnapshot(Base):
    """A tracker state of an agent after consuming its data up to ``t_data``."""

    __tablename__ = "tracker_snapshots"
    __table_args__ = (Index("ix_snapshot_agent_t", "agent_id", "t_data"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    agent_id: Mapped[int] = mapped_column(ForeignKey("agents.id", ondelete="CASCADE"))
    t_data: Mapped[float] = mapped_column(Float)
    t_final: Mapped[float] = mapped_column(Float)
    created_unix: Mapped[float] = mapped_column(Float)
    state: Mapped[bytes] = mapped_column(LargeBinary)


class EstimateRow(Base):
    """A published estimate of an agent (mission time)."""

    __tablename__ = "estimates"
    __table_args__ = (Index("ix_estimate_mission_t", "mission_id", "t"),
                      Index("ix_estimate_agent_t", "agent_id", "t"))

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    agent_id: Mapped[int] = mapped_column(ForeignKey("agents.id", ondelete="CASCADE"))
    t: Mapped[float] = mapped_column(Float)
    x: Mapped[float] = mapped_column(Float)
    y: Mapped[float] = mapped_column(Float)
    z: Mapped[float] = mapped_column(Float)
    floor: Mapped[int] = mapped_column(Integer)
    cxx: Mapped[float] = mapped_column(Float)
    cxy: Mapped[float] = mapped_column(Float)
    cyy: Mapped[float] = mapped_column(Float)
    heading_rad: Mapped[float] = mapped_column(Float)
    var_heading: Mapped[float] = mapped_column(Float)
    activity: Mapped[str] = mapped_column(String(16))
    since_correction_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    stale: Mapped[bool] = mapped_column(Boolean)
    received_t: Mapped[float] = mapped_column(Float)


class EventRow(Base):
    """An alarm or notable event, with its acknowledgement."""

    __tablename__ = "events"
    __table_args__ = (Index("ix_event_mission", "mission_id", "id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    agent_id: Mapped[int | None] = mapped_column(
        ForeignKey("agents.id", ondelete="CASCADE"), nullable=True)
    kind: Mapped[str] = mapped_column(String(32))
    severity: Mapped[str] = mapped_column(String(16))
    t: Mapped[float] = mapped_column(Float)
    x: Mapped[float | None] = mapped_column(Float, nullable=True)
    y: Mapped[float | None] = mapped_column(Float, nullable=True)
    floor: Mapped[int | None] = mapped_column(Integer, nullable=True)
    detail: Mapped[dict[str, Any]] = mapped_column(JSON)
    cleared_t: Mapped[float | None] = mapped_column(Float, nullable=True)
    acknowledged_by: Mapped[str | None] = mapped_column(String(200), nullable=True)
    acknowledged_at: Mapped[float | None] = mapped_column(Float, nullable=True)


class OrderRow(Base):
    """An order of the commander to one agent, with its delivery receipt."""

    __tablename__ = "orders"
    __table_args__ = (Index("ix_order_agent", "agent_id", "id"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    agent_id: Mapped[int] = mapped_column(ForeignKey("agents.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(16))
    text: Mapped[str | None] = mapped_column(Text, nullable=True)
    waypoint: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    created_by: Mapped[str] = mapped_column(String(200))
    created_at: Mapped[float] = mapped_column(Float)
    status: Mapped[str] = mapped_column(String(16))
    delivered_at: Mapped[float | None] = mapped_column(Float, nullable=True)
    answered_at: Mapped[float | None] = mapped_column(Float, nullable=True)
    answer_text: Mapped[str | None] = mapped_column(Text, nullable=True)


class MissionNetwork(Base):
    """The sensor network a mission declared: its node ids and the mission estimator's state.

    ``params``: fields of :class:`hrtls.mission.tracker.MissionParams` set for this mission;
    ``estimates``: the newest node estimates (``id -> {position, covariance, localized,
    reason, readings}``) at the processed horizon ``horizon_s``.
    """

    __tablename__ = "mission_networks"

    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"),
                                            primary_key=True)
    nodes: Mapped[list[str]] = mapped_column(JSON)
    params: Mapped[dict[str, Any]] = mapped_column(JSON)
    estimates: Mapped[dict[str, Any]] = mapped_column(JSON)
    horizon_s: Mapped[float | None] = mapped_column(Float, nullable=True)


class MissionSnapshot(Base):
    """A mission estimator's state.

    After its windows up to ``horizon_s`` and the raw log up to ``raw_id`` (the newest raw
    batch it had consumed).
    """

    __tablename__ = "mission_snapshots"
    __table_args__ = (Index("ix_mission_snapshot_horizon", "mission_id", "horizon_s"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    horizon_s: Mapped[float] = mapped_column(Float)
    raw_id: Mapped[int] = mapped_column(Integer)
    net_raw_id: Mapped[int] = mapped_column(Integer, server_default="0")
    """The newest ``network_range_batches`` id it had consumed."""
    created_unix: Mapped[float] = mapped_column(Float)
    state: Mapped[bytes] = mapped_column(LargeBinary)


class NetworkRangeBatch(Base):
    """Append-only log of the ranges the dropped nodes measured between themselves.

    One numbered batch (``seq``, unique per mission) as accepted by ``POST
    /missions/{id}/network/ranges``; ``body``: its columns (msgpack ``{"t_s", "node_a",
    "node_b", "range_m"}``), mission time s and m.
    """

    __tablename__ = "network_range_batches"
    __table_args__ = (UniqueConstraint("mission_id", "seq", name="uq_network_range_seq"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    mission_id: Mapped[int] = mapped_column(ForeignKey("missions.id", ondelete="CASCADE"))
    seq: Mapped[int] = mapped_column(Integer)
    received_unix: Mapped[float] = mapped_column(Float)
    t_first: Mapped[float] = mapped_column(Float)
    t_last: Mapped[float] = mapped_column(Float)
    rows: Mapped[int] = mapped_column(Integer)
    body: Mapped[bytes] = mapped_column(LargeBinary)
