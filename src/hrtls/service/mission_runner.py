"""The mission estimator live, in the service process.

One :class:`~hrtls.mission.tracker.MissionTracker` per mission that declared a sensor network
(``PUT /missions/{id}/network``).

A thread polls the raw log every ``poll_s``: the batches stored since the last poll (in the
order they were stored, the order the raw log commits them) are decoded into session parts
(:mod:`hrtls.service.decoders`) and fed to the mission estimator, which then processes every
complete window (:meth:`MissionTracker.advance`, silence judged on the wall clock). The
ranges the dropped nodes measured between themselves (``POST /missions/{id}/network/ranges``,
the ``network_range_batches`` log) are fed the same way, after the agents' batches. The nodes
re-localized, and every node whose readings grew (heard but not localized, or no longer
localized), go to the mission's ``mission_networks`` row (the network and infrastructure
endpoints, the live picture, ``hrtls mission export``) and to the dashboards' deltas
(``nodes``), each with its state as the estimator has it now.

Every ``snapshot_every_s`` of processed mission time the estimator's state is stored in
``mission_snapshots`` with the id of the newest raw batch it consumed; after a restart the
newest snapshot is restored and the raw log replayed after that id, so every batch is fed
exactly once. Without a snapshot the whole raw log of the mission is replayed.

A closed mission (``PATCH /missions/{id}`` ``status: closed``) has ended: its last windows
are processed.

Landmark versions written during the mission (``hrtls.service.landmark_versions``) are given to
the estimator at the next poll, each from its time on; one older than the processed horizon is
counted and logged, not used (the host's per-agent trackers re-run instead).

Limits: the agents are those of the mission when its estimator starts (an agent created later
is not part of it); data older than the processed horizon (back-fill after a radio gap longer
than the window wait) are late: counted, logged, not used.
"""

from __future__ import annotations

import logging
import math
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sqlalchemy import delete, select
from sqlalchemy.orm import Session as DbSession
from sqlalchemy.orm import sessionmaker

from hrtls.data import Landmark
from hrtls.data.session import SessionMeta
from hrtls.errors import FormatError
from hrtls.mission.nodes import NodeEstimate
from hrtls.mission.smoother_modes import smoother_params
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionTracker
from hrtls.pipeline import preset
from hrtls.service.clock import Clock
from hrtls.service.decoders import raw_part
from hrtls.service.hub import Hub
from hrtls.service.landmark_versions import versions_of
from hrtls.service.models import Agent, Mission, MissionNetwork, MissionSnapshot, RawBatch
from hrtls.service.network_log import batches_after, newest_id

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class MissionRunnerParams:
    """Tuning of :class:`MissionRunner`.

    ``poll_s``: raw-log poll period, s; ``snapshot_every_s``: processed mission time between
    snapshots, s; ``keep_snapshots``: snapshots kept per mission; ``page``: raw batches read
    per query.
    """

    poll_s: float = 0.2
    snapshot_every_s: float = 30.0
    keep_snapshots: int = 5
    page: int = 500


@dataclass
class LiveMission:
    """The estimator of one mission and how far it read the raw log."""

    mission_id: int
    tracker: MissionTracker
    agents: dict[int, str]
    raw_id: int = 0
    net_raw_id: int = 0
    """Newest ``network_range_batches`` id consumed."""
    t_snap: float = -math.inf
    late_samples: int = 0
    late_versions: set[tuple[str, float | None]] = field(default_factory=set)
    """Landmark versions (id, time) older than the horizon when they came: not used."""
    restored_horizon_s: float | None = None
    """Processed horizon of the snapshot it was restored from (None: started new)."""
    declared: frozenset[str] = frozenset()
    """Ids of the declared network."""
    published: dict[str, int] = field(default_factory=dict)
    """Readings count of each node when its state was last published."""
    lock: threading.Lock = field(default_factory=threading.Lock)


def node_json(node: str, est: NodeEstimate | None, *, readings: int, passes: int,
              t_s: float, floor: int = 0) -> dict[str, Any]:
    """A node's state as stored and published (planar: no z; its floor when localized).

    ``floor``: the mission's floor of the node (:mod:`hrtls.mission.floors`); ``est`` None:
    heard, not yet estimated (too few readings); ``passes``: groups of readings sharing one
    agent error (:meth:`NodeReadings.ranges`); ``t_s``: mission time of the window
    end the state is from (for a localized node, that of its newest estimate).
    """
    ok = est is not None and bool(est.localized)
    cov = None if est is None else np.asarray(est.covariance_m2)
    return {"id": node, "localized": ok,
            "reason": "too few readings to estimate" if est is None else est.reason,
            "readings": readings, "passes": passes, "t": t_s,
            "position": [float(v) for v in est.position_m] if ok and est is not None else None,
            "covariance_m2": cov.tolist() if ok and cov is not None else None,
            "sigma_m": float(np.sqrt(np.linalg.eigvalsh(cov)[-1]))
            if ok and cov is not None else None,
            "floor": floor if ok else None, "seed": False}


def mission_params(values: dict[str, Any]) -> MissionParams:
    """A mission network's stored parameters as the estimator's (``smoother`` by mode name)."""
    v = dict(values)
    if "smoother" in v:
        v["smoother"] = smoother_params(str(v["smoother"]))
    return MissionParams(**v)


def network_nodes(db: DbSession, mission_id: int) -> list[dict[str, Any]] | None:
    """Declared and heard nodes with their newest states (None without a network).

    ``declared``: the node is in the declared network (a heard one may not be); a declared
    node never heard has ``readings`` 0 and ``t`` None.
    """
    net = db.get(MissionNetwork, mission_id)
    if net is None:
        return None
    est = dict(net.estimates)
    declared = set(net.nodes)
    ids = list(net.nodes) + sorted(set(est) - declared)
    blank = {"localized": False, "reason": "never heard", "readings": 0, "passes": 0,
             "t": None, "position": None, "covariance_m2": None, "sigma_m": None,
             "floor": None, "seed": False}
    return [{**est.get(n, {"id": n, **blank}), "declared": n in declared} for n in ids]


def _header(agent: Agent, mission: Mission, landmarks: dict[str, Landmark]) -> AgentHeader:
    meta = SessionMeta.model_validate({
        "start_pose": agent.start_pose, "placement": agent.placement,
        "mounting_q_bd": agent.mounting_q_bd, "user": agent.user,
        "floor_height_m": mission.floor_height_m, "channel": mission.channel,
        "georeference": mission.georeference})
    return AgentHeader(meta, landmarks)


class MissionRunner:
    """The mission estimators of the networked missions, fed from the raw log (module doc)."""

    def __init__(self, *, sessions: sessionmaker[DbSession], clock: Clock, hub: Hub,
                 params: MissionRunnerParams | None = None) -> None:
        self.sessions = sessions
        self.clock = clock
        self.hub = hub
        self.params = params or MissionRunnerParams()
        self.missions: dict[int, LiveMission] = {}
        self.errors: dict[int, str] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start polling (restores each networked mission from its newest snapshot)."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, name="hrtls-missions", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop polling (the raw log keeps what was not consumed)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=30)
            self._thread = None

    def _loop(self) -> None:
        while not self._stop.wait(self.params.poll_s):
            try:
                self.poll()
            except Exception:
                log.exception("mission estimator poll failed")

    def poll(self) -> None:
        """One round: every networked mission consumes its new batches and advances."""
        with self.sessions() as db:
            ids = list(db.scalars(select(MissionNetwork.mission_id)))
        for mission_id in ids:
            try:
                self._poll_mission(mission_id)
            except Exception as exc:
                log.exception("mission estimator of mission %s failed", mission_id)
                self.errors[mission_id] = f"{type(exc).__name__}: {exc}"

    def _poll_mission(self, mission_id: int) -> None:
        lm = self.missions.get(mission_id)
        if lm is None:
            lm = self._open(mission_id)
            if lm is None:
                return
            self.missions[mission_id] = lm
        with self.sessions() as db:
            closed = db.scalar(select(Mission.status).where(Mission.id == mission_id)) \
                == "closed"
            _, timed = versions_of(db, mission_id)
        with lm.lock:
            self._versions(lm, timed)
            self._consume(lm)
            progress = lm.tracker.advance(now_s=self.clock(), final=closed)
            self._publish(lm, progress.changed)
            if lm.tracker.horizon_s - lm.t_snap >= self.params.snapshot_every_s:
                self._snapshot(lm)

    def _open(self, mission_id: int) -> LiveMission | None:
        """The mission's estimator from its newest snapshot, else new (None: no agents)."""
        with self.sessions() as db:
            snap = db.scalars(select(MissionSnapshot).where(
                MissionSnapshot.mission_id == mission_id)
                .order_by(MissionSnapshot.horizon_s.desc(), MissionSnapshot.id.desc())).first()
            names = {aid: str(aid) for aid in db.scalars(
                select(Agent.id).where(Agent.mission_id == mission_id).order_by(Agent.id))}
            net = db.get(MissionNetwork, mission_id)
            declared = frozenset(net.nodes) if net is not None else frozenset()
        if snap is not None:
            try:
                tracker = MissionTracker.restore(snap.state)
            except FormatError as exc:    # e.g. written by an older version
                log.warning("mission %s: snapshot not restorable (%s); replaying the raw log "
                            "from the start", mission_id, exc)
                return self._open_new(mission_id)
            for buf in tracker.buffers.values():   # the service was down, not the agents
                buf.heard_s = max(buf.heard_s, self.clock())
            if set(tracker.names) == set(names.values()):
                return LiveMission(mission_id, tracker, names, raw_id=snap.raw_id,
                                   net_raw_id=snap.net_raw_id, t_snap=snap.horizon_s,
                                   restored_horizon_s=snap.horizon_s, declared=declared)
            log.warning("mission %s: snapshot agents differ; starting over", mission_id)
        return self._open_new(mission_id)

    def _open_new(self, mission_id: int) -> LiveMission | None:
        """A new estimator of the mission's agents (None without a network or agents)."""
        with self.sessions() as db:
            net = db.get(MissionNetwork, mission_id)
            mission = db.get(Mission, mission_id)
            agents = list(db.scalars(select(Agent).where(Agent.mission_id == mission_id)
                                     .order_by(Agent.id)))
            if net is None or mission is None or not agents:
                return None
            names = {a.id: str(a.id) for a in agents}
            start, timed = versions_of(db, mission_id)
            landmarks = {d["id"]: Landmark.model_validate(d) for d in start}
            kinds = {str(a.id): "robot" if a.kind == "robot" else "rescuer" for a in agents}
            rescuers = [a for a in agents if a.kind != "robot"]
            config = preset(rescuers[0].preset) if rescuers else None
            tracker = MissionTracker(
                {str(a.id): _header(a, mission, landmarks) for a in agents}, config=config,
                params=mission_params(net.params), kinds=kinds,
                landmark_updates=[Landmark.model_validate(d) for d in timed],
                now_s=self.clock())
            declared = frozenset(net.nodes)
        return LiveMission(mission_id, tracker, names, declared=declared)

    def _versions(self, lm: LiveMission, timed: tuple[dict[str, Any], ...]) -> None:
        """Give the estimator the landmark versions written since it started."""
        seen = {(v.id, v.updated) for v in lm.tracker.landmark_updates} | lm.late_versions
        new = [lm_ for d in timed if ((lm_ := Landmark.model_validate(d)).id, lm_.updated)
               not in seen]
        if not new:
            return
        late = lm.tracker.add_landmark_updates(new)
        lm.late_versions |= {(v.id, v.updated) for v in late}
        for v in late:
            log.warning("mission %s: landmark %s version of %.1f s is before the processed "
                        "horizon %.1f s; not used", lm.mission_id, v.id, v.updated or 0.0,
                        lm.tracker.horizon_s)

    def _consume(self, lm: LiveMission) -> None:
        """Feed the batches stored since the last poll, in raw-log order, then the node ranges."""
        ids = list(lm.agents)
        while True:
            with self.sessions() as db:
                page = db.execute(
                    select(RawBatch.id, RawBatch.agent_id, RawBatch.source,
                           RawBatch.content_type, RawBatch.body)
                    .where(RawBatch.agent_id.in_(ids), RawBatch.id > lm.raw_id,
                           RawBatch.t_first.is_not(None))
                    .order_by(RawBatch.id).limit(self.params.page)).all()
                fresh = {a for a in {r.agent_id for r in page}
                         if lm.agents[a] not in lm.tracker.started}
                rows = {a.id: a for a in db.scalars(select(Agent).where(Agent.id.in_(fresh)))}
                mission = db.get(Mission, lm.mission_id) if fresh else None
            for aid, row in rows.items():   # check-in may come after the estimator started
                name = lm.agents[aid]
                assert mission is not None
                lm.tracker.headers[name] = _header(row, mission,
                                                   lm.tracker.headers[name].landmarks)
            now = self.clock()
            for r in page:
                name = lm.agents[r.agent_id]
                part = raw_part(r.source, r.content_type, r.body, lm.tracker.headers[name])
                if part is not None:
                    late = lm.tracker.feed(name, part, now_s=now)
                    if late is not None:
                        lm.late_samples += late.samples
                        log.warning("mission %s agent %s: %d samples older than the processed "
                                    "horizon %.1f s not used", lm.mission_id, name, late.samples,
                                    late.horizon_s)
                lm.raw_id = r.id
            if len(page) < self.params.page:
                break
        self._consume_network(lm)

    def _consume_network(self, lm: LiveMission) -> None:
        """Feed the node-to-node ranges stored since the last poll, in log order."""
        while True:
            with self.sessions() as db:
                page = batches_after(db, lm.mission_id, lm.net_raw_id, limit=self.params.page)
            now = self.clock()
            for batch_id, ranges in page:
                late = lm.tracker.feed_network(ranges, now_s=now)
                if late is not None:
                    lm.late_samples += late.samples
                    log.warning("mission %s: %d node-to-node ranges older than the processed "
                                "horizon %.1f s not used", lm.mission_id, late.samples,
                                late.horizon_s)
                lm.net_raw_id = batch_id
            if len(page) < self.params.page:
                return

    def _publish(self, lm: LiveMission, changed: tuple[str, ...]) -> None:
        """Store and push the nodes re-localized, and every node whose readings changed."""
        tr = lm.tracker
        counts = {n: len(r.r) for n, r in tr.readings.items()}
        nodes = set(changed) | {n for n, k in counts.items() if lm.published.get(n) != k}
        if not nodes:
            return
        items = {}
        for n in sorted(nodes):
            est = tr.estimates.get(n)
            hist = tr.history.get(n)
            t_s = hist[-1][0] if est is not None and est.localized and hist else tr.horizon_s
            passes = len(np.unique(tr.readings[n].ranges(tr.params.pass_gap_s).group))
            items[n] = node_json(n, est, readings=counts[n], passes=passes, t_s=t_s,
                                 floor=tr.node_floor.get(n, 0))
        with self.sessions() as db, db.begin():
            net = db.get(MissionNetwork, lm.mission_id)
            if net is None:
                return
            net.estimates = {**net.estimates, **items}
            net.horizon_s = tr.horizon_s
        lm.published.update({n: counts[n] for n in items})
        for n, item in items.items():
            self.hub.add(lm.mission_id, "nodes", {**item, "declared": n in lm.declared})

    def _snapshot(self, lm: LiveMission) -> None:
        """Store the estimator's state; keep the newest ``keep_snapshots``."""
        state = lm.tracker.snapshot()
        with self.sessions() as db, db.begin():
            db.add(MissionSnapshot(mission_id=lm.mission_id, horizon_s=lm.tracker.horizon_s,
                                   raw_id=lm.raw_id, net_raw_id=lm.net_raw_id,
                                   created_unix=self.clock(), state=state))
            db.flush()
            old = list(db.scalars(select(MissionSnapshot.id).where(
                MissionSnapshot.mission_id == lm.mission_id)
                .order_by(MissionSnapshot.horizon_s.desc(), MissionSnapshot.id.desc())
                .offset(self.params.keep_snapshots)))
            if old:
                db.execute(delete(MissionSnapshot).where(MissionSnapshot.id.in_(old)))
        lm.t_snap = lm.tracker.horizon_s

    def caught_up(self, mission_id: int) -> bool:
        """Whether the mission's estimator consumed every stored batch of its agents."""
        lm = self.missions.get(mission_id)
        if lm is None:
            return False
        with self.sessions() as db:
            newest = db.scalars(select(RawBatch.id).where(RawBatch.agent_id.in_(list(lm.agents)))
                                .order_by(RawBatch.id.desc()).limit(1)).first()
            net_newest = newest_id(db, mission_id)
        return (newest is None or newest <= lm.raw_id) and net_newest <= lm.net_raw_id


def offline_tracker(sessions: sessionmaker[DbSession], mission_id: int) -> MissionTracker:
    """The mission's estimator fed the whole raw log at once (as offline), not yet run.

    Every stored batch of the mission's agents, in raw-log order, with the agents' headers as
    they are now, and every stored node-to-node range; :meth:`MissionTracker.run` then gives
    what ``hrtls mission track`` gives on the same data.
    """
    runner = MissionRunner(sessions=sessions, clock=lambda: 0.0, hub=Hub())
    lm = runner._open_new(mission_id)
    if lm is None:
        raise KeyError(mission_id)
    runner._consume(lm)
    return lm.tracker
