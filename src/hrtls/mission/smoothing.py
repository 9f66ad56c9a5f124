"""The mission loop's range-SLAM smoother (:mod:`hrtls.mission.graph`) at a cadence.

With ``MissionParams.smoother`` set, :class:`~hrtls.mission.tracker.MissionTracker` keeps, for
every agent, its estimate rows every ``decimate_s`` (the first row's covariance too) and every
range it measured to a node without a known position (used by its tracker or kept as a reading),
and every ``every_s`` of mission time solves :func:`hrtls.mission.graph.smooth` on all of it,
warm-started from the previous solution. The data are those of the processed windows only
(causal); a range later than its agent's latest row waits for the next solve. Each node the
smoother localizes becomes the mission's estimate of that node (the per-node estimator no longer
re-estimates it) and is shared with the agents like any re-localized node.

With ``SmootherParams.window_s`` the poses older than the window leave the problem after each
solve (:mod:`hrtls.mission.graph_window`): a dense prior factor takes their information, and
the state keeps only what the next problem uses: an agent's rows from its cut pose on (the first
row there, on the dead reckoning of the solve before: ``g(t_c)`` plus the jumps of its
corrections up to ``t_c``, so the increments after it do not change), its corrections after
``t_c``, its ranges from ``t_c`` on, and the distance it walked before ``t_c`` (its segments).

Floors (:mod:`hrtls.mission.floors`). Each range carries its agent's floor at its time, from the
agent's causal rows (its floor log, which the rows the smoother pulls also update); a node's
floor is that of most of its ranges, those in the problem and those that left it with the
window (counted per floor); only the ranges on the node's floor enter the problem. The solve
gives each node it localizes with that floor (:attr:`MissionTracker.node_floor`), and an agent
uses it only on that floor. An agent's poses on other floors stay in its chain: the path is
2-D and its increments are the same dead reckoning whatever the floor; the height column is
the height between an agent's antenna and a node on the same floor, the only pairs left, so
nothing depends on the floor there. A marginalized prior keeps the node information it took;
a node whose floor changes later keeps that (the slab blocks the radio: a range from another
floor comes from a wrong floor estimate, rare and short).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data.observations import RangeMeasurements
from hrtls.errors import FormatError
from hrtls.mission import bridge, network_feed, peer_feed
from hrtls.mission.correction_factors import dead_reckoning, implied_factors
from hrtls.mission.feedback import feed_back
from hrtls.mission.floors import on_node_floor
from hrtls.mission.graph import AgentPath, RangeSet, SmootherResult, linearize, smooth
from hrtls.mission.graph_links import NodeLinks
from hrtls.mission.graph_peers import information, marginalizable
from hrtls.mission.graph_window import (
    Layout,
    MarginalPrior,
    carried,
    cut_index,
    marginalized,
    prior_from,
    prior_state,
    solution_vector,
    trimmed,
)
from hrtls.mission.increment_noise import ChainNoise, growth_curve, robot_chain
from hrtls.mission.nodes import NodeEstimate
from hrtls.mission.robot import RobotTracker
from hrtls.pipeline.corrections import SMOOTHED
from hrtls.pipeline.schedule import BEARING, MAGNETIC, RANGE
from hrtls.pipeline.tracker import Tracker

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

FloatArray = NDArray[np.float64]


@dataclass
class SmootherState:
    """What the loop keeps for the smoother (all plain arrays / lists: snapshot-ready).

    ``rows``: per agent its kept rows (t, x, y, covariance P00, P01, P10, P11); ``start_cov``:
    its first row's covariance; ``pulled``: time of its last final row; ``tail``: its latest
    row (t, x, y, covariance), which may still change; ``ranges``: agent index, t, node,
    range, sigma;
    ``last_solve_s``: mission time of the last solve; ``owned``: nodes the smoother localized;
    ``warm``: the last solution (warm start); ``corr``: per agent its tracker's corrections
    (blocks of ``[t, kind, source, mean0, cov0, mean1, cov1]``,
    :class:`hrtls.pipeline.corrections.Corrections`); ``corr_next``: the next record to read;
    ``prior``: the marginalized older poses (``window_s``); ``walked``: per agent the distance
    walked before its first kept row, m; ``floors_cut``: per node, the ranges that left the
    problem with the window, counted per floor (they still count for the node's floor);
    ``peers``: the ranges between agents, as ``ranges`` (:mod:`hrtls.mission.peer_feed`).
    """

    rows: dict[str, list[list[float]]] = field(default_factory=dict)
    start_cov: dict[str, FloatArray] = field(default_factory=dict)
    pulled: dict[str, float] = field(default_factory=dict)
    tail: dict[str, list[float]] = field(default_factory=dict)
    ranges: list[list[Any]] = field(default_factory=list)
    last_solve_s: float = -math.inf
    owned: set[str] = field(default_factory=set)
    warm: SmootherResult | None = None
    seconds: list[float] = field(default_factory=list)
    corr: dict[str, list[list[Any]]] = field(default_factory=dict)
    corr_next: dict[str, int] = field(default_factory=dict)
    prior: MarginalPrior | None = None
    walked: dict[str, float] = field(default_factory=dict)
    floors_cut: dict[str, dict[int, int]] = field(default_factory=dict)
    peers: list[list[Any]] = field(default_factory=list)


def collect(mt: MissionTracker, i: int, ranges: RangeMeasurements | None) -> None:
    """Keep agent ``i``'s new rows (every ``decimate_s``) and its ranges to unknown nodes."""
    prm = mt.params.smoother
    st = mt.smoother
    if prm is None or st is None:
        return
    name = mt.names[i]
    if name in mt.started:
        est = mt.trackers[name].estimates_since(st.pulled.get(name, -math.inf))
        mt.floor_logs[name].add(est.t, est.floor)
        new = [[float(est.t[k]), float(est.xyz[k, 0]), float(est.xyz[k, 1]),
                *np.asarray(est.cov_xy[k], np.float64).reshape(-1).tolist()]
               for k in range(len(est))]
        tail = st.tail.get(name)
        if tail is not None and (not new or new[0][0] > tail[0]):
            new.insert(0, tail)               # a restored tracker does not repeat it
        rows = st.rows.setdefault(name, [])
        for row in new[:-1]:                  # the last row may still change: the tail
            if not rows:
                st.start_cov[name] = np.asarray(row[3:7], np.float64).reshape(2, 2)
            if not rows or row[0] >= rows[-1][0] + prm.decimate_s:
                rows.append(row[:7])
            st.pulled[name] = row[0]
        if new:
            st.tail[name] = new[-1]
        _pull_corrections(mt, name)
    if ranges is None or not len(ranges.t):
        return
    m = ~np.isin(ranges.node, mt.known[i])
    if m.any():
        st.ranges.append([i, ranges.t[m].copy(), ranges.node[m].astype(str),
                          ranges.range_m[m].copy(), ranges.sigma_m[m].copy()])


def via_feedback(mt: MissionTracker, i: int, node: str) -> bool:
    """Agent ``i``'s ranges to ``node`` reach its tracker only through the feedback.

    With ``feedback_ranges`` ``"smoother"``: a rescuer the smoother feeds back (its tracker a
    :class:`~hrtls.pipeline.tracker.Tracker`) takes no range to a node the smoother owns. The
    smoother solves that node jointly with the rescuer's path from the same ranges, so its
    latest pose already holds them; taken by the tracker too, they would count twice after a
    feedback (the node's error and the fed-back pose's are one and the same solve's), and the
    implied update's premise, the tracker's information inside the smoother's, would hold only
    approximately. The ranges still go to the smoother (:func:`collect`).
    """
    prm, st = mt.params.smoother, mt.smoother
    return prm is not None and st is not None and prm.feedback != "off" and \
        prm.feedback_ranges == "smoother" and node in st.owned and \
        isinstance(mt.trackers[mt.names[i]], Tracker)


def _pull_corrections(mt: MissionTracker, name: str) -> None:
    """The agent's new correction records (a tracker that keeps them: rescuers)."""
    st = mt.smoother
    tr = mt.trackers[name]
    if st is None or not isinstance(tr, Tracker | RobotTracker):
        return
    c = tr.corrections_since(st.corr_next.get(name, 0))
    st.corr_next[name] = c.next_index
    if len(c):
        st.corr.setdefault(name, []).append([c.t, c.kind, c.source, c.mean0_m, c.cov0_m2,
                                             c.mean1_m, c.cov1_m2])


def _agent_path(mt: MissionTracker, i: int, name: str, rows: FloatArray) -> AgentPath:
    """The agent's rows with its dead reckoning and correction factors (when it keeps them).

    Every correction's jump leaves the chain (the magnetic heading's and the tag bearings' with
    ``heading_updates`` ``"chain"`` aside); all but the ranges to nodes that are not the agent's
    known landmarks (mission nodes: their raw ranges are the problem's; peers), the smoother's
    own feedback (:mod:`hrtls.mission.feedback`) and, unless ``heading_updates`` is
    ``"factor"``, the heading corrections become factors. A robot's chain noise is its EKF's
    (:func:`hrtls.mission.increment_noise.robot_chain`), not the smoother's walker model.
    """
    st, prm = mt.smoother, mt.params.smoother
    assert st is not None and prm is not None
    blocks = st.corr.get(name)
    cov = rows[:, 3:7].reshape(-1, 2, 2)
    if not blocks and not isinstance(mt.trackers[name], Tracker | RobotTracker):
        return AgentPath(name, rows[:, 0], rows[:, 1:3], st.start_cov[name], growth_m2=cov)
    t, kind, src, m0, c0, m1, c1 = (np.concatenate([b[j] for b in blocks]) if blocks else
                                    np.zeros((0, 2, 2)) if j in (4, 6) else
                                    np.zeros((0, 2)) if j in (3, 5) else np.zeros(0)
                                    for j in range(7))
    heading = np.isin(kind, (MAGNETIC, BEARING))
    jump = _jump_leaves_chain(kind, prm.heading_updates)
    dr = dead_reckoning(rows[:, 0], rows[:, 1:3], t[jump], (m1 - m0)[jump])
    keep = ~((kind == RANGE) & ~np.isin(src.astype(str), mt.known[i])) & (kind != SMOOTHED)
    if prm.heading_updates != "factor":
        keep &= ~heading
    z, wm = implied_factors(m0[keep], c0[keep], m1[keep], c1[keep])
    growth = growth_curve(cov, rows[:, 0], t[jump], c0[jump], c1[jump])
    return AgentPath(name, rows[:, 0], rows[:, 1:3], st.start_cov[name], dr, (t[keep], z, wm),
                     growth_m2=growth, chain=_robot_chain(mt, name))


def _robot_chain(mt: MissionTracker, name: str) -> ChainNoise | None:
    """A robot's own chain noise (its EKF's odometry model); None for a rescuer."""
    tr, prm = mt.trackers[name], mt.params.smoother
    if not isinstance(tr, RobotTracker) or prm is None:
        return None
    sp = mt.headers[name].meta.start_pose
    return robot_chain(odometry_fraction=tr.params.odometry_fraction,
                       heading_var_per_m=tr.params.heading_var_per_m,
                       start_heading_sigma_rad=prm.heading_sigma_rad if sp is None
                       else sp.sigma_heading_rad, segment_m=prm.segment_m)


def _jump_leaves_chain(kind: NDArray[Any], heading_updates: str) -> NDArray[np.bool_]:
    """Corrections whose jump the dead reckoning drops (``"chain"``: not the heading updates')."""
    if heading_updates == "chain":
        return np.asarray(~np.isin(kind, (MAGNETIC, BEARING)))
    return np.ones(len(kind), dtype=bool)


def problem(mt: MissionTracker) -> tuple[list[AgentPath], RangeSet] | None:
    """The agents' paths and the ranges the next solve takes (None: nothing to solve).

    The ranges are those the agents' rows cover, on their nodes' floors (module doc).
    """
    st = mt.smoother
    assert st is not None
    paths: list[AgentPath] = []
    index: dict[int, int] = {}
    feedback = mt.params.smoother is not None and mt.params.smoother.feedback != "off"
    for i, name in enumerate(mt.names):
        rows = st.rows.get(name, [])
        tail = st.tail.get(name)
        if feedback and rows and tail is not None and tail[0] > rows[-1][0]:
            rows = [*rows, tail[:7]]          # the latest row: the pose fed back
        if len(rows) < 2:
            continue
        index[i] = len(paths)
        paths.append(replace(_agent_path(mt, i, name, np.asarray(rows, np.float64)),
                             walked0_m=st.walked.get(name, 0.0)))
    parts = [p for p in st.ranges if int(p[0]) in index]
    if not paths or not parts:
        return None
    agent = np.concatenate([np.full(len(p[1]), index[int(p[0])], np.int64) for p in parts])
    t = np.concatenate([p[1] for p in parts])
    node = np.concatenate([p[2] for p in parts])
    floor = np.concatenate([mt.floor_logs[mt.names[int(p[0])]].at(p[1]) for p in parts])
    last = np.array([paths[a].t[-1] for a in range(len(paths))])
    m = np.flatnonzero(t <= last[agent])
    m = m[on_node_floor(node[m], floor[m], st.floors_cut)[0]]
    return paths, RangeSet(agent[m], t[m], node[m], np.concatenate([p[3] for p in parts])[m],
                           np.concatenate([p[4] for p in parts])[m], floor[m])


def solve(mt: MissionTracker, t_end: float, *, final: bool = False) -> list[str]:
    """Solve when due; the nodes it changed.

    Due: ``every_s`` since the last solve, or ``final`` past the last solve's time (a closed
    mission advanced again without new data does not solve again). Each localized node
    replaces the mission's estimate of it (version, history) and its floor, and is owned by the
    smoother from then on.
    """
    import time

    prm, st = mt.params.smoother, mt.smoother
    if prm is None or st is None or not (t_end > st.last_solve_s if final
                                         else t_end >= st.last_solve_s + prm.every_s):
        return []
    st.last_solve_s = t_end
    got = problem(mt)
    if got is None:
        return []
    paths, ranges = got
    initial = {n: e.position_m for n, e in mt.estimates.items() if e.localized}
    clock = time.perf_counter()
    links = network_feed.links(mt)
    st.warm = smooth(paths, ranges, params=prm, initial_nodes=initial, warm=st.warm,
                     prior=st.prior, links=links, peers=peer_feed.problem_peers(mt, paths))
    st.seconds.append(time.perf_counter() - clock)
    solved = st.warm
    changed: list[str] = []
    for node, (p, cov, ok) in sorted(solved.nodes.items()):
        if not ok:
            continue
        mine = ranges.node == node
        k = int(np.count_nonzero(mine))
        if k and ranges.floor is not None:        # else: only in the prior, floor unchanged
            mt.node_floor[node] = int(ranges.floor[mine][0])
        elif node not in mt.node_floor:           # joined through its links: theirs
            mt.node_floor[node] = _linked_floor(mt, links, node)
        mt.estimates[node] = NodeEstimate(p.copy(), cov.copy(), True, "", np.ones(k, dtype=bool),
                                          solved.rms, solved.evaluations)
        st.owned.add(node)
        mt.versions[node] = mt.versions.get(node, 0) + 1
        mt.history.setdefault(node, []).append((t_end, p.copy(), cov.copy()))
        changed.append(node)
    if prm.window_s is not None:
        _slide(mt, paths, ranges, t_end - prm.window_s, links)
    if prm.feedback != "off" and mt.params.cooperate:
        for name in feed_back(mt, solved):
            _fed_back(mt, name)
    return changed


def _linked_floor(mt: MissionTracker, links: NodeLinks, node: str) -> int:
    """The floor of the first of ``node``'s linked nodes with one (0 without)."""
    other = np.concatenate([links.b[links.a == node], links.a[links.b == node]])
    return next((mt.node_floor[o] for o in other.tolist() if o in mt.node_floor), 0)


def _slide(mt: MissionTracker, paths: list[AgentPath], ranges: RangeSet, t_cut_s: float,
           links: NodeLinks) -> None:
    """Marginalize the poses before ``t_cut_s`` of the solve just made (module doc).

    The links stay in the problem (their nodes do): in both linearizations, they cancel. The
    ranges between agents the prior cannot take leave without it
    (:func:`hrtls.mission.graph_peers.marginalizable`).
    """
    prm, st = mt.params.smoother, mt.smoother
    assert prm is not None and st is not None and st.warm is not None
    res, ids = st.warm, list(st.warm.nodes)
    peers = peer_feed.problem_peers(mt, paths)
    lay0, h0, g0 = linearize(paths, ranges, ids, params=prm, prior=st.prior,
                             point=lambda lay: solution_vector(lay, res), links=links,
                             peers=peers)
    x0 = solution_vector(lay0, res)
    cut = {}
    for a, name in enumerate(lay0.names):
        c = cut_index(lay0, a, t_cut_s, float(st.rows[name][-1][0]))
        if c > 0:
            cut[name] = c
            _cut_agent(mt, paths[a], float(lay0.t[a][c]), float(lay0.walked_m[a][c]))
    if not cut:
        return
    agents = tuple(sorted(set(st.prior.agents if st.prior is not None else ()) | set(cut)))
    d = 4 * len(agents) + 2 * len(ids) + 1
    hold = MarginalPrior(agents, tuple(ids), np.zeros((0, d)), np.zeros(0), np.zeros(d))
    lost = ~marginalizable(peers, lay0, cut, agents)
    if lost.any():
        h_lost, g_lost = information(peers, lost, lay0, x0, prm)
        h0, g0 = h0 - h_lost, g0 - g_lost
    got = problem(mt)
    assert got is not None

    def at(lay: Layout) -> NDArray[np.float64]:
        return np.asarray(x0[np.maximum(carried(lay0, lay, cut), 0)], np.float64)

    lay1, h1, g1 = linearize(*got, ids, params=prm, prior=hold, point=at, links=links,
                             peers=peer_feed.problem_peers(mt, got[0]))
    st.prior = marginalized(lay0, h0, g0, x0, lay1, h1, g1, cut, agents)
    st.warm = trimmed(res, lay0, cut)


def _cut_agent(mt: MissionTracker, path: AgentPath, t_c: float, walked_m: float) -> None:
    """Drop the agent's rows before ``t_c`` (module doc).

    A first row at ``t_c`` replaces them (the dead reckoning and the growth curve there plus
    the jumps and the shrinkage of the corrections they removed up to ``t_c``); its corrections
    up to ``t_c`` and its ranges before ``t_c`` go too (counted per node and floor).
    """
    st, prm = mt.smoother, mt.params.smoother
    assert st is not None and prm is not None
    name = path.name
    i = mt.names.index(name)
    dr = path.xy_m if path.dead_reckoning_m is None else path.dead_reckoning_m
    xy = np.array([np.interp(t_c, path.t, dr[:, k]) for k in (0, 1)])
    gr = path.growth_m2
    cov = np.zeros(4) if gr is None else np.array(
        [np.interp(t_c, path.t, gr[:, j, k]) for j in (0, 1) for k in (0, 1)])
    blocks = []
    for b in st.corr.get(name, []):
        old = b[0] <= t_c
        removed = old & _jump_leaves_chain(b[1], prm.heading_updates)
        xy += np.sum(b[5][removed] - b[3][removed], axis=0)
        cov -= np.sum(b[4][removed] - b[6][removed], axis=0).reshape(-1)
        if not old.all():
            blocks.append([v[~old] for v in b])
    first = [t_c, float(xy[0]), float(xy[1]), *cov.tolist()]
    if name in st.corr:
        st.corr[name] = blocks
    st.rows[name] = [first] + [r for r in st.rows[name] if r[0] > t_c]
    peer_feed.cut(mt, i, t_c)
    st.walked[name] = walked_m
    parts = []
    for p in st.ranges:
        keep = p[1] >= t_c if int(p[0]) == i else np.ones(len(p[1]), dtype=bool)
        _count_floors(st.floors_cut, p[2][~keep], mt.floor_logs[name].at(p[1][~keep]))
        if keep.any():
            parts.append([p[0], *(v[keep] for v in p[1:])])
    # an empty block of this agent keeps the next problem buildable without ranges
    st.ranges = parts or [[i, *(v[:0] for v in p[1:])] for p in st.ranges[-1:]]


def _count_floors(counts: dict[str, dict[int, int]], node: NDArray[np.str_],
                  floor: NDArray[np.int64]) -> None:
    """Add the readings ``(node, floor)`` to the per-node, per-floor ``counts``."""
    if not len(node):
        return
    pairs, n = np.unique(np.column_stack([node.astype(str), floor.astype(str)]), axis=0,
                         return_counts=True)
    for (nd, fl), c in zip(pairs.tolist(), n.tolist(), strict=True):
        per = counts.setdefault(str(nd), {})
        per[int(fl)] = per.get(int(fl), 0) + int(c)


def _fed_back(mt: MissionTracker, name: str) -> None:
    """Read the agent's corrected latest row and the feedback's record now.

    Every reader of the agent's rows (the smoother's tail, the mission's recent rows, the
    smoothed-readings bridge) takes it before any snapshot: a restored tracker does not repeat
    the row.
    """
    st = mt.smoother
    assert st is not None
    t = st.tail[name][0]
    est = mt.trackers[name].estimates_since(float(np.nextafter(t, -math.inf)))
    st.tail[name] = [t, float(est.xyz[0, 0]), float(est.xyz[0, 1]),
                     *np.asarray(est.cov_xy[0], np.float64).reshape(-1).tolist()]
    mt.agent_rows(name)
    bridge.pull(mt, name)
    _pull_corrections(mt, name)


def state_of(st: SmootherState | None) -> dict[str, Any] | None:
    """Plain values of the smoother's state (snapshot)."""
    if st is None:
        return None
    w = st.warm
    warm = None if w is None else {
        "nodes": {n: [p, c, ok] for n, (p, c, ok) in w.nodes.items()},
        "paths": {k: list(v) for k, v in w.paths.items()},
        "corrections": {k: list(v) for k, v in w.corrections.items()},
        "scale": w.scale, "heading": w.heading_rad, "height": w.height_m, "rms": w.rms,
        "evaluations": w.evaluations}
    return {"rows": st.rows, "start_cov": st.start_cov, "pulled": st.pulled, "tail": st.tail,
            "ranges": st.ranges, "last": st.last_solve_s, "owned": sorted(st.owned),
            "warm": warm, "seconds": st.seconds, "corr": st.corr, "corr_next": st.corr_next,
            "prior": prior_state(st.prior), "walked": st.walked, "peers": st.peers,
            "floors_cut": {n: [[f, c] for f, c in sorted(v.items())]
                           for n, v in st.floors_cut.items()}}


def state_from(d: dict[str, Any] | None) -> SmootherState | None:
    """The smoother's state from :func:`state_of` values."""
    if d is None:
        return None
    if any(len(r) != 7 for v in d["rows"].values() for r in v):
        raise FormatError("smoother rows without their covariance (an older snapshot)",
                          where="mission snapshot", expected="rows of t, x, y and 4 covariance "
                          "terms: start the mission's estimator again")
    if "floors_cut" not in d:
        raise FormatError("smoother state without its ranges' floors (an older snapshot)",
                          where="mission snapshot", expected="the per-node floor counts of the "
                          "ranges the window cut: start the mission's estimator again")
    w = d["warm"]
    warm = None if w is None else SmootherResult(
        {n: (np.asarray(p), np.asarray(c), bool(ok)) for n, (p, c, ok) in w["nodes"].items()},
        {k: (v[0], v[1]) for k, v in w["paths"].items()},
        {k: (v[0], v[1]) for k, v in w["corrections"].items()},
        dict(w["scale"]), dict(w["heading"]), float(w["height"]), float(w["rms"]),
        int(w["evaluations"]))
    return SmootherState(
        rows={k: [list(r) for r in v] for k, v in d["rows"].items()},
        start_cov=dict(d["start_cov"]), pulled=dict(d["pulled"]),
        tail={k: list(v) for k, v in d["tail"].items()},
        ranges=[[int(p[0]), p[1], np.asarray(p[2]).astype(str), p[3], p[4]]
                for p in d["ranges"]],
        last_solve_s=float(d["last"]), owned=set(d["owned"]), warm=warm,
        seconds=list(d["seconds"]),
        corr={k: [[np.asarray(b[0], np.float64), np.asarray(b[1], np.int64),
                   np.asarray(b[2]).astype(str), *(np.asarray(v, np.float64) for v in b[3:])]
                  for b in v] for k, v in d.get("corr", {}).items()},
        corr_next={k: int(v) for k, v in d.get("corr_next", {}).items()},
        prior=prior_from(d.get("prior")),
        walked={k: float(v) for k, v in d.get("walked", {}).items()},
        floors_cut={n: {int(f): int(c) for f, c in v} for n, v in d["floors_cut"].items()},
        peers=[[int(p[0]), p[1], np.asarray(p[2]).astype(str), p[3], p[4]]
               for p in d.get("peers", [])])
