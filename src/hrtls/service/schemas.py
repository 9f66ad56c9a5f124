"""Request and response bodies of the REST API (docs/service-api.md).

Requests are strict: unknown fields are refused and numbers must be finite. Responses are
separate models so that storage changes never leak into the contract.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from hrtls.data import Landmark
from hrtls.data.session import ChannelModel, GeoreferenceModel, StartPose

API_PREFIX = "/api/v1"
"""Path prefix of every API route."""

Name = Field(min_length=1, max_length=200)


class Strict(BaseModel):
    """Base of request bodies: unknown fields and non-finite numbers are refused."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Out(BaseModel):
    """Base of response bodies."""

    model_config = ConfigDict(from_attributes=True)


# ---------------------------------------------------------------------------- auth / tokens
class LoginIn(Strict):
    """Body of ``POST /auth/login``."""

    token: str = Field(min_length=1, max_length=200)


class WhoamiOut(Out):
    """The caller."""

    role: str
    token_id: int
    label: str
    mission: int | None
    agent: int | None
    mission_t: float | None = None


class TokenIn(Strict):
    """Body of ``POST /tokens``: a commander or viewer token (agent tokens come with agents)."""

    role: Literal["commander", "viewer"]
    label: str = Name


class TokenOut(Out):
    """A token without its secret."""

    id: int
    role: str
    label: str
    created_at: float
    revoked_at: float | None
    mission: int | None
    agent: int | None


class NewTokenOut(TokenOut):
    """A token just created, with its secret (shown once)."""

    token: str


# ---------------------------------------------------------------------------- missions
class AlarmProfile(Strict):
    """Thresholds of the alarms (PASS no-motion, silent agent, uncertainty)."""

    prealarm_s: float = Field(default=20.0, gt=0.0, le=3600.0)
    alarm_s: float = Field(default=30.0, gt=0.0, le=3600.0)
    silent_s: float = Field(default=15.0, gt=0.0, le=3600.0)
    sigma_alarm_m: float = Field(default=5.0, gt=0.0, le=1000.0)

    @model_validator(mode="after")
    def _order(self) -> AlarmProfile:
        if self.alarm_s < self.prealarm_s:
            raise ValueError("alarm_s must be >= prealarm_s")
        return self


class Georeference(GeoreferenceModel):
    """Anchor of the local mission frame on WGS-84 (strict)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Channel(ChannelModel):
    """Path-loss model of the mission's beacons (strict)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


_PLAN_KINDS = ("wall", "door", "room", "corridor", "stairs", "exit", "zone")


def check_plan(plan: dict[str, Any] | None) -> dict[str, Any] | None:
    """A floor plan: a GeoJSON FeatureCollection in local metres whose geometries shapely reads."""
    if plan is None:
        return None
    from shapely.geometry import shape

    if plan.get("type") != "FeatureCollection" or not isinstance(plan.get("features"), list):
        raise ValueError("plan must be a GeoJSON FeatureCollection {type, features: [...]}")
    for i, feature in enumerate(plan["features"]):
        if not isinstance(feature, dict) or feature.get("type") != "Feature":
            raise ValueError(f"plan feature {i}: not a GeoJSON Feature")
        props = feature.get("properties") or {}
        if not isinstance(props, dict):
            raise ValueError(f"plan feature {i}: properties must be an object")
        kind = props.get("kind")
        if kind is not None and kind not in _PLAN_KINDS:
            raise ValueError(f"plan feature {i}: kind {kind!r} not one of {_PLAN_KINDS}")
        try:
            geom = shape(feature.get("geometry"))
        except Exception as exc:
            raise ValueError(f"plan feature {i}: invalid geometry ({exc})") from None
        if geom.is_empty or not all(math.isfinite(v) for v in geom.bounds):
            raise ValueError(f"plan feature {i}: empty or non-finite geometry")
    return plan


class FloorIn(Strict):
    """A floor (``PUT /missions/{m}/floors/{index}`` body, without the index)."""

    name: str = Name
    height_m: float = Field(ge=-500.0, le=2000.0)
    plan: dict[str, Any] | None = None

    @field_validator("plan")
    @classmethod
    def _valid_plan(cls, value: dict[str, Any] | None) -> dict[str, Any] | None:
        return check_plan(value)


class FloorWithIndexIn(FloorIn):
    """A floor in ``POST /missions``."""

    index: int = Field(ge=-20, le=300)


class FloorImageOut(Out):
    """Where a floor's plan image lies: lower-left corner and scale in the mission frame."""

    media_type: str
    width_px: int
    height_px: int
    origin_x_m: float
    origin_y_m: float
    m_per_px: float
    url: str
    """``GET`` it (as a reader) for the image bytes."""


class FloorOut(Out):
    """A floor."""

    index: int
    name: str
    height_m: float
    plan: dict[str, Any] | None
    image: FloorImageOut | None = None


class MissionIn(Strict):
    """Body of ``POST /missions``."""

    name: str = Name
    georeference: Georeference | None = None
    channel: Channel | None = None
    floor_height_m: float = Field(default=3.0, gt=0.5, le=20.0)
    stale_after_s: float = Field(default=10.0, gt=0.0, le=3600.0)
    alarm_profile: AlarmProfile = Field(default_factory=AlarmProfile)
    floors: list[FloorWithIndexIn] = Field(default_factory=list, max_length=300)

    @field_validator("floors")
    @classmethod
    def _unique_floors(cls, value: list[FloorWithIndexIn]) -> list[FloorWithIndexIn]:
        indices = [f.index for f in value]
        if len(set(indices)) != len(indices):
            raise ValueError("floor indices must be unique")
        return value


class MissionPatch(Strict):
    """Body of ``PATCH /missions/{m}``."""

    name: str | None = Field(default=None, min_length=1, max_length=200)
    georeference: Georeference | None = None
    channel: Channel | None = None
    floor_height_m: float | None = Field(default=None, gt=0.5, le=20.0)
    stale_after_s: float | None = Field(default=None, gt=0.0, le=3600.0)
    alarm_profile: AlarmProfile | None = None
    status: Literal["active", "closed"] | None = None


class MissionSummaryOut(Out):
    """A mission in the list."""

    id: int
    name: str
    status: str
    t0_unix: float
    created_at: float
    n_agents: int


class MissionOut(Out):
    """A mission with its floors."""

    id: int
    name: str
    status: str
    t0_unix: float
    now_t: float
    created_at: float
    georeference: dict[str, Any] | None
    channel: dict[str, Any] | None
    floor_height_m: float
    stale_after_s: float
    alarm_profile: dict[str, Any]
    floors: list[FloorOut]


# ---------------------------------------------------------------------------- landmarks
class LandmarkIn(Landmark):
    """A landmark in a request: :class:`hrtls.data.Landmark`, strict."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    id: str = Field(min_length=1, max_length=200)


class NodeOut(Out):
    """A sensor-network node."""

    id: str
    position: list[float] | None
    floor: int | None
    sigma_m: float | None
    seed: bool
    localized: bool


class WaypointOut(Out):
    """The way point of a pending go-to order."""

    agent: int
    order: int
    x: float
    y: float
    floor: int
    status: str


class InfrastructureOut(Out):
    """Landmarks, sensor nodes and robot way points of a mission."""

    landmarks: list[dict[str, Any]]
    nodes: list[NodeOut]
    waypoints: list[WaypointOut]


# ---------------------------------------------------------------------------- agents
class StartPoseIn(StartPose):
    """A check-in pose (mission time), strict."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class UserIn(Strict):
    """The person carrying the device."""

    height_m: float | None = Field(default=None, gt=0.5, lt=2.8)
    step_model: dict[str, float | str] = Field(default_factory=dict, max_length=20)


class AgentIn(Strict):
    """Body of ``POST /missions/{m}/agents``."""

    name: str = Name
    kind: Literal["rescuer", "robot"] = "rescuer"
    preset: str = Field(default="default", min_length=1, max_length=64)
    placement: str | None = Field(default=None, max_length=64)
    mounting_q_bd: tuple[float, float, float, float] | None = None
    device: dict[str, str | float | int | bool | None] = Field(default_factory=dict,
                                                                max_length=50)
    user: UserIn = Field(default_factory=UserIn)
    start_pose: StartPoseIn | None = None


class AgentPatch(Strict):
    """Body of ``PATCH /missions/{m}/agents/{a}``."""

    name: str | None = Field(default=None, min_length=1, max_length=200)
    preset: str | None = Field(default=None, min_length=1, max_length=64)
    placement: str | None = Field(default=None, max_length=64)
    mounting_q_bd: tuple[float, float, float, float] | None = None
    device: dict[str, str | float | int | bool | None] | None = Field(default=None,
                                                                       max_length=50)
    user: UserIn | None = None


class AgentOut(Out):
    """An agent with its live status."""

    id: int
    mission: int
    name: str
    kind: str
    preset: str
    placement: str | None
    mounting_q_bd: list[float] | None
    device: dict[str, Any]
    user: dict[str, Any]
    start_pose: dict[str, Any] | None
    checked_in: bool
    created_at: float
    status: dict[str, Any]


class NewAgentOut(Out):
    """An agent just created, with its ingest token (shown once)."""

    agent: AgentOut
    token: str
    token_id: int


class HealthOut(Out):
    """``GET /health``."""

    status: str
    version: str
    db: str


# ---------------------------------------------------------------------------- dashboard
class BasemapOut(Out):
    """A web-mercator tile source for georeferenced missions."""

    url: str
    max_zoom: int
    attribution: str


class DashboardConfigOut(Out):
    """What the dashboard needs to know of this deployment."""

    basemap: BasemapOut | None
