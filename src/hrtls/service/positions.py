"""GNSS positions of phone tracking apps as fixes: OsmAnd (Traccar Client) and OwnTracks.

Each message is parsed to one :class:`Position`, converted to mission metres through the
mission's georeference and turned into a batch with one fix. These apps number nothing, so the
service numbers the batches (``hrtls.service.seqbook.ASSIGNED_SEQ_BASE`` and up). The raw log
keeps an envelope: the message text as received (the ``token`` query parameter removed) with
the seq, ``t0_unix`` and georeference it was converted with, so :func:`decode_position` rebuilds
the same batch on replay even after the mission's georeference changed.

Fields each protocol documents are accepted; those hrtls does not use are ignored (OsmAnd query
parameters are free-form by definition: unknown ones are ignored and listed in the ack);
fields no documentation names are refused, as are non-finite or out-of-range values we use.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any
from urllib.parse import parse_qsl, urlencode

from hrtls.data.session import GeoreferenceModel
from hrtls.service.batches import Batch, BatchError, parse_batch

ENVELOPE_TYPE = "application/vnd.hrtls.position+json"
"""Content type of the raw-log rows of positions."""

SOURCES = ("osmand", "owntracks")
"""Raw-log sources of positions."""


@dataclass(frozen=True)
class PositionParams:
    """How positions become fixes."""

    accuracy_to_sigma: float = 1.0 / math.sqrt(-2.0 * math.log(1.0 - 0.68))
    """Per-axis sigma / reported accuracy: Android and iOS report the radius of 68 %
    horizontal confidence; for a circular Gaussian that radius is 1.51 sigma."""
    max_accuracy_m: float = 10_000.0
    max_future_s: float = 300.0
    """Positions stamped further ahead of the server clock are refused (phone clock wrong)."""


PARAMS = PositionParams()


@dataclass(frozen=True)
class Position:
    """One position report (WGS-84), before conversion."""

    device: str
    time_unix: float
    lat_deg: float
    lon_deg: float
    accuracy_m: float
    battery: float | None = None
    """0..1, None when not sent."""
    sos: bool = False


@dataclass(frozen=True)
class Parsed:
    """A message: its position, or why it carries none (acknowledged and ignored)."""

    position: Position | None
    ignored_reason: str | None = None
    ignored_fields: tuple[str, ...] = ()


# ---------------------------------------------------------------------------- values
def _number(value: Any, where: str, *, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(value, bool):
        raise BatchError(422, f"{where}: expected a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise BatchError(422, f"{where}: expected a number, got {value!r}") from None
    if not math.isfinite(x) or not lo <= x <= hi:
        raise BatchError(422, f"{where} = {value!r} must be a finite number in [{lo:g}, {hi:g}]")
    return x


def _accuracy(value: Any, where: str) -> float:
    if value is None:
        raise BatchError(422, f"{where} (horizontal accuracy, m) is required: it sets the fix's "
                              "uncertainty")
    acc = _number(value, where, lo=0.0, hi=PARAMS.max_accuracy_m)
    if acc <= 0.0:
        raise BatchError(422, f"{where} = {value!r}: a fix needs an accuracy > 0 m")
    return acc


def _lat_lon(lat: Any, lon: Any, where_lat: str, where_lon: str) -> tuple[float, float]:
    if lat is None or lon is None:
        raise BatchError(422, f"{where_lat} and {where_lon} are required")
    return _number(lat, where_lat, lo=-90.0, hi=90.0), _number(lon, where_lon, lo=-180.0,
                                                                 hi=180.0)


def _time(value: Any, where: str) -> float:
    """Unix seconds from s or ms since 1970 (number or digits) or ISO 8601 (naive = UTC)."""
    if value is None or value == "":
        raise BatchError(422, f"{where} (time of the fix) is required")
    if isinstance(value, str):
        try:
            t = float(value)
        except ValueError:
            try:
                stamp = datetime.fromisoformat(value.strip())
            except ValueError:
                raise BatchError(422, f"{where} = {value!r}: expected Unix seconds or "
                                      "milliseconds, or an ISO 8601 time") from None
            if stamp.tzinfo is None:
                stamp = stamp.replace(tzinfo=UTC)
            return stamp.timestamp()
    else:
        t = _number(value, where)
    t = _number(t, where, lo=0.0)
    return t / 1000.0 if t > 1e11 else t   # 1e11 s is the year 5138; 1e11 ms is 1973


def _battery_percent(value: Any, where: str) -> float | None:
    if value is None or value == "":
        return None
    b = _number(value, where)
    return None if b < 0 else _number(b, where, hi=100.0) / 100.0   # -1: unknown


def _check_finite(obj: dict[str, Any], keys: tuple[str, ...], where: str) -> None:
    """Optional numbers hrtls does not use must still be numbers (or null)."""
    for k in keys:
        if obj.get(k) is not None:
            _number(obj[k], f"{where}{k}")


def _unknown(obj: dict[str, Any], known: frozenset[str], where: str) -> None:
    extra = sorted(set(obj) - known)
    if extra:
        raise BatchError(422, f"{where}: unknown field(s) {', '.join(map(repr, extra))} "
                              f"(documented: {', '.join(sorted(known))})")


def _object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise BatchError(422, f"{where}: expected an object")
    return value


def _device(value: Any, where: str) -> str:
    if value is None or not str(value).strip():
        raise BatchError(422, f"{where} (device identifier) is required")
    text = str(value)
    if len(text) > 200:
        raise BatchError(422, f"{where}: longer than 200 characters")
    return text


# ---------------------------------------------------------------------------- OsmAnd, query form
OSMAND_QUERY = frozenset({
    "id", "deviceid", "timestamp", "lat", "lon", "location", "accuracy", "altitude", "speed",
    "bearing", "heading", "batt", "charge", "hdop", "valid", "alarm", "mock", "driverUniqueId",
    "motion", "event", "odometer"})
"""Parameters the OsmAnd protocol documents and Traccar Client sends (any other is a free
attribute in that protocol: ignored and listed)."""
MAX_PARAMS = 64


def osmand_query(pairs: list[tuple[str, str]]) -> Parsed:
    """A position of OsmAnd query / form parameters (``token`` already removed)."""
    if len(pairs) > MAX_PARAMS:
        raise BatchError(422, f"{len(pairs)} parameters; at most {MAX_PARAMS}")
    p: dict[str, str] = {}
    for k, v in pairs:
        if k in p:
            raise BatchError(422, f"parameter {k!r} given twice")
        p[k] = v
    ignored = tuple(sorted(set(p) - OSMAND_QUERY))
    device = _device(p.get("id", p.get("deviceid")), "id")
    if "location" in p and ("lat" in p or "lon" in p):
        raise BatchError(422, "send either location=lat,lon or lat and lon")
    lat_s, lon_s = p.get("lat"), p.get("lon")
    if "location" in p:
        lat_s, _, lon_s = p["location"].partition(",")
    lat, lon = _lat_lon(lat_s, lon_s, "lat", "lon")
    _check_finite(p, ("altitude", "speed", "bearing", "heading", "hdop"), "")
    time_unix = _time(p.get("timestamp"), "timestamp")
    if p.get("valid", "true").lower() in ("false", "0"):
        return Parsed(None, "valid=false: the app marks this position invalid", ignored)
    position = Position(device, time_unix, lat, lon, _accuracy(p.get("accuracy"), "accuracy"),
                        battery=_battery_percent(p.get("batt"), "batt"),
                        sos=p.get("alarm", "").lower() == "sos")
    return Parsed(position, None, ignored)


# ---------------------------------------------------------------------------- OsmAnd, JSON form
OSMAND_ROOT = frozenset({"location", "device_id"})
OSMAND_LOCATION = frozenset({
    "timestamp", "coords", "is_moving", "odometer", "event", "battery", "activity", "extras",
    "uuid", "age", "mock", "sample", "is_heartbeat", "provider", "geofence"})
OSMAND_COORDS = frozenset({
    "latitude", "longitude", "accuracy", "speed", "speed_accuracy", "heading",
    "heading_accuracy", "altitude", "ellipsoidal_altitude", "altitude_accuracy", "floor"})
"""Fields of Traccar Client's JSON (its location SDK's format); ``extras`` is free-form."""


def osmand_json(message: Any) -> Parsed:
    """A position of Traccar Client's JSON body ``{"device_id", "location": {...}}``."""
    root = _object(message, "body")
    _unknown(root, OSMAND_ROOT, "body")
    device = _device(root.get("device_id"), "device_id")
    if isinstance(root.get("location"), list):
        raise BatchError(422, "location: one location object per request")
    loc = _object(root.get("location"), "location")
    _unknown(loc, OSMAND_LOCATION, "location")
    coords = _object(loc.get("coords"), "location.coords")
    _unknown(coords, OSMAND_COORDS, "location.coords")
    lat, lon = _lat_lon(coords.get("latitude"), coords.get("longitude"),
                        "location.coords.latitude", "location.coords.longitude")
    _check_finite(coords, tuple(OSMAND_COORDS - {"latitude", "longitude", "accuracy"}),
                  "location.coords.")
    time_unix = _time(loc.get("timestamp"), "location.timestamp")
    battery = None
    if loc.get("battery") is not None:
        level = _object(loc["battery"], "location.battery").get("level")
        if level is not None:
            b = _number(level, "location.battery.level", hi=1.0)
            battery = None if b < 0 else b   # -1: unknown
    accuracy = _accuracy(coords.get("accuracy"), "location.coords.accuracy")
    return Parsed(Position(device, time_unix, lat, lon, accuracy, battery=battery))


# ---------------------------------------------------------------------------- OwnTracks
OWNTRACKS_LOCATION = frozenset({
    "_type", "_id", "_http", "acc", "alt", "batt", "bs", "cog", "lat", "lon", "rad", "t", "tid",
    "tst", "vac", "vel", "p", "poi", "image", "imagename", "conn", "tag", "topic", "inregions",
    "inrids", "SSID", "BSSID", "created_at", "m", "source", "motionactivities"})
"""Fields of OwnTracks' ``location`` message (booklet, "JSON")."""


def owntracks(message: Any) -> Parsed:
    """A position of an OwnTracks HTTP-mode message; other ``_type`` s carry none."""
    msg = _object(message, "body")
    kind = msg.get("_type")
    if not isinstance(kind, str):
        raise BatchError(422, "_type is required (OwnTracks message)")
    if kind == "encrypted":
        raise BatchError(422, "_type encrypted: hrtls cannot decrypt OwnTracks payloads; clear "
                              "the app's encryption key (use HTTPS instead)")
    if kind != "location":
        return Parsed(None, f"_type {kind!r} carries no position")
    _unknown(msg, OWNTRACKS_LOCATION, "location")
    lat, lon = _lat_lon(msg.get("lat"), msg.get("lon"), "lat", "lon")
    _check_finite(msg, ("alt", "vac", "vel", "cog", "p", "rad", "created_at"), "")
    if isinstance(msg.get("tst"), str):
        raise BatchError(422, "tst: expected Unix seconds (a number)")
    time_unix = _time(msg.get("tst"), "tst")
    device = _device(msg.get("tid", msg.get("topic", "owntracks")), "tid")
    return Parsed(Position(device, time_unix, lat, lon, _accuracy(msg.get("acc"), "acc"),
                           battery=_battery_percent(msg.get("batt"), "batt")))


# ---------------------------------------------------------------------------- fixes, raw log
PROTOCOLS = {"osmand-query": "osmand", "osmand-json": "osmand", "owntracks": "owntracks"}
"""Envelope protocol -> raw-log source."""


def parse(protocol: str, text: str) -> Parsed:
    """The message ``text`` of ``protocol`` (an envelope's ``protocol``)."""
    if protocol == "osmand-query":
        return osmand_query(parse_qsl(text, keep_blank_values=True))
    try:
        value = json.loads(text, parse_constant=_reject_constant)
    except ValueError as exc:
        raise BatchError(400, f"body is not valid JSON: {exc}") from None
    return osmand_json(value) if protocol == "osmand-json" else owntracks(value)


def _reject_constant(name: str) -> None:
    raise ValueError(f"{name} is not a finite number")


def query_text(pairs: list[tuple[str, str]]) -> str:
    """OsmAnd parameters as stored (``token`` removed: secrets stay out of the log)."""
    return urlencode([(k, v) for k, v in pairs if k != "token"])


def fix_batch(position: Position, *, seq: int, t0_unix: float,
              georeference: dict[str, Any]) -> Batch:
    """The batch holding ``position`` as a fix in mission metres and mission time."""
    geo = GeoreferenceModel.model_validate(georeference).to_georeference()
    xyz = geo.from_wgs84(position.lat_deg, position.lon_deg)[0]
    value: dict[str, Any] = {
        "seq": seq, "sos": position.sos,
        "fixes": {"t": [position.time_unix - t0_unix], "x": [float(xyz[0])],
                  "y": [float(xyz[1])], "sigma_m": [position.accuracy_m
                                                    * PARAMS.accuracy_to_sigma]}}
    if position.battery is not None:
        value["status"] = {"battery": position.battery}
    return parse_batch(value)


def envelope(protocol: str, text: str, *, seq: int, t0_unix: float,
             georeference: dict[str, Any]) -> bytes:
    """The raw-log body of a position message."""
    return json.dumps({"protocol": protocol, "seq": seq, "t0_unix": t0_unix,
                       "georeference": georeference, "message": text},
                      sort_keys=True).encode()


def decode_position(body: bytes, content_type: str) -> Batch:
    """Raw-log decoder of stored positions (sources ``osmand`` and ``owntracks``)."""
    env = json.loads(body)
    parsed = parse(env["protocol"], env["message"])
    assert parsed.position is not None, "only positions are stored"
    return fix_batch(parsed.position, seq=env["seq"], t0_unix=env["t0_unix"],
                     georeference=env["georeference"])


def same_position(body: bytes, position: Position) -> bool:
    """Whether a stored envelope holds ``position`` (same device time and coordinates)."""
    env = json.loads(body)
    stored = parse(env["protocol"], env["message"]).position
    return stored is not None and (stored.time_unix, stored.lat_deg, stored.lon_deg) == (
        position.time_unix, position.lat_deg, position.lon_deg)


def iso_time(t_unix: float) -> str:
    """ISO 8601 UTC of a Unix time (for messages)."""
    return datetime.fromtimestamp(t_unix, UTC).isoformat()
