"""Byte form of a :class:`~hrtls.mission.tracker.MissionTracker`: snapshot and restore.

The bytes are the tracker codec of :mod:`hrtls.pipeline.snapshot` (versioned header, zstd of
msgpack of plain values and raw arrays; nothing is pickled) holding a mapping with
``"format": "hrtls-mission"`` and its own ``"mission_version"``. Inside: the mission's
parameters, each agent's header (metadata, landmarks as JSON), each rescuer's
:meth:`hrtls.pipeline.Tracker.snapshot` bytes, each robot's EKF state, the agents' buffered data
not yet processed, and the node side (readings, estimates, history, who contributed and who
uses which node, loop closures, each agent's ranges pending until its rows cover them, the
agents' floor logs, the readings' and nodes' floors), and the ranges between nodes (buffered
and processed, :mod:`hrtls.mission.network_feed`; none in a snapshot made before them).
Version 3 (before floors) still restores: its readings and nodes are on floor 0 and its
agents' floor logs start empty (floor 0).

A restored mission continues exactly as the original would: the same windows, node estimates
and agent rows. The agents' rows produced before the snapshot are not in it (the service stores
rows as they come; :meth:`MissionTracker.result` of a restored mission holds the rows after it).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from hrtls.data import Landmark, Session
from hrtls.data.observations import (
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.data.session import SessionMeta
from hrtls.errors import FormatError
from hrtls.mission import bridge, network_feed, smoothing
from hrtls.mission.floors import FloorLog
from hrtls.mission.graph import SmootherParams
from hrtls.mission.nodes import NodeEstimate, NodeEstimatorParams
from hrtls.mission.provenance import Provenance
from hrtls.mission.readings import NodeReadings
from hrtls.mission.robot import RobotTracker
from hrtls.pipeline import snapshot as codec
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import Tracker

FORMAT = "hrtls-mission"
MISSION_VERSION = 4
READABLE_VERSIONS = (3, 4)
"""Layout of the mission mapping written by :func:`mission_snapshot`."""

_ESTIMATE_FIELDS = tuple(f.name for f in dataclasses.fields(NodeEstimate))


def _lm(values: Any) -> Any:
    """Landmarks (a mapping, a sequence or one) as JSON-ready values."""
    if isinstance(values, Landmark):
        return values.model_dump(mode="json")
    if isinstance(values, dict):
        return {k: _lm(v) for k, v in values.items()}
    return [_lm(v) for v in values]


def _session_state(s: Session | None) -> dict[str, Any] | None:
    """The data of a buffered part (metadata and landmarks are the agent's header)."""
    if s is None:
        return None
    d: dict[str, Any] = {}
    if s.imu is not None:
        d["imu"] = [s.imu.accel.t, s.imu.accel.values,
                    None if s.imu.gyro is None else s.imu.gyro.values,
                    None if s.imu.mag is None else s.imu.mag.values]
    if s.pressure is not None:
        d["pressure"] = [s.pressure.t, s.pressure.values, s.pressure.name]
    if s.orientation is not None:
        d["orientation"] = [s.orientation.t, s.orientation.q, s.orientation.name]
    if s.fixes is not None:
        f = s.fixes
        d["fixes"] = [f.t, f.xyz, f.sigma_m, f.has_z, f.name]
    if s.rss is not None:
        d["rss"] = [s.rss.t, s.rss.anchor.astype(str), s.rss.rss_dbm, s.rss.name]
    if s.tags is not None:
        d["tags"] = [s.tags.t, s.tags.tag.astype(str), s.tags.name]
    if s.ranges is not None:
        r = s.ranges
        d["ranges"] = [r.t, r.node.astype(str), r.range_m, r.sigma_m, r.name]
    return d


def _session_from(d: dict[str, Any] | None, meta: SessionMeta,
                  landmarks: dict[str, Landmark]) -> Session | None:
    if d is None:
        return None
    parts: dict[str, Any] = {}
    if "imu" in d:
        t, acc, gyr, mag = d["imu"]
        parts["imu"] = ImuStream(SensorSeries(t, acc, "accelerometer"),
                                 None if gyr is None else SensorSeries(t, gyr, "gyroscope"),
                                 None if mag is None else SensorSeries(t, mag, "magnetometer"),
                                 check_units=False)
    if "pressure" in d:
        parts["pressure"] = SensorSeries(*d["pressure"])
    if "orientation" in d:
        parts["orientation"] = OrientationSeries(*d["orientation"])
    if "fixes" in d:
        parts["fixes"] = PositionFixes(*d["fixes"])
    if "rss" in d:
        parts["rss"] = RssReadings(*d["rss"])
    if "tags" in d:
        parts["tags"] = TagDetections(*d["tags"])
    if "ranges" in d:
        parts["ranges"] = RangeMeasurements(*d["ranges"])
    return Session(meta=meta, landmarks=landmarks, **parts)


def _tracker_state(tr: Tracker | RobotTracker, started: bool) -> dict[str, Any]:
    if not started:
        return {"started": False}
    if isinstance(tr, Tracker):
        return {"started": True, "tracker": tr.snapshot()}
    return {"started": True, **tr.state()}


def _tracker_from(d: dict[str, Any], kind: str, config: TrackerConfig | None
                  ) -> Tracker | RobotTracker:
    if not d["started"]:
        return RobotTracker() if kind == "robot" else Tracker(config)
    if kind == "rescuer":
        return Tracker.restore(d["tracker"])
    return RobotTracker.from_state(d)


def _deferred(ops: list[tuple[str, object]]) -> list[list[Any]]:
    return [[method, _lm(arg)] for method, arg in ops]


def _deferred_from(ops: list[list[Any]]) -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    for method, arg in ops:
        if isinstance(arg, dict):
            out.append((method, {k: Landmark.model_validate(v) for k, v in arg.items()}))
        else:
            out.append((method, [Landmark.model_validate(v) for v in arg]))
    return out


def _nodes_state(mt: Any) -> dict[str, Any]:
    """The node side of the mission (readings, estimates, history, bookkeeping)."""
    return {
        "readings": {n: [np.asarray(r.agent, dtype=np.int64), np.asarray(r.t),
                         np.asarray(r.xy).reshape(-1, 2), np.asarray(r.cov).reshape(-1, 2, 2),
                         np.asarray(r.r), np.asarray(r.s), np.asarray(r.floor, dtype=np.int64)]
                     for n, r in mt.readings.items()},
        "estimates": {n: [getattr(e, f) for f in _ESTIMATE_FIELDS]
                      for n, e in mt.estimates.items()},
        "contrib": {n: sorted(v) for n, v in mt.contrib.items()},
        "users": {n: sorted(v) for n, v in mt.users.items()},
        "given": {str(i): g for i, g in mt.given.items()},
        "history": {n: [list(h) for h in rows] for n, rows in mt.history.items()},
        "version": mt.versions, "estimated_at": mt.estimated_at,
        "contrib_trace": [[i, n, v] for (i, n), v in mt.contrib_trace.items()],
        "closures": [dataclasses.astuple(c) for c in mt.closures],
        "provenance": mt.prov.state(),
        "peer_use": [[i, n, t, c] for (i, n), (t, c) in mt.peers.uses.items()],
        "pending": {k: None if r is None else [r.t, r.node.astype(str), r.range_m, r.sigma_m]
                    for k, r in mt.pending.items()},
        "floor_logs": {k: [log.t, log.floor] for k, log in mt.floor_logs.items()},
        "node_floor": dict(mt.node_floor),
    }


def _restore_nodes(mt: Any, d: dict[str, Any]) -> None:
    from hrtls.mission.peers import PeerUses
    from hrtls.mission.tracker import LoopClosure

    for n, (a, t, xy, cov, r, s, *fl) in d["readings"].items():
        mt.readings[n] = NodeReadings(a.tolist(), t.tolist(), list(xy), list(cov),
                                       r.tolist(), s.tolist(),
                                       fl[0].tolist() if fl else [0] * len(t))
    mt.estimates = {n: NodeEstimate(*v) for n, v in d["estimates"].items()}
    mt.contrib = {n: set(v) for n, v in d["contrib"].items()}
    mt.users = {n: set(v) for n, v in d["users"].items()}
    mt.given = {int(i): dict(g) for i, g in d["given"].items()}
    mt.history = {n: [(float(h[0]), h[1], h[2]) for h in rows]
                  for n, rows in d["history"].items()}
    mt.versions = dict(d["version"])
    mt.estimated_at = dict(d["estimated_at"])
    mt.contrib_trace = {(int(i), n): float(v) for i, n, v in d["contrib_trace"]}
    mt.closures = [LoopClosure(*c) for c in d["closures"]]
    mt.prov = Provenance.from_state(d["provenance"])
    mt.peers = PeerUses({(int(i), n): (float(t), int(c))
                         for i, n, t, c in d.get("peer_use", [])})
    mt.pending = {k: None if r is None else RangeMeasurements(*r)
                   for k, r in d["pending"].items()}
    mt.floor_logs = {k: FloorLog([float(v) for v in t], [int(v) for v in f])
                     for k, (t, f) in d.get("floor_logs", {}).items()} or mt.floor_logs
    mt.node_floor = {n: int(f) for n, f in
                     d.get("node_floor", dict.fromkeys(mt.estimates, 0)).items()}


def mission_snapshot(mt: Any) -> bytes:
    """The state of ``mt`` (a :class:`~hrtls.mission.tracker.MissionTracker`) as bytes."""
    prm = dataclasses.asdict(mt.params)
    state = {
        "format": FORMAT, "mission_version": MISSION_VERSION, "params": prm,
        "config": None if mt.config is None else mt.config.model_dump(mode="json"),
        "names": list(mt.names), "kinds": dict(mt.kinds),
        "headers": {k: [h.meta.model_dump(mode="json"), _lm(h.landmarks)]
                    for k, h in mt.headers.items()},
        "landmark_updates": _lm(list(mt.landmark_updates)),
        "robot_updates": _lm(list(mt.robot_updates)),
        "trackers": {k: _tracker_state(tr, k in mt.started) for k, tr in mt.trackers.items()},
        "deferred": {k: _deferred(v) for k, v in mt.deferred.items()},
        "buffers": {k: [_session_state(b.data), b.t_first, b.t_last, b.heard_s, b.ended]
                    for k, b in mt.buffers.items()},
        "t0": mt.t0, "horizon_s": mt.horizon_s, "k": mt.window_index,
        "last_t": dict(mt.rows_pulled_s),
        "rows": {k: [list(r) for r in rows] for k, rows in mt.recent_rows.items()},
        "nodes": _nodes_state(mt),
        "smoother": smoothing.state_of(mt.smoother),
        "bridge": bridge.state_of(mt.bridge),
        "network": network_feed.state_of(mt.network),
    }
    return codec.pack(state)


def restore_mission(data: bytes) -> Any:
    """The :class:`~hrtls.mission.tracker.MissionTracker` of :func:`mission_snapshot` bytes."""
    from hrtls.mission.peers import PeerRangeParams
    from hrtls.mission.tracker import AgentHeader, MissionParams, MissionTracker

    d = codec.unpack(data)
    if d.get("format") != FORMAT:
        raise FormatError(f"format {d.get('format')!r}", where="mission snapshot",
                          expected="bytes from MissionTracker.snapshot()")
    if d.get("mission_version") not in READABLE_VERSIONS:
        raise FormatError(f"mission snapshot version {d.get('mission_version')}",
                          where="mission snapshot",
                          expected="version " + " or ".join(map(str, READABLE_VERSIONS)))
    try:
        prm = dict(d["params"])
        prm["nodes"] = NodeEstimatorParams(**prm["nodes"])
        prm["peer_ranges"] = PeerRangeParams(**prm.get("peer_ranges", {}))
        if prm.get("smoother") is not None:
            prm["smoother"] = SmootherParams(**prm["smoother"])
        config = None if d["config"] is None else TrackerConfig.model_validate(d["config"])
        headers = {k: AgentHeader(SessionMeta.model_validate(m),
                                  {i: Landmark.model_validate(v) for i, v in lms.items()})
                   for k, (m, lms) in d["headers"].items()}
        mt = MissionTracker({k: headers[k] for k in d["names"]}, config=config,
                            params=MissionParams(**prm), kinds=d["kinds"],
                            landmark_updates=[Landmark.model_validate(v)
                                              for v in d["landmark_updates"]])
        mt.robot_updates = [Landmark.model_validate(v) for v in d["robot_updates"]]
        for k, st in d["trackers"].items():
            mt.trackers[k] = _tracker_from(st, mt.kinds[k], config)
            if st["started"]:
                mt.started.add(k)
        mt.deferred = {k: _deferred_from(v) for k, v in d["deferred"].items()}
        for k, (data_state, t_first, t_last, heard, ended) in d["buffers"].items():
            b = mt.buffers[k]
            b.data = _session_from(data_state, headers[k].meta, headers[k].landmarks)
            b.t_first, b.t_last, b.heard_s, b.ended = t_first, t_last, heard, ended
        mt.t0 = d["t0"]
        mt.horizon_s = float(d["horizon_s"]) if d["horizon_s"] is not None else -math.inf
        mt.window_index = int(d["k"])
        mt.rows_pulled_s = dict(d["last_t"])
        mt.recent_rows = {k: [tuple(r) for r in rows] for k, rows in d["rows"].items()}
        _restore_nodes(mt, d["nodes"])
        mt.smoother = smoothing.state_from(d.get("smoother"))
        mt.bridge = bridge.state_from(d.get("bridge"))
        mt.network = network_feed.state_from(d.get("network"))
    except (KeyError, TypeError, ValueError) as exc:
        raise FormatError(f"incomplete mission snapshot ({exc!r})", where="mission snapshot",
                          expected="bytes from MissionTracker.snapshot()") from None
    return mt
