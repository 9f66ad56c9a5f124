"""The ingest wire format: a batch of one agent's samples (JSON or msgpack), both directions.

:func:`parse_batch` checks a received batch into a :class:`Batch` of numpy columns (rows or
binary column blocks, :mod:`hrtls.service.columns`); :func:`to_chunk` turns it into the
:class:`hrtls.data.Session` chunk the tracker consumes; :func:`from_chunk` is the inverse used
by the client to stream a recorded session.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

import msgpack
import numpy as np
from pydantic import ValidationError

from hrtls.data import Landmark, Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, SensorSeries
from hrtls.data.session import SessionMeta
from hrtls.service.columns import ColumnError, block, first_out_of_order, numeric, strings

Column = np.ndarray


def _pack(a: Column | None) -> Any:
    """A column as cheap pickle input: float bytes and shape, or the list of strings."""
    if a is None:
        return None
    if a.dtype.kind == "U":
        return a.tolist()
    return a.tobytes(), a.shape


def _unpack(v: Any) -> Column | None:
    if v is None:
        return None
    if type(v) is list:
        return np.asarray(v) if v else np.zeros(0, dtype="<U1")
    return np.frombuffer(v[0], dtype=np.float64).reshape(v[1]).copy()  # writable, as sent


def _rebuild(cls: type[_Part], packed: tuple[Any, ...]) -> _Part:
    return cls(*map(_unpack, packed))


class _Part:
    """Base of the parts: pickled as bytes of their columns (a float array pickles slowly)."""

    t: Column

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        packed = tuple(_pack(getattr(self, f.name)) for f in fields(self))  # type: ignore[arg-type]
        return _rebuild, (type(self), packed)

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and all(
            _same(getattr(self, f.name), getattr(other, f.name))
            for f in fields(self))  # type: ignore[arg-type]

    __hash__ = None  # type: ignore[assignment]


def _same(a: Column | None, b: Column | None) -> bool:
    if a is None or b is None:
        return a is b
    return a.shape == b.shape and a.dtype.kind == b.dtype.kind and bool(
        np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


@dataclass(frozen=True, eq=False)
class ImuPart(_Part):
    """IMU samples in the device frame: m/s^2, rad/s, uT (``n x 3``)."""

    t: Column
    acc: Column
    gyr: Column | None = None
    mag: Column | None = None


@dataclass(frozen=True, eq=False)
class BaroPart(_Part):
    """Barometer, Pa."""

    t: Column
    p_pa: Column


@dataclass(frozen=True, eq=False)
class RssPart(_Part):
    """Received signal strengths, dBm."""

    t: Column
    anchor: Column
    rss_dbm: Column


@dataclass(frozen=True, eq=False)
class TagPart(_Part):
    """Passive tag reads."""

    t: Column
    tag: Column


@dataclass(frozen=True, eq=False)
class RangePart(_Part):
    """Ranges to radio nodes, m (``sigma_m`` NaN = unknown)."""

    t: Column
    node: Column
    range_m: Column
    sigma_m: Column


@dataclass(frozen=True, eq=False)
class FixPart(_Part):
    """Absolute position fixes in mission metres (``z`` optional)."""

    t: Column
    x: Column
    y: Column
    sigma_m: Column
    z: Column | None = None


@dataclass(frozen=True, eq=False)
class OdometryPart(_Part):
    """Robot odometry poses in mission metres."""

    t: Column
    x: Column
    y: Column
    heading_rad: Column
    sigma_m: Column


@dataclass(frozen=True)
class Status:
    """Device status sent along."""

    battery: float | None = None


PARTS = ("imu", "baro", "rss", "tags", "ranges", "fixes", "odometry")


@dataclass(frozen=True, eq=False)
class Batch:
    """One numbered, checked batch of an agent (docs/service-api.md, "Batch")."""

    seq: int
    imu: ImuPart | None = None
    baro: BaroPart | None = None
    rss: RssPart | None = None
    tags: TagPart | None = None
    ranges: RangePart | None = None
    fixes: FixPart | None = None
    odometry: OdometryPart | None = None
    sos: bool = False
    status: Status | None = None
    _span: tuple[float, float] | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        firsts, lasts = [], []
        for name in PARTS:
            part = getattr(self, name)
            if part is not None:
                firsts.append(float(part.t[0]))
                lasts.append(float(part.t[-1]))
        object.__setattr__(self, "_span", (min(firsts), max(lasts)) if firsts else None)

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return Batch, (self.seq, *(getattr(self, p) for p in PARTS), self.sos, self.status)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Batch) and (self.seq, self.sos, self.status) == (
            other.seq, other.sos, other.status) and all(
            getattr(self, p) == getattr(other, p) for p in PARTS)

    __hash__ = None  # type: ignore[assignment]

    def time_span(self) -> tuple[float, float] | None:
        """First and last sample time over all parts (None without samples)."""
        return self._span

    def n_samples(self) -> int:
        """Samples over all parts."""
        return sum(len(getattr(self, p).t) for p in PARTS if getattr(self, p) is not None)


# ---------------------------------------------------------------------------- checking
_T, _NUM, _VEC, _IDS, _OPT_NUM = "t", "num", "vec", "ids", "opt"
"""Column kinds: times, numbers, ``n x 3`` rows, identifiers, numbers with NaN/null unknown."""

_SPECS: dict[str, tuple[type[_Part], dict[str, tuple[str, bool]]]] = {
    "imu": (ImuPart, {"t": (_T, True), "acc": (_VEC, True), "gyr": (_VEC, False),
                      "mag": (_VEC, False)}),
    "baro": (BaroPart, {"t": (_T, True), "p_pa": (_NUM, True)}),
    "rss": (RssPart, {"t": (_T, True), "anchor": (_IDS, True), "rss_dbm": (_NUM, True)}),
    "tags": (TagPart, {"t": (_T, True), "tag": (_IDS, True)}),
    "ranges": (RangePart, {"t": (_T, True), "node": (_IDS, True), "range_m": (_NUM, True),
                           "sigma_m": (_OPT_NUM, False)}),
    "fixes": (FixPart, {"t": (_T, True), "x": (_NUM, True), "y": (_NUM, True),
                        "z": (_NUM, False), "sigma_m": (_NUM, True)}),
    "odometry": (OdometryPart, {"t": (_T, True), "x": (_NUM, True), "y": (_NUM, True),
                                "heading_rad": (_NUM, True), "sigma_m": (_NUM, True)}),
}
_STRICT_TIMES = ("imu", "baro", "fixes", "odometry")
"""Parts whose times must increase strictly (the others: must not decrease)."""

_TOP = frozenset(("seq", *PARTS, "sos", "status"))


def numeric_fields(part: str) -> tuple[str, ...]:
    """The numeric columns of a part (those a column block may carry)."""
    return tuple(k for k, (kind, _) in _SPECS[part][1].items() if kind != _IDS)


def _column(kind: str, value: Any, where: str) -> Column:
    if kind == _IDS:
        return strings(value, where)
    return numeric(value, where, width=3 if kind == _VEC else None, nan_ok=kind == _OPT_NUM,
                   time=kind == _T)


def _check_part(name: str, value: Any) -> _Part:
    cls, spec = _SPECS[name]
    if not isinstance(value, dict):
        raise ColumnError(f"{name}: expected an object")
    unknown = set(value) - set(spec)
    if unknown:
        raise ColumnError(f"{name}: unknown field(s) {', '.join(sorted(map(repr, unknown)))}")
    cols: dict[str, Column] = {}
    for key, (kind, required) in spec.items():
        raw = value.get(key)
        if raw is None:
            if required:
                raise ColumnError(f"{name}.{key}: field required")
            continue
        cols[key] = _column(kind, raw, f"{name}.{key}")
    t = cols["t"]
    if len(t) == 0:
        raise ColumnError(f"{name}.t: at least 1 sample")
    for key, col in cols.items():
        if len(col) != len(t):
            raise ColumnError(f"{name}.{key} has {len(col)} rows, {name}.t has {len(t)}")
    _check_values(name, cols)
    if name == "ranges" and "sigma_m" not in cols:
        cols["sigma_m"] = np.full(len(t), np.nan)
    return cls(**cols)


def _check_values(name: str, cols: dict[str, Column]) -> None:
    t = cols["t"]
    strict = name in _STRICT_TIMES
    i = first_out_of_order(t, strict)
    if i >= 0:
        if strict:
            raise ColumnError(f"{name}.t[{i}] = {t[i]} is not after t[{i - 1}] = {t[i - 1]} "
                              "(times must increase strictly)")
        raise ColumnError(f"{name}.t[{i}] = {t[i]} is before t[{i - 1}] = {t[i - 1]} "
                          "(times must not decrease)")
    if name == "baro" and not ((cols["p_pa"] >= 10_000.0) & (cols["p_pa"] <= 120_000.0)).all():
        raise ColumnError("baro.p_pa outside 10000..120000 Pa (hPa must be x 100)")
    if name in ("fixes", "odometry") and not (cols["sigma_m"] > 0).all():
        raise ColumnError(f"{name}.sigma_m must be > 0 m")


def _check_status(value: Any) -> Status:
    if not isinstance(value, dict) or set(value) - {"battery"}:
        raise ColumnError("status: expected an object with at most 'battery'")
    battery = value.get("battery")
    if battery is None:
        return Status()
    if type(battery) not in (int, float) or not 0.0 <= battery <= 1.0:
        raise ColumnError(f"status.battery = {battery!r}: a number in [0, 1]")
    return Status(float(battery))


def check_batch(value: dict[str, Any]) -> Batch:
    """The batch of a decoded object (:class:`ColumnError` naming the field)."""
    unknown = set(value) - _TOP
    if unknown:
        raise ColumnError(f"unknown field(s) {', '.join(sorted(map(repr, unknown)))} "
                          f"(a batch has {', '.join(sorted(_TOP))})")
    seq = value.get("seq")
    if type(seq) is not int or not 0 <= seq < 2**31:
        raise ColumnError(f"seq = {seq!r}: an integer in [0, 2^31)")
    sos = value.get("sos", False)
    if type(sos) is not bool:
        raise ColumnError(f"sos = {sos!r}: true or false")
    status = None if value.get("status") is None else _check_status(value["status"])
    parts = {p: _check_part(p, value[p]) for p in PARTS if value.get(p) is not None}
    if not parts and not sos and status is None:
        raise ColumnError(f"a batch needs at least one of {', '.join(PARTS)}, sos or status")
    return Batch(seq, sos=sos, status=status, **parts)  # type: ignore[arg-type]


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
    """Check a decoded object as a batch (422 as :class:`BatchError`)."""
    try:
        return check_batch(value)
    except ColumnError as exc:
        raise BatchError(422, str(exc)) from None


def validation_errors(exc: ValidationError) -> str:
    """One line naming every failing field."""
    return "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())


def to_chunk(batch: Batch, meta: SessionMeta, landmarks: dict[str, Landmark]) -> Session | None:
    """The tracker's chunk of ``batch`` (None when it has no motion or position source).

    Odometry poses enter as position fixes with their sigma.
    """
    imu = None
    if batch.imu is not None:
        i = batch.imu
        imu = ImuStream(SensorSeries(i.t, i.acc, "accelerometer"),
                        None if i.gyr is None else SensorSeries(i.t, i.gyr, "gyroscope"),
                        None if i.mag is None else SensorSeries(i.t, i.mag, "magnetometer"),
                        check_units=False)
    b = batch.baro
    pressure = None if b is None else SensorSeries(b.t, b.p_pa[:, None], "pressure")
    r = batch.rss
    rss = None if r is None else RssReadings(r.t, r.anchor, r.rss_dbm)
    tags = None if batch.tags is None else TagDetections(batch.tags.t, batch.tags.tag)
    g = batch.ranges
    ranges = None if g is None else RangeMeasurements(g.t, g.node, g.range_m, g.sigma_m)
    fixes = None
    if batch.fixes is not None:
        f = batch.fixes
        z = f.z if f.z is not None else np.zeros(len(f.t))
        fixes = PositionFixes(f.t, np.column_stack([f.x, f.y, z]), f.sigma_m,
                              has_z=f.z is not None)
    elif batch.odometry is not None:
        o = batch.odometry
        fixes = PositionFixes(o.t, np.column_stack([o.x, o.y, np.zeros(len(o.t))]), o.sigma_m)
    if imu is None and fixes is None and rss is None and tags is None and ranges is None:
        return None
    return Session(meta=meta, imu=imu, pressure=pressure, fixes=fixes, rss=rss, tags=tags,
                   ranges=ranges, landmarks=landmarks)


def _rows(a: np.ndarray, offset: float = 0.0) -> list[Any]:
    return (np.asarray(a, dtype=np.float64) + offset).tolist()


def _blocks(a: np.ndarray, offset: float = 0.0) -> dict[str, Any]:
    return block(np.asarray(a, dtype=np.float64) + offset)


def _nan_as_null(a: np.ndarray) -> list[float | None]:
    out = a.astype(object)
    out[np.isnan(a)] = None
    return list(out.tolist())


def from_chunk(chunk: Session, *, seq: int, t_offset_s: float = 0.0,
               blocks: bool = False) -> dict[str, Any]:
    """The batch of a session chunk (times shifted by ``t_offset_s``), ready to encode.

    ``blocks``: numeric columns as column blocks (msgpack only), else as lists.
    """
    col: Callable[..., Any] = _blocks if blocks else _rows
    out: dict[str, Any] = {"seq": seq}
    imu = chunk.imu
    if imu is not None:
        out["imu"] = {"t": col(imu.accel.t, t_offset_s), "acc": col(imu.accel.values)}
        if imu.gyro is not None:
            out["imu"]["gyr"] = col(imu.gyro.values)
        if imu.mag is not None:
            out["imu"]["mag"] = col(imu.mag.values)
    if chunk.pressure is not None and len(chunk.pressure.t):
        out["baro"] = {"t": col(chunk.pressure.t, t_offset_s),
                       "p_pa": col(chunk.pressure.values[:, 0])}
    if chunk.rss is not None and len(chunk.rss.t):
        out["rss"] = {"t": col(chunk.rss.t, t_offset_s),
                      "anchor": chunk.rss.anchor.astype(str).tolist(),
                      "rss_dbm": col(chunk.rss.rss_dbm)}
    if chunk.tags is not None and len(chunk.tags.t):
        out["tags"] = {"t": col(chunk.tags.t, t_offset_s),
                       "tag": chunk.tags.tag.astype(str).tolist()}
    if chunk.ranges is not None and len(chunk.ranges.t):
        r = chunk.ranges
        sigma = np.asarray(r.sigma_m, dtype=np.float64)
        out["ranges"] = {"t": col(r.t, t_offset_s), "node": r.node.astype(str).tolist(),
                         "range_m": col(r.range_m),
                         "sigma_m": block(sigma) if blocks else _nan_as_null(sigma)}
    if chunk.fixes is not None and len(chunk.fixes.t):
        f = chunk.fixes
        out["fixes"] = {"t": col(f.t, t_offset_s), "x": col(f.xyz[:, 0]),
                        "y": col(f.xyz[:, 1]), "z": col(f.xyz[:, 2]) if f.has_z else None,
                        "sigma_m": col(f.sigma_m)}
    return out
