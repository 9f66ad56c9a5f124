"""Loose cooperation: the Safe Navigation Algorithm and its way-point planner (thesis Sec. 5.3).

The Safe Navigation Algorithm repeats three steps: SELA on the network, the mission planner that
proposes way points for a rescuer, and the rescuer walking there (tracked with range corrections
to localized nodes). At a way point the rescuer is a temporary node of the disk graph: it is
linked to every node within ``rho`` and its range measurements enter SELA. This approximates the
Minimum Augmentation Problem (eq. 5.1): make the augmented framework shadow localizable with few
way points.

Planner (one round), reading of the thesis used here:

* an unlocalized node with two localized neighbours whose candidates SELA cannot tell apart gets
  one of its candidate positions as way point (Fig. 5.3): when the agent stands there, either it
  hears the node (a third range) or the candidate is ruled out by the agent's own shadow edge;
  candidates within ``collinear_fraction * rho`` of the line of those two neighbours (close to
  each other) get instead the point half ``rho`` across that line, where the node is heard and
  the third range is far from collinear;
* an unlocalized node with a single localized neighbour ``p`` (the *pivot*) gets a new seed
  ``Sigma_j = {p, a, b}`` with ``a, b`` the two localized nodes nearest to ``p``; the coverage of
  each seed node is the square ``S_i`` of half side ``rho`` (eq. 5.2), their intersection is the
  rectangle ``Q_j`` (eq. 5.3, max-min of the bounds); the way point is the vertex of ``Q_j``
  nearest to the pivot (Fig. 5.4), or, when that vertex is collinear with two seed nodes, the
  midpoint of the two vertices nearest to the pivot (Fig. 5.5);
* nodes whose seeds share two or three nodes share one way point, the centroid of theirs.

The heuristic does not always make progress. A round without progress falls back to an *arc
search* for one frontier node ``u`` with pivot ``p``: ``u`` lies on the circle of radius ``d_up``
around ``p``, outside the radius ``rho`` of every localized node it does not hear; the agent goes
to the middle of the longest still-feasible arc. Either it hears ``u`` (``u`` becomes 2-covered and
a candidate visit resolves it) or the agent's own shadow removes at least a 60 degree arc, so at
most a handful of visits are needed per node.

What is guaranteed: with exact ranges and an exactly tracked agent, every connected network ends
fully localized within ``max_waypoints``. With a dead-reckoning agent the temporary nodes carry
its tracking error; the arc constraints are widened by three position sigmas of the nodes they
use, and when the ranges to the other localized neighbours still rule out the whole circle the
search keeps the shadow constraints only, so an inconsistent estimate does not end the search.
A node can still be given up after ``max_arc_visits_per_node`` visits when the agent's error
exceeds those margins (``SafeNavigationResult.complete`` then says so).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.wsn._propagation import M_AGENT, M_ANCHOR
from hrtls.wsn.agents import AgentLeg, Landmarks, MobileAgent
from hrtls.wsn.network import Adjacency, Network, build_adjacency
from hrtls.wsn.shadow_edge import circle_candidates
from hrtls.wsn.trilateration import Localization, PropagationParams, propagate

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, kw_only=True)
class PlannerParams:
    """Parameters of the way-point planner and the Safe Navigation loop.

    Attributes
    ----------
    max_waypoints:
        Stop after this many visited way points.
    arc_samples:
        Angular samples of the circle in the arc-search fallback.
    max_arc_visits_per_node:
        Give up a node after this many arc-search visits.
    share_seeds:
        Merge way points of nodes whose seeds share >= 2 nodes (thesis Sec. 5.3, last paragraph).
    collinear_fraction:
        A vertex of ``Q_j`` (a candidate) is "collinear" with two seed nodes (the two neighbours
        it comes from) when its distance from their line is below this times ``rho``.
    heuristic:
        Use the thesis' seed/vertex way points; False uses only candidates and the arc search.
    """

    max_waypoints: int = 400
    arc_samples: int = 360
    max_arc_visits_per_node: int = 12
    share_seeds: bool = True
    collinear_fraction: float = 0.05
    heuristic: bool = True

    def __post_init__(self) -> None:
        if self.max_waypoints < 0 or self.arc_samples < 8 or self.max_arc_visits_per_node < 1:
            raise InputError("invalid planner limits", where="PlannerParams",
                             expected="max_waypoints >= 0, arc_samples >= 8, visits >= 1")


@dataclass(frozen=True, eq=False)
class WayPoint:
    """A target point for the agent.

    ``kind`` is ``"candidate"`` (Fig. 5.3), ``"vertex"`` (Fig. 5.4), ``"midpoint"`` (Fig. 5.5),
    ``"shared"`` (centroid of several) or ``"arc"`` (fallback). ``targets`` are the unlocalized
    nodes it is meant for and ``seed`` the seed nodes used (indices in the augmented framework).
    """

    position_m: FloatArray
    kind: str
    targets: tuple[int, ...]
    seed: tuple[int, ...] = ()


@dataclass(eq=False)
class AugmentedFramework:
    """The network plus the temporary agent nodes (indices ``n, n+1, ...``)."""

    net: Network
    temp_m: list[FloatArray] = field(default_factory=list)
    temp_links: list[tuple[int, int, float]] = field(default_factory=list)
    temp_sigma_m: list[float] = field(default_factory=list)

    @property
    def n_total(self) -> int:
        """Real plus temporary nodes."""
        return self.net.n_nodes + len(self.temp_m)

    def add(self, position_m: FloatArray, nodes: IntArray, ranges_m: FloatArray,
            sigma_m: float = 0.0) -> int:
        """Add a temporary node linked to ``nodes`` with position sigma ``sigma_m``."""
        t = len(self.temp_m)
        self.temp_m.append(np.asarray(position_m, dtype=np.float64).reshape(2).copy())
        self.temp_sigma_m.append(float(sigma_m))
        for k, r in zip(nodes.tolist(), ranges_m.tolist(), strict=True):
            self.temp_links.append((t, int(k), float(r)))
        return self.net.n_nodes + t

    def adjacency(self) -> Adjacency:
        """Adjacency of the augmented graph."""
        n = self.net.n_nodes
        if self.temp_links:
            arr = np.array(self.temp_links, dtype=np.float64)
            a = arr[:, 0].astype(np.int64) + n
            b = arr[:, 1].astype(np.int64)
            e = np.vstack([self.net.edges, np.stack([np.minimum(a, b), np.maximum(a, b)], 1)])
            d = np.concatenate([self.net.distance_m, np.maximum(arr[:, 2], 0.0)])
        else:
            e, d = self.net.edges, self.net.distance_m
        return build_adjacency(self.n_total, e, d)

    def localize(self, params: PropagationParams | None) -> Localization:
        """SELA on the augmented framework (anchors and temporary nodes are the seeds)."""
        n = self.net.n_nodes
        nt = self.n_total
        pos = np.zeros((nt, 2))
        pos[:n][self.net.anchor] = self.net.position_m[self.net.anchor]
        if self.temp_m:
            pos[n:] = np.array(self.temp_m)
        loc = np.zeros(nt, dtype=bool)
        loc[:n] = self.net.anchor
        loc[n:] = True
        meth = np.zeros(nt, dtype=np.int8)
        meth[:n][self.net.anchor] = M_ANCHOR
        meth[n:] = M_AGENT
        sig = np.zeros(nt)
        k = min(len(self.temp_sigma_m), nt - n)
        sig[n:n + k] = self.temp_sigma_m[:k]
        return propagate(nt, self.adjacency(), self.net.radius_m, positions_m=pos,
                         localized=loc, method=meth, use_shadow=True, params=params,
                         initial_sigma_m=sig)


def _localized_neighbours(adj: Adjacency, loc: BoolArray, u: int) -> tuple[IntArray, FloatArray]:
    s, e = adj.indptr[u], adj.indptr[u + 1]
    nb = adj.indices[s:e]
    d = adj.distance_m[s:e]
    m = loc[nb]
    return nb[m], d[m]


def _pair_index(pts: FloatArray) -> tuple[int, int]:
    dm = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    ia, ib = np.unravel_index(int(np.argmax(np.triu(dm, 1))), dm.shape)
    return int(ia), int(ib)


def _farthest_pair(adj: Adjacency, loc: Localization, u: int) -> FloatArray:
    """Positions of the two localized neighbours of ``u`` that give its candidates, ``(2, 2)``."""
    pts = loc.estimate_m[_localized_neighbours(adj, loc.localized, u)[0]]
    return pts[list(_pair_index(pts))]


def _surviving_candidates(
    u: int, adj: Adjacency, loc: Localization, rho: float, params: PropagationParams
) -> list[FloatArray]:
    """Candidates of a 2-covered node not ruled out by ranges or a non-linked localized node."""
    nb, d = _localized_neighbours(adj, loc.localized, u)
    pts = loc.estimate_m[nb]
    ia, ib = _pair_index(pts)
    tol = params.range_tolerance_fraction * rho
    try:
        cands = circle_candidates(pts[ia], float(d[ia]), pts[ib], float(d[ib]), tolerance_m=tol)
    except InputError:
        return []
    linked = set(adj.indices[adj.indptr[u]:adj.indptr[u + 1]].tolist())
    others = np.array([j for j in np.flatnonzero(loc.localized) if j not in linked and j != u],
                      dtype=np.int64)
    lim = rho * (1.0 - params.shadow_margin_fraction)
    out = []
    for c in cands:
        if np.any(np.abs(np.linalg.norm(pts - c, axis=1) - d) > tol):
            continue
        if others.size and np.any(np.linalg.norm(loc.estimate_m[others] - c, axis=1) < lim):
            continue
        out.append(c)
    if len(out) == 2 and np.linalg.norm(out[0] - out[1]) <= 1e-12 * rho:
        out = out[:1]
    return out


def plan_waypoints(
    aug: AugmentedFramework,
    loc: Localization,
    *,
    params: PlannerParams | None = None,
    prop_params: PropagationParams | None = None,
) -> list[WayPoint]:
    """One planning round of the mission planner (see module docstring)."""
    prm = params or PlannerParams()
    pp = prop_params or PropagationParams()
    net = aug.net
    n = net.n_nodes
    rho = net.radius_m
    adj = aug.adjacency()
    localized = loc.localized
    lpos = loc.estimate_m
    lidx = np.flatnonzero(localized)
    centroid = lpos[lidx].mean(axis=0) if lidx.size else np.zeros(2)
    out: list[WayPoint] = []
    pivot_items: list[tuple[int, tuple[int, ...], FloatArray, str]] = []
    for u in range(n):
        if localized[u]:
            continue
        nb, _ = _localized_neighbours(adj, localized, u)
        if nb.size >= 2:
            cands = _surviving_candidates(u, adj, loc, rho, pp)
            if not cands:
                continue
            c = min(cands, key=lambda q: float(np.linalg.norm(q - centroid)))
            pair = _farthest_pair(adj, loc, u)
            if _collinear_with_seed(c, pair, prm.collinear_fraction * rho):
                c = _separating_point(pair, np.mean(cands, axis=0), rho, centroid)
            out.append(WayPoint(position_m=c, kind="candidate", targets=(u,)))
        elif nb.size == 1 and prm.heuristic:
            p = int(nb[0])
            others = lidx[lidx != p]
            if others.size < 2:
                continue
            dd = np.linalg.norm(lpos[others] - lpos[p], axis=1)
            pick = others[np.argsort(dd, kind="stable")[:2]]
            seed = (p, int(pick[0]), int(pick[1]))
            sp = lpos[list(seed)]
            lo = sp.max(axis=0) - rho  # eq. 5.2-5.3: intersection of the squares S_i
            hi = sp.min(axis=0) + rho
            if np.any(lo > hi):
                continue
            verts = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
            dv = np.linalg.norm(verts - lpos[p], axis=1)
            order = np.argsort(dv, kind="stable")
            v = verts[order[0]]
            kind = "vertex"
            if _collinear_with_seed(v, sp, prm.collinear_fraction * rho):
                v = 0.5 * (verts[order[0]] + verts[order[1]])
                kind = "midpoint"
            pivot_items.append((u, seed, v, kind))
    if prm.share_seeds and pivot_items:
        out.extend(_share(pivot_items))
    else:
        out.extend(WayPoint(position_m=v, kind=k, targets=(u,), seed=s)
                   for u, s, v, k in pivot_items)
    return out


def _separating_point(pair_m: FloatArray, mid_m: FloatArray, rho: float,
                      centroid: FloatArray) -> FloatArray:
    """Candidate way point for candidates almost on the line of their two neighbours.

    Such candidates are close to each other (the agent stood almost on the node): standing on
    one adds a nearly collinear range, or revisits the same place. The way point is half ``rho``
    from ``mid_m`` (the candidates' midpoint) across the line ``pair_m``: the node is heard there,
    the ranges to the two candidates differ by their whole separation and the three ranges are
    far from collinear.
    """
    t = pair_m[1] - pair_m[0]
    e = np.array([-t[1], t[0]]) / max(float(np.hypot(*t)), 1e-300)
    w = (mid_m + 0.5 * rho * e, mid_m - 0.5 * rho * e)
    return min(w, key=lambda q: float(np.linalg.norm(q - centroid)))


def _collinear_with_seed(v: FloatArray, seed_m: FloatArray, tol_m: float) -> bool:
    for a in range(len(seed_m)):
        for b in range(a + 1, len(seed_m)):
            t = seed_m[b] - seed_m[a]
            ln = float(np.hypot(*t))
            if ln <= 0:
                continue
            w = v - seed_m[a]
            dist = abs(float(t[0] * w[1] - t[1] * w[0])) / ln
            if dist < tol_m:
                return True
    return False


def _share(items: list[tuple[int, tuple[int, ...], FloatArray, str]]) -> list[WayPoint]:
    """Merge pivot way points whose seeds share >= 2 nodes (union-find, centroid)."""
    parent = list(range(len(items)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(len(items)):
        for j in range(i + 1, len(items)):
            if len(set(items[i][1]) & set(items[j][1])) >= 2:
                parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(items)):
        groups.setdefault(find(i), []).append(i)
    out = []
    for members in groups.values():
        if len(members) == 1:
            u, s, v, k = items[members[0]]
            out.append(WayPoint(position_m=v, kind=k, targets=(u,), seed=s))
        else:
            pts = np.array([items[i][2] for i in members])
            seed = tuple(sorted({x for i in members for x in items[i][1]}))
            out.append(WayPoint(position_m=pts.mean(axis=0), kind="shared",
                                targets=tuple(items[i][0] for i in members), seed=seed))
    return out


def arc_waypoint(
    aug: AugmentedFramework,
    loc: Localization,
    u: int,
    *,
    params: PlannerParams | None = None,
    prop_params: PropagationParams | None = None,
) -> WayPoint | None:
    """Fallback way point for a frontier node ``u`` (middle of the longest feasible arc)."""
    prm = params or PlannerParams()
    pp = prop_params or PropagationParams()
    rho = aug.net.radius_m
    adj = aug.adjacency()
    nb, d = _localized_neighbours(adj, loc.localized, u)
    if nb.size == 0:
        return None
    p = loc.estimate_m[nb[0]]
    th = np.linspace(0.0, 2.0 * np.pi, prm.arc_samples, endpoint=False)
    s = p + float(d[0]) * np.stack([np.cos(th), np.sin(th)], axis=1)
    tol = max(pp.range_tolerance_fraction * rho, 0.02 * rho)
    # Position uncertainty of the localized nodes (a tracked agent's temporary nodes carry the
    # agent's tracking error) widens every constraint by three of its sigmas.
    slack = 3.0 * (loc.sigma_m[nb[0]] + loc.sigma_m)
    ranges_ok = np.ones(th.size, dtype=bool)
    for j, dj in zip(nb[1:].tolist(), d[1:].tolist(), strict=True):
        res = np.abs(np.linalg.norm(s - loc.estimate_m[j], axis=1) - dj)
        ranges_ok &= res <= tol + slack[j]
    linked = set(adj.indices[adj.indptr[u]:adj.indptr[u + 1]].tolist())
    others = np.array([j for j in np.flatnonzero(loc.localized) if j not in linked and j != u],
                      dtype=np.int64)
    lim = rho * (1.0 - pp.shadow_margin_fraction)
    shadow_ok = np.ones(th.size, dtype=bool)
    if others.size:
        dist = np.linalg.norm(s[:, None, :] - loc.estimate_m[others][None], axis=2)
        shadow_ok = np.all(dist >= lim - slack[others][None, :], axis=1)
    ok = ranges_ok & shadow_ok
    if not ok.any():
        # The ranges to the other localized neighbours disagree with every point of the circle
        # (inconsistent node estimates): search the circle with the shadow constraints only.
        ok = shadow_ok
    if not ok.any():
        return None
    if ok.all():
        k = 0
    else:
        # longest circular run of feasible samples
        start = int(np.flatnonzero(~ok)[0]) + 1
        rolled = np.roll(ok, -start)
        best_len, best_mid, run = 0, 0, 0
        for i, f in enumerate(rolled):
            run = run + 1 if f else 0
            if run > best_len:
                best_len, best_mid = run, i - run // 2
        k = (best_mid + start) % th.size
    return WayPoint(position_m=s[k], kind="arc", targets=(u,), seed=(int(nb[0]),))


@dataclass(frozen=True, eq=False)
class SafeNavigationResult:
    """Outcome of the Safe Navigation Algorithm.

    Attributes
    ----------
    localization:
        Final localization of the real nodes (first ``n`` entries of the augmented result).
    augmented:
        Localization of the augmented framework (real + temporary agent nodes).
    waypoints:
        Visited way points, in order.
    temp_positions_m:
        Agent's estimated position at every visited way point (the temporary nodes).
    path_m, path_true_m:
        Agent's estimated and true path.
    distance_m:
        True distance walked, m.
    initial:
        SELA result before the agent moved.
    complete:
        All real nodes localized.
    temp_links:
        ``(way-point index, node index, range)`` of every link of the temporary agent nodes.
    """

    localization: Localization
    augmented: Localization
    waypoints: tuple[WayPoint, ...]
    temp_positions_m: FloatArray
    path_m: FloatArray
    path_true_m: FloatArray
    distance_m: float
    initial: Localization
    complete: bool
    temp_links: tuple[tuple[int, int, float], ...] = ()


def real_nodes(loc: Localization, n: int) -> Localization:
    """Restrict an augmented-framework localization to the first ``n`` (real) nodes."""
    order = loc.order[loc.order < n]
    wit = np.where(loc.witness[:n] < n, loc.witness[:n], -1)
    return Localization(estimate_m=loc.estimate_m[:n].copy(), localized=loc.localized[:n].copy(),
                        method=loc.method[:n].copy(), status=loc.status[:n].copy(),
                        witness=wit, order=order, sigma_m=loc.sigma_m[:n].copy())


def safe_navigation(
    net: Network,
    agent: MobileAgent,
    *,
    params: PlannerParams | None = None,
    prop_params: PropagationParams | None = None,
) -> SafeNavigationResult:
    """Run SELA -> planner -> agent walk until every node is localized or nothing more can be done.

    Nodes not connected (through links) to the localized part are never reachable by this
    algorithm; they stay unlocalized and ``complete`` is False.
    """
    prm = params or PlannerParams()
    pp = prop_params or PropagationParams()
    n = net.n_nodes
    aug = AugmentedFramework(net)
    loc = aug.localize(pp)
    initial = real_nodes(loc, n)
    visited: list[WayPoint] = []
    legs: list[AgentLeg] = []
    arc_visits: dict[int, int] = {}
    hopeless: set[int] = set()

    def visit(wp: WayPoint) -> Localization:
        lm = np.flatnonzero(loc.localized[:n])
        leg = agent.go_to(wp.position_m, Landmarks(node=lm, position_m=loc.estimate_m[lm],
                                                   sigma_m=loc.sigma_m[lm]))
        legs.append(leg)
        visited.append(wp)
        sc = leg.scan
        sigma = float(np.sqrt(max(np.linalg.eigvalsh(leg.covariance_m2)[-1], 0.0)))
        aug.add(leg.estimate_m, sc.node[sc.linked], sc.range_m[sc.linked], sigma)
        return aug.localize(pp)

    while len(visited) < prm.max_waypoints:
        if np.all(loc.localized[:n]):
            break
        before = int(np.count_nonzero(loc.localized[:n]))
        plan = plan_waypoints(aug, loc, params=prm, prop_params=pp)
        plan = _tour(plan, agent.estimate()[0])
        for wp in plan:
            if len(visited) >= prm.max_waypoints:
                break
            if all(loc.localized[t] for t in wp.targets):
                continue
            if _already_visited(wp.position_m, visited, tol_m=1e-3 * net.radius_m):
                continue  # the same ranges again: no new information
            loc = visit(wp)
        if int(np.count_nonzero(loc.localized[:n])) > before:
            continue
        # no progress: arc search for one frontier node
        adj = aug.adjacency()
        frontier = [
            u for u in range(n)
            if not loc.localized[u] and u not in hopeless
            and _localized_neighbours(adj, loc.localized, u)[0].size >= 1
        ]
        if not frontier:
            break
        est = agent.estimate()[0]
        frontier.sort(key=lambda u: _frontier_key(adj, loc, u, est))
        u = frontier[0]
        wp_arc = arc_waypoint(aug, loc, u, params=prm, prop_params=pp)
        arc_visits[u] = arc_visits.get(u, 0) + 1
        if wp_arc is None or arc_visits[u] > prm.max_arc_visits_per_node:
            hopeless.add(u)
            continue
        loc = visit(wp_arc)
    real = real_nodes(loc, n)
    path = np.vstack([leg.path_m for leg in legs]) if legs else np.zeros((0, 2))
    path_true = np.vstack([leg.path_true_m for leg in legs]) if legs else np.zeros((0, 2))
    temps = np.array(aug.temp_m).reshape(-1, 2)
    return SafeNavigationResult(
        localization=real, augmented=loc, waypoints=tuple(visited), temp_positions_m=temps,
        path_m=path, path_true_m=path_true, distance_m=float(sum(g.length_m for g in legs)),
        initial=initial, complete=bool(np.all(real.localized)),
        temp_links=tuple(aug.temp_links),
    )


def _already_visited(position_m: FloatArray, visited: list[WayPoint], *, tol_m: float) -> bool:
    return any(float(np.linalg.norm(w.position_m - position_m)) <= tol_m for w in visited)


def _frontier_key(adj: Adjacency, loc: Localization, u: int, here: FloatArray) -> tuple[int, float]:
    nb, _ = _localized_neighbours(adj, loc.localized, u)
    return (-int(nb.size), float(np.linalg.norm(loc.estimate_m[nb[0]] - here)))


def _tour(plan: list[WayPoint], start_m: FloatArray) -> list[WayPoint]:
    """Order way points by a greedy nearest-neighbour tour from the agent's position."""
    rest = list(plan)
    out: list[WayPoint] = []
    here = np.asarray(start_m, dtype=np.float64)
    while rest:
        k = int(np.argmin([np.linalg.norm(w.position_m - here) for w in rest]))
        w = rest.pop(k)
        out.append(w)
        here = w.position_m
    return out
