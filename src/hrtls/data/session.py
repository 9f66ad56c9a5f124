"""The session: everything recorded for one agent on one mission, plus its metadata.

The on-disk form (a folder or zip of CSV/JSON files) is read and written by
:mod:`hrtls.io.session`; this module holds the in-memory form and ``session.json``'s schema.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import (
    Checkpoints,
    GroundTruth,
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.errors import InputError
from hrtls.frames import Georeference


class StartPose(BaseModel):
    """Known start position (m) and heading (rad, ENU, CCW from east) of the agent.

    ``t`` is the time (s, session clock) at which the pose holds; None means the start of the
    recording. Trackers run their attitude filter from the first sample but place the agent at
    ``t``.
    """

    model_config = ConfigDict(extra="forbid")

    t: float | None = None
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    heading: float | None = None
    sigma_xy_m: float = Field(default=0.5, gt=0.0)
    sigma_heading_rad: float = Field(default=0.2, gt=0.0)


class ChannelModel(BaseModel):
    """Log-normal path loss (Tarrio eq. 1): ``rss = A - 10 eta log10(d)``, d in m."""

    model_config = ConfigDict(extra="forbid")

    a_dbm: float = Field(default=-59.0, description="RSS at 1 m, dBm")
    eta: float = Field(default=2.0, gt=0.0, description="path-loss exponent")
    sigma_db: float = Field(default=4.0, gt=0.0, description="shadowing std, dB")


class GeoreferenceModel(BaseModel):
    """Anchor of the local frame on WGS-84 (see :class:`hrtls.frames.Georeference`)."""

    model_config = ConfigDict(extra="forbid")

    lat_deg: float = Field(ge=-90.0, le=90.0)
    lon_deg: float = Field(ge=-180.0, le=360.0)
    height_m: float = 0.0
    rotation_rad: float = 0.0

    def to_georeference(self) -> Georeference:
        """The frames-level georeference."""
        return Georeference(self.lat_deg, self.lon_deg, self.height_m, self.rotation_rad)


class UserProfile(BaseModel):
    """The person: height and the parameters of their step-length model (free-form)."""

    model_config = ConfigDict(extra="allow")

    height_m: float | None = Field(default=None, gt=0.5, lt=2.8)
    step_model: dict[str, Any] = Field(default_factory=dict)


class SessionMeta(BaseModel):
    """Contents of ``session.json``. Unknown keys are kept (and written back)."""

    model_config = ConfigDict(extra="allow")

    format_version: int = 1
    start_pose: StartPose | None = None
    placement: str | None = Field(default=None, description="e.g. waist, pocket, hand, belt")
    mounting_q_bd: tuple[float, float, float, float] | None = Field(
        default=None, description="device->body rotation [w, x, y, z], when known")
    user: UserProfile = Field(default_factory=UserProfile)
    floor_height_m: float = Field(default=3.0, gt=0.0)
    channel: ChannelModel | None = None
    georeference: GeoreferenceModel | None = None
    time_origin_unix_s: float | None = Field(
        default=None, description="Unix time of t = 0, when the source clock is known")
    source: dict[str, Any] = Field(default_factory=dict, description="format, files, converter")
    notes: list[str] = Field(default_factory=list)


SESSION_PARTS = ("imu", "pressure", "orientation", "fixes", "rss", "tags", "ranges", "truth",
                 "checkpoints")


@dataclass(frozen=True, slots=True, eq=False)
class Session:
    """One recording: sensor streams, observations, landmarks, ground truth and metadata.

    Every part is optional, but a session needs at least one source of motion or position
    (an IMU stream, fixes, RSS, tag reads or ranges).
    """

    meta: SessionMeta = field(default_factory=SessionMeta)
    imu: ImuStream | None = None
    pressure: SensorSeries | None = None
    orientation: OrientationSeries | None = None
    fixes: PositionFixes | None = None
    rss: RssReadings | None = None
    tags: TagDetections | None = None
    ranges: RangeMeasurements | None = None
    landmarks: dict[str, Landmark] = field(default_factory=dict)
    truth: GroundTruth | None = None
    checkpoints: Checkpoints | None = None

    def __post_init__(self) -> None:
        if all(getattr(self, name) is None for name in ("imu", "fixes", "rss", "tags", "ranges")):
            raise InputError("session has no source of motion or position", where="session",
                             expected="imu.csv or at least one of fixes/rss/tags/ranges")
        for key, landmark in self.landmarks.items():
            if key != landmark.id:
                raise InputError(f"key {key!r} differs from id {landmark.id!r}",
                                 where="session landmarks", expected="landmarks keyed by id")

    @property
    def georeference(self) -> Georeference | None:
        """The local frame's WGS-84 anchor, when known."""
        g = self.meta.georeference
        return None if g is None else g.to_georeference()

    def resolved_landmarks(self) -> dict[str, Landmark]:
        """Landmarks with local positions (WGS-84 ones placed through the georeference)."""
        geo = self.georeference
        return {k: lm.resolved(geo) for k, lm in self.landmarks.items()}

    def unknown_ids(self) -> dict[str, list[str]]:
        """Ids in rss/tags/ranges that no landmark describes, per observation file."""
        out: dict[str, list[str]] = {}
        for label, ids in (("rss", None if self.rss is None else self.rss.anchor),
                           ("tags", None if self.tags is None else self.tags.tag),
                           ("ranges", None if self.ranges is None else self.ranges.node)):
            if ids is None:
                continue
            missing = sorted(set(ids.tolist()) - set(self.landmarks))
            if missing:
                out[label] = missing
        return out

    def time_span(self) -> tuple[float, float]:
        """Earliest and latest time over all streams and observations, s."""
        starts, ends = [], []
        for name in SESSION_PARTS:
            part = getattr(self, name)
            if part is None:
                continue
            t = part.accel.t if isinstance(part, ImuStream) else part.t
            if len(t):
                starts.append(float(t[0]))
                ends.append(float(t[-1]))
        if not starts:
            return (0.0, 0.0)
        return (min(starts), max(ends))

    def with_parts(self, **parts: Any) -> Session:
        """A copy with some parts replaced (``session.with_parts(truth=None)``)."""
        return replace(self, **parts)
