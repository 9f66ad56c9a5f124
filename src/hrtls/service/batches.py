"""The ingest wire format: a batch of one agent's samples (JSON or msgpack), both directions.

:class:`Batch` validates a received batch; :func:`to_chunk` turns it into the
:class:`hrtls.data.Session` chunk the tracker consumes; :func:`from_chunk` is the inverse used
by the client to stream a recorded session.
"""

from __future__ import annotations

import json
import math
from typing import Any

import msgpack
import numpy as np
from pydantic import Field, ValidationError, model_validator

from hrtls.data import Landmark, Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, SensorSeries
from hrtls.data.session import SessionMeta
from hrtls.service.schemas import Strict

MAX_SAMPLES = 2000
Vec3 = tuple[float, float, float]
_Times = Field(min_length=1, max_length=MAX_SAMPLES)
_Ids = Field(min_length=1, max_length=MAX_SAMPLES)


def _increasing(t: list[float], part: str) -> None:
    for i in range(1, len(t)):
        if not t[i] > t[i - 1]:
            raise ValueError(f"{part}.t[{i}] = {t[i]} is not after t[{i - 1}] = {t[i - 1]} "
                             "(times must increase strictly)")


def _same_length(part: str, t: list[float], **columns: list[Any] | None) -> None:
    for name, column in columns.items():
        if column is not None and len(column) != len(t):
            raise ValueError(f"{part}.{name} has {len(column)} rows, {part}.t has {len(t)}")


class ImuPart(Strict):
    """IMU samples in the device frame: m/s^2, rad/s, uT."""

    t: list[float] = _Times
    acc: list[Vec3]
    gyr: list[Vec3] | None = None
    mag: list[Vec3] | None = None

    @model_validator(mode="after")
    def _check(self) -> ImuPart:
        _same_length("imu", self.t, acc=self.acc, gyr=self.gyr, mag=self.mag)
        _increasing(self.t, "imu")
        return self


class BaroPart(Strict):
    """Barometer, Pa."""

    t: list[float] = _Times
    p_pa: list[float] = Field(max_length=MAX_SAMPLES)

    @model_validator(mode="after")
    def _check(self) -> BaroPart:
        _same_length("baro", self.t, p_pa=self.p_pa)
        _increasing(self.t, "baro")
        if any(not 10_000.0 <= p <= 120_000.0 for p in self.p_pa):
            raise ValueError("baro.p_pa outside 10000..120000 Pa (hPa must be x 100)")
        return self


class RssPart(Strict):
    """Received signal strengths, dBm."""

    t: list[float] = _Times
    anchor: list[str] = _Ids
    rss_dbm: list[float] = Field(max_length=MAX_SAMPLES)

    @model_validator(mode="after")
    def _check(self) -> RssPart:
        _same_length("rss", self.t, anchor=self.anchor, rss_dbm=self.rss_dbm)
        if any(b < a for a, b in zip(self.t, self.t[1:], strict=False)):
            raise ValueError("rss.t must not decrease")
        return self


class TagPart(Strict):
    """Passive tag reads."""

    t: list[float] = _Times
    tag: list[str] = _Ids

    @model_validator(mode="after")
    def _check(self) -> TagPart:
        _same_length("tags", self.t, tag=self.tag)
        if any(b < a for a, b in zip(self.t, self.t[1:], strict=False)):
            raise ValueError("tags.t must not decrease")
        return self


class RangePart(Strict):
    """Ranges to radio nodes, m (``sigma_m`` null = unknown)."""

    t: list[float] = _Times
    node: list[str] = _Ids
    range_m: list[float] = Field(max_length=MAX_SAMPLES)
    sigma_m: list[float | None] | None = None

    @model_validator(mode="after")
    def _check(self) -> RangePart:
        _same_length("ranges", self.t, node=self.node, range_m=self.range_m,
                     sigma_m=self.sigma_m)
        if any(b < a for a, b in zip(self.t, self.t[1:], strict=False)):
            raise ValueError("ranges.t must not decrease")
        return self


class FixPart(Strict):
    """Absolute position fixes in mission metres (``z`` optional)."""

    t: list[float] = _Times
    x: list[float] = Field(max_length=MAX_SAMPLES)
    y: list[float] = Field(max_length=MAX_SAMPLES)
    z: list[float] | None = None
    sigma_m: list[float] = Field(max_length=MAX_SAMPLES)

    @model_validator(mode="after")
    def _check(self) -> FixPart:
        _same_length("fixes", self.t, x=self.x, y=self.y, z=self.z, sigma_m=self.sigma_m)
        _increasing(self.t, "fixes")
        if any(s <= 0 for s in self.sigma_m):
            raise ValueError("fixes.sigma_m must be > 0 m")
        return self


class OdometryPart(Strict):
    """Robot odometry poses in mission metres."""

    t: list[float] = _Times
    x: list[float] = Field(max_length=MAX_SAMPLES)
    y: list[float] = Field(max_length=MAX_SAMPLES)
    heading_rad: list[float] = Field(max_length=MAX_SAMPLES)
    sigma_m: list[float] = Field(max_length=MAX_SAMPLES)

    @model_validator(mode="after")
    def _check(self) -> OdometryPart:
        _same_length("odometry", self.t, x=self.x, y=self.y, heading_rad=self.heading_rad,
                     sigma_m=self.sigma_m)
        _increasing(self.t, "odometry")
        if any(s <= 0 for s in self.sigma_m):
            raise ValueError("odometry.sigma_m must be > 0 m")
        return self


class Status(Strict):
    """Device status sent along."""

    battery: float | None = Field(default=None, ge=0.0, le=1.0)


PARTS = ("imu", "baro", "rss", "tags", "ranges", "fixes", "odometry")


class Batch(Strict):
    """One numbered batch of an agent (docs/service-api.md, "Batch")."""

    seq: int = Field(ge=0, lt=2**31)
    imu: ImuPart | None = None
    baro: BaroPart | None = None
    rss: RssPart | None = None
    tags: TagPart | None = None
    ranges: RangePart | None = None
    fixes: FixPart | None = None
    odometry: OdometryPart | None = None
    sos: bool = False
    status: Status | None = None

    @model_validator(mode="after")
    def _not_empty(self) -> Batch:
        if all(getattr(self, p) is None for p in PARTS) and not self.sos and self.status is None:
            raise ValueError(f"a batch needs at least one of {', '.join(PARTS)}, sos or status")
        return self

    def time_span(self) -> tuple[float, float] | None:
        """First and last sample time over all parts (None without samples)."""
        firsts, lasts = [], []
        for name in PARTS:
            part = getattr(self, name)
            if part is not None:
                firsts.append(part.t[0])
                lasts.append(part.t[-1])
        return (min(firsts), max(lasts)) if firsts else None

    def n_samples(self) -> int:
        """Samples over all parts."""
        return sum(len(getattr(self, p).t) for p in PARTS if getattr(self, p) is not None)


class BatchError(ValueError):
    """A body that is not a batch: ``status`` is the HTTP status to answer."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail


JSON_TYPES = ("application/json",)
MSGPACK_TYPES = ("application/msgpack", "application/x-msgpack", "application/vnd.msgpack")


def _reject_constant(name: str) -> None:
    raise ValueError(f"{name} is not a finite number")


def decode_body(body: bytes, content_type: str) -> dict[str, Any]:
    """The object in a JSON or msgpack body (415 / 400 as :class:`BatchError`)."""
    kind = content_type.split(";", 1)[0].strip().lower()
    try:
        if kind in JSON_TYPES:
            value = json.loads(body, parse_constant=_reject_constant)
        elif kind in MSGPACK_TYPES:
            value = msgpack.unpackb(body, raw=False, strict_map_key=True)
        else:
            raise BatchError(415, f"Content-Type {content_type or '(none)'!r}: send "
                                  "application/json or application/msgpack")
    except BatchError:
        raise
    except Exception as exc:
        raise BatchError(400, f"body is not valid {kind}: {exc}") from None
    if not isinstance(value, dict):
        raise BatchError(400, "body must be an object (a batch)")
    return value


def parse_batch(value: dict[str, Any]) -> Batch:
    """Validate a decoded object as a batch (422 as :class:`BatchError`)."""
    try:
        return Batch.model_validate(value)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise BatchError(422, f"{where}: {first['msg']}" if where else first["msg"]) from None


def validation_errors(exc: ValidationError) -> str:
    """One line naming every failing field."""
    return "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())


def to_chunk(batch: Batch, meta: SessionMeta, landmarks: dict[str, Landmark]) -> Session | None:
    """The tracker's chunk of ``batch`` (None when it has no motion or position source).

    Odometry poses enter as position fixes with their sigma.
    """
    imu = None
    if batch.imu is not None:
        t = np.asarray(batch.imu.t, dtype=np.float64)
        imu = ImuStream(
            SensorSeries(t, np.asarray(batch.imu.acc, dtype=np.float64), "accelerometer"),
            None if batch.imu.gyr is None else
            SensorSeries(t, np.asarray(batch.imu.gyr, dtype=np.float64), "gyroscope"),
            None if batch.imu.mag is None else
            SensorSeries(t, np.asarray(batch.imu.mag, dtype=np.float64), "magnetometer"),
            check_units=False)
    pressure = None if batch.baro is None else SensorSeries(
        np.asarray(batch.baro.t), np.asarray(batch.baro.p_pa)[:, None], "pressure")
    rss = None if batch.rss is None else RssReadings(
        np.asarray(batch.rss.t), np.asarray(batch.rss.anchor), np.asarray(batch.rss.rss_dbm))
    tags = None if batch.tags is None else TagDetections(np.asarray(batch.tags.t),
                                                         np.asarray(batch.tags.tag))
    ranges = None
    if batch.ranges is not None:
        r = batch.ranges
        sigma = [math.nan] * len(r.t) if r.sigma_m is None else \
            [math.nan if s is None else s for s in r.sigma_m]
        ranges = RangeMeasurements(np.asarray(r.t), np.asarray(r.node), np.asarray(r.range_m),
                                   np.asarray(sigma, dtype=np.float64))
    fixes = None
    f = batch.fixes if batch.fixes is not None else None
    if f is not None:
        z = f.z if f.z is not None else [0.0] * len(f.t)
        fixes = PositionFixes(np.asarray(f.t), np.column_stack([f.x, f.y, z]),
                              np.asarray(f.sigma_m), has_z=f.z is not None)
    elif batch.odometry is not None:
        o = batch.odometry
        fixes = PositionFixes(np.asarray(o.t), np.column_stack([o.x, o.y, [0.0] * len(o.t)]),
                              np.asarray(o.sigma_m))
    if imu is None and fixes is None and rss is None and tags is None and ranges is None:
        return None
    return Session(meta=meta, imu=imu, pressure=pressure, fixes=fixes, rss=rss, tags=tags,
                   ranges=ranges, landmarks=landmarks)


def _col(a: np.ndarray, offset: float = 0.0) -> list[float]:
    return [float(v) + offset for v in a]


def from_chunk(chunk: Session, *, seq: int, t_offset_s: float = 0.0) -> dict[str, Any]:
    """The batch of a session chunk (times shifted by ``t_offset_s``), ready to encode."""
    out: dict[str, Any] = {"seq": seq}
    imu = chunk.imu
    if imu is not None:
        t = imu.accel.t
        out["imu"] = {"t": _col(t, t_offset_s), "acc": imu.accel.values.tolist()}
        if imu.gyro is not None:
            out["imu"]["gyr"] = imu.gyro.values.tolist()
        if imu.mag is not None:
            out["imu"]["mag"] = imu.mag.values.tolist()
    if chunk.pressure is not None and len(chunk.pressure.t):
        out["baro"] = {"t": _col(chunk.pressure.t, t_offset_s),
                       "p_pa": _col(chunk.pressure.values[:, 0])}
    if chunk.rss is not None and len(chunk.rss.t):
        out["rss"] = {"t": _col(chunk.rss.t, t_offset_s),
                      "anchor": list(map(str, chunk.rss.anchor)),
                      "rss_dbm": _col(chunk.rss.rss_dbm)}
    if chunk.tags is not None and len(chunk.tags.t):
        out["tags"] = {"t": _col(chunk.tags.t, t_offset_s), "tag": list(map(str, chunk.tags.tag))}
    if chunk.ranges is not None and len(chunk.ranges.t):
        r = chunk.ranges
        out["ranges"] = {"t": _col(r.t, t_offset_s), "node": list(map(str, r.node)),
                         "range_m": _col(r.range_m),
                         "sigma_m": [None if math.isnan(s) else float(s) for s in r.sigma_m]}
    if chunk.fixes is not None and len(chunk.fixes.t):
        f = chunk.fixes
        out["fixes"] = {"t": _col(f.t, t_offset_s), "x": _col(f.xyz[:, 0]),
                        "y": _col(f.xyz[:, 1]), "z": _col(f.xyz[:, 2]) if f.has_z else None,
                        "sigma_m": _col(f.sigma_m)}
    return out
