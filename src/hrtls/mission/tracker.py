"""Mission tracker: every agent's causal tracker plus the dropped network, in one loop.

Each agent runs its own causal tracker, chunk by chunk: :class:`hrtls.pipeline.Tracker` for a
rescuer, :class:`hrtls.mission.robot.RobotTracker` (odometry + range EKF) for a robot. Time
advances in common windows of ``chunk_s``; in a window each agent's ranges go one of three ways:

* to a node whose position the agent's session knows (a landmark with a position): the range
  corrects the agent's tracker as in ``hrtls track``, and is never a reading of a node;
* to a node the agent may **use**: the range corrects the agent's tracker (the node is one of its
  landmarks), its sigma widened to ``sqrt(sigma^2 + a c lambda_max(P_node))``: the node's error
  is one and the same for every range of the agent's pass, and its filter takes each range as
  independent; ``a = (N_before + 1)(N_after + 1)``, ``N`` the ranges it used from that node in
  the pass before / after this window, keeps the pass's information from the node below one
  range's with the node's variance, whatever the correlation (:mod:`hrtls.mission.provenance`);
  ``c`` is 2 when the agent's own error is inside the node's (it read the node, or a node that
  corrected an agent that read it), else 1;
* otherwise the range is kept, with the agent's estimate and covariance at the reading's time,
  as a reading of that node for :class:`hrtls.mission.nodes.NodeEstimator` (a range later than
  the agent's latest row waits for it, :mod:`hrtls.mission.readings`).

Double counting. The node's error and the error of an agent that contributed to it are
correlated (the agent's error at its readings is inside the node's estimate), so by default an
agent that contributed to a node keeps contributing and does not use it, and an agent that uses a
node never contributes to it. The one exception is a loop closure: a contributor may use the node
once its own covariance has grown ``loop_closure_ratio`` times (trace) beyond the smallest it had
at its readings of that node. Scalar reasoning, agent error ``e2 = e1 + d`` now (``var P2 =
P1 + D``), node error ``e1 + v``: the filter's update taking the node as independent with variance
``a * P1`` claims a posterior variance ``P2 a P1 / (P2 + a P1)`` while the true one is
``P1 + (a P1 / (P2 + a P1))^2 D``; with ``a = 2`` (the node's variance doubled for its
contributors) the two agree at ``P2 = 4 P1`` and the claim is conservative beyond. Passes of
different agents are taken as partly correlated in the node estimate (``agent_correlation``). A
second-order loop (A localizes n, B corrected by n localizes m, A uses m) gets ``c = 2`` as a
loop closure does (:mod:`hrtls.mission.provenance` tracks whose errors are in which estimate).

After every window the re-estimated nodes go to every agent (``Tracker.set_landmarks``; the
smoother's, on by default, replace those it localizes; a robot gets none unless
``SmootherParams.robots`` is "nodes"); which ranges reach a filter is decided here and by
:func:`hrtls.mission.smoothing.via_feedback`. Floors (:mod:`hrtls.mission.floors`): a reading
keeps its agent's causal floor, a node is estimated from the readings of its floor (most of
them) and given with it, and an agent uses a node only while on its floor.
With ``cooperate=False`` no node is ever given to an agent (each agent alone). Ranges to
other agents (node id = an agent's name) go to :mod:`hrtls.mission.peers` (with cooperation).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session
from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements
from hrtls.data.session import SessionMeta
from hrtls.errors import InputError
from hrtls.mission import bridge, network_feed, smoothing
from hrtls.mission.buffer import AgentBuffer, LateData, startable, window_complete
from hrtls.mission.floors import FloorLog, building_floor_height_m, node_floor
from hrtls.mission.graph import SmootherParams
from hrtls.mission.network_ranges import NetworkRanges
from hrtls.mission.nodes import NodeEstimate, NodeEstimator, NodeEstimatorParams, largest_variance
from hrtls.mission.peers import PeerRangeParams, PeerUses, merge_ranges, split_peer_ranges
from hrtls.mission.provenance import NodeUse, Provenance, UsePool, informative, widening
from hrtls.mission.readings import NodeReadings, Rows, join_ranges, merge_rows, split_at, trim_rows
from hrtls.mission.records import LoopClosure, NodeTrack, Progress
from hrtls.mission.robot import RobotTracker
from hrtls.mission.smoother_modes import default_smoother
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import Tracker, TrackResult

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class MissionParams:
    """Parameters of :class:`MissionTracker`.

    Attributes
    ----------
    chunk_s:
        Length of the common time window, s.
    pass_gap_s:
        Readings of one agent to one node more than this apart belong to different passes
        (each pass has its own agent error in the node estimator), s.
    refresh_fraction:
        A node is estimated again once its readings grew by this fraction (at least 3 new).
    cooperate:
        Give localized nodes to the agents (False: every agent alone).
    pass_cap:
        A pass's ranges to a node widened by ``a = (N_before + 1)(N_after + 1)`` and ``c = 2`` for
        second-order loops (module doc); False: ``a = N_after``, ``c = 2`` for contributors only
        (the earlier rule, over-counting a pass: :mod:`hrtls.mission.provenance`).
    loop_closure_ratio:
        A contributor uses a node once its covariance trace is this many times the smallest it
        had at its readings of the node (module doc; ``inf``: contributors never use it).
    use_variance_ratio:
        Information gate: an agent uses a node's ranges only while the node's claimed variance
        along the line of sight is at most this times the agent's own (its latest row), so a
        range carries information about the agent rather than about the node's error; a gated
        range is kept as a reading of the node (:func:`informative`). inf: no gate (0.3 opt-in).
    silent_after_s:
        Live (:meth:`MissionTracker.advance`): an agent whose latest part arrived longer ago
        than this (on the clock given to :meth:`MissionTracker.feed`) no longer holds the
        windows back; its data older than the processed horizon are then late, s.
    nodes, peer_ranges:
        Node estimator parameters; how a peer's estimate is carried to an inter-agent range.
    smoother:
        The range-SLAM smoother (:mod:`hrtls.mission.smoothing`), by default that of
        :data:`~hrtls.mission.smoother_modes.DEFAULT_MODE`; None: the per-node estimator alone.
    smooth_readings_s:
        Rescuers' readings at their smoothed positions, lag s (:mod:`hrtls.mission.bridge`); 0: off.
    """

    chunk_s: float = 5.0
    pass_gap_s: float = 15.0
    refresh_fraction: float = 0.2
    cooperate: bool = True
    pass_cap: bool = True
    loop_closure_ratio: float = 4.0
    use_variance_ratio: float = math.inf
    silent_after_s: float = 30.0
    nodes: NodeEstimatorParams = field(default_factory=NodeEstimatorParams)
    peer_ranges: PeerRangeParams = field(default_factory=PeerRangeParams)
    smoother: SmootherParams | None = field(default_factory=default_smoother)
    smooth_readings_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("chunk_s", "pass_gap_s", "silent_after_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} = {v}", where="MissionParams", expected="> 0 s")
        if not self.loop_closure_ratio >= 1.0:
            raise InputError(f"loop_closure_ratio = {self.loop_closure_ratio}",
                             where="MissionParams", expected=">= 1 (inf: never)")
        if not self.use_variance_ratio > 0.0:
            raise InputError(f"use_variance_ratio = {self.use_variance_ratio}",
                             where="MissionParams", expected="> 0 (inf: no gate)")


@dataclass(frozen=True, eq=False)
class MissionResult:
    """Per-agent results, the final node estimates and each node's history (localized rows).

    ``readings``: the ranges kept for each node's estimate, all agents; ``closures``: the loop
    closures (contributors starting to use a node they fed); ``uses``: every agent's uses of
    the nodes (:mod:`hrtls.mission.provenance`).
    """

    agents: dict[str, TrackResult]
    nodes: dict[str, NodeEstimate]
    node_history: dict[str, NodeTrack]
    contributors: dict[str, list[str]]
    readings: dict[str, int] = field(default_factory=dict)
    closures: list[LoopClosure] = field(default_factory=list)
    uses: list[NodeUse] = field(default_factory=list)
    node_floor: dict[str, int] = field(default_factory=dict)
    """Each estimated node's floor (:mod:`hrtls.mission.floors`)."""


@dataclass(frozen=True, eq=False)
class AgentHeader:
    """What a mission knows of an agent before its data: metadata and landmarks."""

    meta: SessionMeta
    landmarks: dict[str, Landmark] = field(default_factory=dict)


class MissionTracker:
    """All agents of a mission and the dropped nodes as one causal loop (see module doc).

    Offline, ``agents`` are whole sessions and :meth:`run` processes them. Live, ``agents`` are
    :class:`AgentHeader` (or sessions with the first data); :meth:`feed` buffers each agent's
    parts as they arrive and :meth:`advance` processes every complete window: one where every
    agent that is neither ended (:meth:`end`) nor silent (``silent_after_s``) has data at or
    after its end, and at least one agent has (when all are silent, nothing moves until one
    speaks or the mission ends, ``final``). Windows start at the earliest data time of the
    first processed window. ``now_s``: the clock at creation (an agent not heard from yet
    holds the windows back until ``silent_after_s`` after it).

    Its state is public for :mod:`hrtls.mission.snapshot` (read and restored there); other
    callers use :meth:`agent_rows` and :meth:`give_landmarks` and leave the state alone.
    """

    def __init__(self, agents: Mapping[str, Session | AgentHeader], *,
                 config: TrackerConfig | None = None, params: MissionParams | None = None,
                 kinds: Mapping[str, str] | None = None,
                 landmark_updates: Sequence[Landmark] = (), now_s: float = -math.inf) -> None:
        if not agents:
            raise InputError("no agents", where="mission", expected="at least one session")
        self.params = params or MissionParams()
        self.config = config
        self.names = list(agents)
        self.kinds = {k: (kinds or {}).get(k, "rescuer") for k in self.names}
        bad = [k for k, v in self.kinds.items() if v not in ("rescuer", "robot")]
        if bad:
            raise InputError(f"agent {bad[0]!r} is a {self.kinds[bad[0]]!r}", where="mission kinds",
                             expected="rescuer or robot")
        self.headers = {k: (AgentHeader(a.meta, dict(a.landmarks)) if isinstance(a, Session)
                            else a) for k, a in agents.items()}
        self.known = [network_feed.known_ids(self.headers[k].meta, self.headers[k].landmarks)
                      for k in self.names]
        self.trackers: dict[str, Tracker | RobotTracker] = {
            k: RobotTracker() if self.kinds[k] == "robot" else Tracker(config)
            for k in self.names}
        self.landmark_updates = tuple(landmark_updates)
        self.buffers = {k: AgentBuffer(k) for k in self.names}
        for buf in self.buffers.values():
            buf.heard_s = now_s
        self.started: set[str] = set()
        self.deferred: dict[str, list[tuple[str, object]]] = {k: [] for k in self.names}
        self.t0: float | None = None
        self.horizon_s = -math.inf
        self.window_index = 0
        # robots take a version at the first window starting at or after its time
        self.robot_updates = sorted(landmark_updates, key=lambda v: float(v.updated or 0.0))
        self.estimator = NodeEstimator(self.params.nodes)
        self.readings: dict[str, NodeReadings] = {}
        self.estimates: dict[str, NodeEstimate] = {}
        self.contrib: dict[str, set[int]] = {}
        self.users: dict[str, set[int]] = {}
        self.given: dict[int, dict[str, int]] = {i: {} for i in range(len(self.names))}
        self.history: dict[str, list[tuple[float, FloatArray, FloatArray]]] = {}
        self.rows_pulled_s = dict.fromkeys(self.names, -math.inf)
        self.recent_rows: dict[str, list[Rows]] = {k: [] for k in self.names}
        # ranges later than the agent's latest row, kept until rows cover them (readings.py)
        self.pending: dict[str, RangeMeasurements | None] = dict.fromkeys(self.names)
        self.versions: dict[str, int] = {}
        self.estimated_at: dict[str, int] = {}
        self.contrib_trace: dict[tuple[int, str], float] = {}
        self.closures: list[LoopClosure] = []
        self.peers = PeerUses()
        self.prov = Provenance()
        self.smoother = smoothing.SmootherState() if self.params.smoother else None
        self.bridge = bridge.BridgeState() if self.params.smooth_readings_s > 0 else None
        self.floor_logs = {k: FloorLog() for k in self.names}
        self.network = network_feed.NetworkState()
        self.node_floor: dict[str, int] = {}
        self.floor_height_m = building_floor_height_m(
            [self.headers[k].meta.floor_height_m for k in self.names if self.kinds[k] == "rescuer"])
        for k, a in agents.items():
            if isinstance(a, Session):
                self.feed(k, a, now_s=now_s)

    # ------------------------------------------------------------------ incremental
    def feed(self, agent: str, part: Session, *, now_s: float | None = None) -> LateData | None:
        """Buffer a part of ``agent``'s data (any order within the unprocessed time).

        ``now_s``: the clock of its arrival (silence, ``silent_after_s``; default its last data
        time). Its samples before the processed horizon are not used: they come back as
        :class:`~hrtls.mission.buffer.LateData` (None when nothing was late).
        """
        buf = self.buffers.get(agent)
        if buf is None:
            raise InputError(f"unknown agent {agent!r}", where="MissionTracker.feed",
                             expected="one of " + ", ".join(self.names))
        clock = part.time_span()[1] if now_s is None else now_s
        return buf.add(part, horizon_s=self.horizon_s, now_s=clock)

    def feed_network(self, part: NetworkRanges, *, now_s: float | None = None) -> LateData | None:
        """Buffer ranges between dropped nodes like :meth:`feed` (:mod:`.network_feed`)."""
        return network_feed.feed(self, part, now_s=now_s)

    def add_landmark_updates(self, versions: Sequence[Landmark]) -> list[Landmark]:
        """Landmark versions written during a live mission, each holding from ``updated`` on.

        Used as if given at the start; versions older than the processed horizon are returned
        unused (the windows before it are not processed again).
        """
        late = [v for v in versions if float(v.updated or 0.0) < self.horizon_s]
        due = [v for v in versions if float(v.updated or 0.0) >= self.horizon_s]
        self.landmark_updates += tuple(due)
        self.robot_updates = sorted([*self.robot_updates, *due],
                                     key=lambda v: float(v.updated or 0.0))
        for name in self.started:
            tr = self.trackers[name]
            if isinstance(tr, Tracker):
                tr.update_landmarks(due)
        return late

    def end(self, agent: str) -> None:
        """``agent`` sends no more data: it no longer holds the windows back."""
        self.buffers[agent].ended = True

    def advance(self, t_s: float = math.inf, *, now_s: float | None = None,
                final: bool = False) -> Progress:
        """Process every complete window ending at or before ``t_s`` (class doc).

        ``now_s``: the clock that judges silence (default: the latest data time fed);
        ``final``: every agent has ended (the mission's end: the last windows are processed).
        """
        with_data = [b for b in self.buffers.values() if b.t_first < math.inf]
        if not with_data:
            return Progress(0, self.horizon_s, ())
        if self.t0 is None:
            self.t0 = min(b.t_first for b in with_data)
        t_data = max(b.t_last for b in with_data)
        clock = t_data if now_s is None else now_s
        before = dict(self.versions)
        n = 0
        c = self.params.chunk_s
        while True:
            t_start, t_end = self.t0 + self.window_index * c, self.t0 + (self.window_index + 1) * c
            if t_start > t_data or t_end > t_s:
                break
            if not final and not self._complete(t_end, clock):
                break
            self.step(t_start, t_end)
            self.window_index += 1
            self.horizon_s = t_end
            n += 1
        if final:
            self._flush()
        changed = tuple(sorted(k for k, v in self.versions.items() if before.get(k) != v))
        return Progress(n, self.horizon_s, changed)

    def _complete(self, t_end: float, clock: float) -> bool:
        unready = {k for k in self.names if k not in self.started
                   and not startable(self.buffers[k], robot=self.kinds[k] == "robot")}
        return window_complete(self.buffers, t_end, clock_s=clock, unready=unready,
                               silent_after_s=self.params.silent_after_s)

    def _part(self, name: str, t_start: float, t_end: float) -> Session | None:
        """The agent's data in the window; its tracker starts at its first data."""
        part = self.buffers[name].window(t_start, t_end)
        if part is None or name in self.started:
            return part
        data = self.buffers[name].data
        assert data is not None
        h = self.headers[name]
        tr = self.trackers[name]
        tr.start_session(data.with_parts(meta=h.meta, landmarks=h.landmarks))
        if isinstance(tr, Tracker):
            tr.update_landmarks(self.landmark_updates)
        self.started.add(name)
        for method, arg in self.deferred.pop(name, []):
            getattr(tr, method)(arg)
        return part

    def _apply(self, name: str, method: str, arg: object) -> None:
        """Call ``method(arg)`` on the agent's tracker now, or right after its start."""
        if name in self.started:
            getattr(self.trackers[name], method)(arg)
        else:
            self.deferred.setdefault(name, []).append((method, arg))

    def give_landmarks(self, name: str, landmarks: Mapping[str, Landmark]) -> None:
        """Set ``landmarks`` on agent ``name``'s tracker now, or right after its start."""
        self._apply(name, "set_landmarks", dict(landmarks))

    def windows(self) -> list[tuple[float, float]]:
        """The common windows ``(t_start, t_end)`` covering every agent's data fed so far."""
        spans = [(b.t_first, b.t_last) for b in self.buffers.values() if b.t_first < math.inf]
        if not spans:
            return []
        t0 = self.t0 if self.t0 is not None else min(a for a, _ in spans)
        t1 = max(b for _, b in spans)
        self.t0 = t0
        n = math.floor((t1 - t0) / self.params.chunk_s) + 1
        return [(t0 + k * self.params.chunk_s, t0 + (k + 1) * self.params.chunk_s)
                for k in range(n)]

    def run(self) -> MissionResult:
        """Process every agent's data fed so far to its end (offline: the whole sessions)."""
        self.advance(math.inf, final=True)
        return self.result()

    def snapshot(self) -> bytes:
        """The mission's state as bytes (:mod:`hrtls.mission.snapshot`)."""
        from hrtls.mission.snapshot import mission_snapshot

        return mission_snapshot(self)

    @classmethod
    def restore(cls, data: bytes) -> MissionTracker:
        """A mission tracker continuing from :meth:`snapshot` bytes."""
        from hrtls.mission.snapshot import restore_mission

        return restore_mission(data)

    def result(self) -> MissionResult:
        """Finish every agent's tracker; the mission's result (after the last window)."""
        results = {n: tr.finish() for n, tr in self.trackers.items() if n in self.started}
        hist = {n: NodeTrack(np.array([h[0] for h in rows]), np.array([h[1] for h in rows]),
                             np.array([h[2] for h in rows])) for n, rows in self.history.items()}
        contributors = {n: [self.names[i] for i in sorted(c)] for n, c in self.contrib.items()}
        readings = {n: len(r.r) for n, r in self.readings.items()}
        return MissionResult(results, dict(self.estimates), hist, contributors, readings,
                             list(self.closures), list(self.prov.uses), dict(self.node_floor))

    def step(self, t_start: float, t_end: float) -> None:
        """One common window: feed every agent, then update the nodes and share them."""
        touched: set[str] = set()
        due = [v for v in self.robot_updates if float(v.updated or 0.0) <= t_start]
        if due:
            self.robot_updates = self.robot_updates[len(due):]
            for name, tr in self.trackers.items():
                if isinstance(tr, RobotTracker):
                    self._apply(name, "update_landmarks", due)
        for i, name in enumerate(self.names):
            part = self._part(name, t_start, t_end)
            if part is None:
                continue
            rest, peer = split_peer_ranges(self, i, part.ranges)
            if rest is not None and math.isfinite(self.params.use_variance_ratio):
                self.agent_rows(name)                   # the gate reads the latest row
            use, keep = self._split_ranges(i, rest)
            self.trackers[name].update(part.with_parts(ranges=merge_ranges(use, peer)))
            smoothing.collect(self, i, rest)
            if keep is not None or self.pending[name] is not None:
                touched |= self._collect(i, name, keep, self.agent_rows(name))
            touched |= bridge.revise(self, name, touched)
            self._trim_rows(name, t_end)
        network_feed.step(self, t_start, t_end)
        changed = self._relocalize(touched, t_end)
        changed += [n for n in smoothing.solve(self, t_end) if n not in changed]
        if self.params.cooperate:
            self._share(changed, t_end)

    def _flush(self) -> None:
        """The mission's end: the pending readings stored, their nodes estimated again.

        A reading later than its agent's latest row takes that row's estimate.
        """
        touched: set[str] = set()
        for i, name in enumerate(self.names):
            if self.pending[name] is not None and name in self.started:
                touched |= self._collect(i, name, None, self.agent_rows(name), final=True)
            touched |= bridge.revise(self, name, touched)
        self._relocalize(touched, self.horizon_s, every=True)
        smoothing.solve(self, self.horizon_s, final=True)

    def _relocalize(self, touched: set[str], t_end: float, *, every: bool = False) -> list[str]:
        """Estimate again the touched nodes whose readings grew enough (``every``: any growth)."""
        changed: list[str] = []
        for node in sorted(touched - (self.smoother.owned if self.smoother else set())):
            n_now = len(self.readings[node].r)
            n_then = self.estimated_at.get(node, 0)
            grown = n_now > n_then if every else \
                n_now - n_then >= max(3, self.params.refresh_fraction * n_then)
            if not grown:
                continue
            self.estimated_at[node] = n_now
            floor = node_floor(self.readings[node].floor)
            obs = self.readings[node].ranges(self.params.pass_gap_s, floor=floor)
            prev = self.estimates.get(node)
            init = (prev.position_m if prev is not None and prev.localized
                    and self.node_floor.get(node, 0) == floor else None)
            self.node_floor[node] = floor
            est = self.estimator.estimate(obs, initial_m=init)
            if not est.localized and init is not None:
                est = self.estimator.estimate(obs)
            self.estimates[node] = est
            if est.localized:
                self.versions[node] = self.versions.get(node, 0) + 1
                changed.append(node)
                self.history.setdefault(node, []).append(
                    (t_end, est.position_m.copy(), est.covariance_m2.copy()))
        return changed

    def _split_ranges(self, i: int, ranges: RangeMeasurements | None
                      ) -> tuple[RangeMeasurements | None, RangeMeasurements | None]:
        """Ranges for the agent's own tracker (usable nodes) and readings kept for the nodes."""
        if ranges is None:
            return None, None
        known = np.isin(ranges.node, self.known[i])
        ok = {n: self._informative(i, n) and self._usable(i, n)
              for n in dict.fromkeys(ranges.node.tolist())}
        usable = ~known & np.array([ok[n] for n in ranges.node.tolist()], dtype=bool)
        use = None
        if (usable | known).any():
            sig = ranges.sigma_m.copy()
            if usable.any():
                sig[usable] = np.sqrt(sig[usable] ** 2 + self._use_var(i, ranges, usable))
            m = usable | known
            use = RangeMeasurements(ranges.t[m], ranges.node[m], ranges.range_m[m], sig[m])
            for n in set(ranges.node[usable].tolist()):
                self.users.setdefault(str(n), set()).add(i)
        keep = None
        if (~(usable | known)).any():
            m = ~(usable | known)
            keep = RangeMeasurements(ranges.t[m], ranges.node[m], ranges.range_m[m],
                                     ranges.sigma_m[m])
        return use, keep

    def _usable(self, i: int, node: str) -> bool:
        """A node localized by the mission that agent ``i`` may use (see module doc)."""
        name = self.names[i]
        if not (self.params.cooperate and node in self.given[i]) or smoothing.via_feedback(
                self, i, node) or self.node_floor.get(node, 0) != self.floor_logs[name].now():
            return False
        if i not in self.contrib.get(node, set()) or i in self.users.get(node, set()):
            return True
        rows = self.recent_rows[name]
        if not rows or not math.isfinite(self.params.loop_closure_ratio):
            return False
        now, then = float(np.trace(rows[0][2][-1])), self.contrib_trace[(i, node)]
        if now < self.params.loop_closure_ratio * then:
            return False
        self.closures.append(LoopClosure(float(rows[0][0][-1]), self.names[i], node, now, then))
        self.users.setdefault(node, set()).add(i)
        return True

    def _informative(self, i: int, node: str) -> bool:
        """The information gate (``use_variance_ratio``) at the agent's latest row."""
        rows, est = self.recent_rows[self.names[i]], self.estimates.get(node)
        if not rows or est is None:
            return True
        return informative(est.position_m, est.covariance_m2, rows[0][1][-1], rows[0][2][-1],
                           ratio=self.params.use_variance_ratio)

    def _use_var(self, i: int, ranges: RangeMeasurements, usable: NDArray[np.bool_]
                 ) -> FloatArray:
        """Variance added to each usable range: its node's variance times its pass's factor."""
        nodes, times = ranges.node[usable], ranges.t[usable]
        extra = np.zeros(len(times))
        for n in np.unique(nodes).tolist():
            m = nodes == n
            kind = self.prov.kind(i, str(n), contributor=i in self.contrib.get(str(n), set()))
            self.prov.passes[(i, str(n))], factor = widening(
                self.prov.passes.get((i, str(n)), UsePool()), t_first_s=float(times[m][0]),
                t_last_s=float(times[m][-1]), ranges=int(np.count_nonzero(m)),
                gap_s=self.params.pass_gap_s, kind=kind, cap=self.params.pass_cap)
            extra[m] = factor * largest_variance(self.estimates[str(n)].covariance_m2)
            est = self.estimates[str(n)]
            self.prov.use(NodeUse(
                float(times[m][0]), i, str(n), kind, int(np.count_nonzero(m)),
                est.position_m.copy(), est.covariance_m2.copy(),
                float(np.sqrt(ranges.sigma_m[usable][m][-1] ** 2 + extra[m][-1]))))
        return extra

    def agent_rows(self, name: str) -> Rows | None:
        """Agent ``name``'s recent estimates (time, xy, covariance) with its newest rows.

        Pulls the rows its tracker made since the last call (kept back to the trim of the
        last window); None before its first row.
        """
        est = self.trackers[name].estimates_since(self.rows_pulled_s[name])
        self.floor_logs[name].add(est.t, est.floor)
        if len(est) > 1:
            self.rows_pulled_s[name] = float(est.t[-2])
        rows = merge_rows(self.recent_rows[name], (est.t, est.xyz[:, :2], est.cov_xy))
        self.recent_rows[name] = [] if rows is None else [rows]
        return rows

    def _trim_rows(self, name: str, t_end: float) -> None:
        """Keep the per-window cost of :meth:`_collect` independent of the mission's length."""
        if len(self.recent_rows[name]) == 1:
            self.recent_rows[name] = [trim_rows(self.recent_rows[name][0], t_end,
                                                keep_s=self.params.peer_ranges.rows_kept_s())]

    def _collect(self, i: int, name: str, ranges: RangeMeasurements | None, rows: Rows | None,
                 *, final: bool = False) -> set[str]:
        """Store the readings the agent's rows cover; the nodes touched.

        Each reading gets the agent's estimate at its time; the later ones (all before the
        agent's first row) stay pending, none with ``final`` (:mod:`hrtls.mission.readings`).
        """
        ranges = join_ranges(self.pending[name], ranges)
        self.pending[name] = None
        if ranges is None:
            return set()
        if rows is None:
            self.pending[name] = ranges
            return set()
        now, self.pending[name] = (ranges, None) if final else split_at(ranges, float(rows[0][-1]))
        if now is None:
            return set()
        touched: set[str] = set()
        for n in np.unique(now.node).tolist():
            node = str(n)
            if i in self.users.get(node, set()):
                continue
            m = now.node == n
            tr = self.readings.setdefault(node, NodeReadings()).add(
                agent=i, t_s=now.t[m], rows=rows, range_m=now.range_m[m], sigma_m=now.sigma_m[m],
                floor=self.floor_logs[name].at(now.t[m]))
            self.contrib.setdefault(node, set()).add(i)
            self.prov.read(i, node)
            self.contrib_trace[(i, node)] = min(self.contrib_trace.get((i, node), math.inf), tr)
            touched.add(node)
        return touched

    def _share(self, changed: list[str], t: float) -> None:
        """Give each node re-localized in this window to every agent (see :meth:`_usable`)."""
        no_robot = self.params.smoother is not None and self.params.smoother.robots != "nodes"
        for node in changed:
            est, v = self.estimates[node], self.versions[node]
            sigma = float(np.sqrt(largest_variance(est.covariance_m2)))
            f = self.node_floor.get(node, 0)
            lm = Landmark(id=node, kind="node", floor=f, accuracy_m=max(sigma, 1e-6),
                          position=(float(est.position_m[0]), float(est.position_m[1]),
                                    f * self.floor_height_m), updated=t)
            for i, name in enumerate(self.names):
                if self.given[i].get(node) == v or (no_robot and self.kinds[name] == "robot"):
                    continue
                self._apply(name, "set_landmarks", {node: lm})
                self.given[i][node] = v
