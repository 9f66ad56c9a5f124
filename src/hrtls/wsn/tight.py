"""Tight cooperation: localizing an anchor-free network with a mobile agent (thesis Sec. 5.4).

Algorithm 1 (read as follows). The network has no anchors; the agent knows its own position
(it is localized during the motion, e.g. the robot's EKF) and the number of nodes ``N``.

1. The agent explores until it hears a node, homes in on it and, once within ``Delta`` (eq. 5.6),
   assigns it its own estimated position (``SetPosition``, method ``agent``).
2. Next target: among the unlocalized nodes linked to a localized one, the one of largest degree,
   ties broken by the smallest measured distance to its localized neighbour (thesis Sec. 6.4.2).
   The agent homes in on it and assigns it too. After every assignment trilateration and shadow
   edges (``N_3``, ``N_2`` of eq. 5.7-5.9) propagate from everything localized so far, so after
   the first three non-collinear assignments the network localizes itself as far as it can.
3. When no unlocalized node is linked to the localized part but fewer than ``N`` are localized,
   the agent sweeps the bounding box of the localized nodes grown by its radio range ``d_r``
   (Theorem 2: components within ``d_r`` are found), then the whole search region. A node heard
   on the way is reached through the agent's radio (the *bridge link*) and assigned.
4. Stop when all ``N`` nodes are localized or nothing new can be found.

Homing on a node whose position is unknown (Fig. 5.6): its admissible positions are kept as
points on the circle given by a range (to a localized neighbour, or to the agent when it was
heard), pruned by every later range the agent measures and by the shadow of localized nodes that
do not hear it; the agent drives to the centroid of the cluster of admissible points nearest to
it, measures again, and repeats until the range is below ``Delta``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.wsn._propagation import M_AGENT
from hrtls.wsn.agents import AgentLeg, Landmarks, MobileAgent, RangeScan
from hrtls.wsn.network import Network
from hrtls.wsn.trilateration import Localization, PropagationParams, propagate, trilaterate

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, kw_only=True)
class TightParams:
    """Parameters of tight cooperation.

    Attributes
    ----------
    delta_m:
        ``Delta`` of eq. 5.6: the agent assigns its position to a node heard closer than this, m.
    radio_range_m:
        Agent's radio range ``d_r`` (Theorem 2 uses ``2 rho``), m.
    search_region_m:
        ``(xmin, ymin, xmax, ymax)`` of the area to explore, m.
    range_noise_fraction:
        Relative range noise assumed when pruning admissible points.
    n_points:
        Admissible points kept on a circle while homing.
    max_homing_legs:
        Legs spent on one node before it is given up.
    max_legs:
        Total leg budget.
    cluster_fraction:
        Admissible points within this fraction of ``rho`` of the nearest one form the cluster
        whose centroid is the next target.
    """

    delta_m: float
    radio_range_m: float
    search_region_m: tuple[float, float, float, float]
    range_noise_fraction: float = 0.0
    n_points: int = 720
    max_homing_legs: int = 30
    max_legs: int = 3000
    cluster_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not (self.delta_m > 0 and self.radio_range_m > 0):
            raise InputError("delta_m and radio_range_m must be positive", where="TightParams",
                             expected="> 0")
        x0, y0, x1, y1 = self.search_region_m
        if not (x1 > x0 and y1 > y0):
            raise InputError(f"search region {self.search_region_m}", where="TightParams",
                             expected="(xmin, ymin, xmax, ymax) with xmax > xmin, ymax > ymin")


def tight_propagation_params(delta_m: float, radius_m: float,
                             range_noise_fraction: float = 0.0) -> PropagationParams:
    """Tolerances for positions assigned by an agent (errors up to about ``Delta``).

    The assigned nodes carry a position sigma (see :func:`tight_cooperation`), so the residual,
    flip and shadow tolerances grow with the error each node inherits; GDOP <= 2.5, spread
    >= 0.1 rho and a propagated sigma of at most 0.15 rho keep error accumulation from turning
    into wrong placements.
    """
    s = range_noise_fraction
    floor = 1e-3  # keeps a GDOP-scaled term even with exact ranges
    return PropagationParams(range_tolerance_fraction=min(0.5, 6.0 * s + 1e-7),
                             min_spread_fraction=0.1,
                             shadow_margin_fraction=min(0.5, 3.0 * s + 1e-7),
                             max_gdop=2.5, range_sigma_fraction=max(s, floor),
                             max_sigma_fraction=0.15)


@dataclass(frozen=True, eq=False)
class TightResult:
    """Outcome of tight cooperation.

    Attributes
    ----------
    localization:
        Final localization (methods: agent, trilateration, shadow-edge).
    assigned:
        Nodes the agent assigned, in order (``SetPosition``).
    legs:
        Number of agent legs (homing and exploration moves).
    distance_m:
        True distance travelled by the agent, m.
    path_m, path_true_m:
        Estimated and true agent path.
    complete:
        All nodes localized.
    """

    localization: Localization
    assigned: IntArray
    legs: int
    distance_m: float
    path_m: FloatArray
    path_true_m: FloatArray
    complete: bool


class _Run:
    def __init__(self, net: Network, agent: MobileAgent, prm: TightParams,
                 pp: PropagationParams) -> None:
        self.net = net
        self.agent = agent
        self.prm = prm
        self.pp = pp
        n = net.n_nodes
        self.set_pos = np.zeros((n, 2))
        self.set_sigma = np.zeros(n)
        self.assigned: list[int] = []
        self.loc = self._propagate()
        self.legs: list[AgentLeg] = []
        self.given_up: set[int] = set()

    def _propagate(self) -> Localization:
        n = self.net.n_nodes
        mask = np.zeros(n, dtype=bool)
        mask[self.assigned] = True
        meth = np.where(mask, M_AGENT, 0).astype(np.int8)
        return propagate(n, self.net.adjacency, self.net.radius_m, positions_m=self.set_pos,
                         localized=mask, method=meth, use_shadow=True, params=self.pp,
                         initial_sigma_m=self.set_sigma)

    def budget_left(self) -> bool:
        return len(self.legs) < self.prm.max_legs

    def move(self, target: FloatArray) -> RangeScan:
        lm = np.flatnonzero(self.loc.localized)
        leg = self.agent.go_to(target, Landmarks(node=lm, position_m=self.loc.estimate_m[lm],
                                                 sigma_m=self.prm.delta_m))
        self.legs.append(leg)
        return leg.scan

    def assign(self, v: int) -> None:
        est, cov = self.agent.estimate()
        self.set_pos[v] = est
        # the node is within Delta of the agent: uniform in a disk -> sigma Delta / 2 per axis
        self.set_sigma[v] = float(np.hypot(0.5 * self.prm.delta_m,
                                           np.sqrt(max(np.linalg.eigvalsh(cov)[-1], 0.0))))
        self.assigned.append(v)
        self.loc = self._propagate()

    # -- homing ------------------------------------------------------------------------------
    def _circle(self, center: FloatArray, radius: float) -> FloatArray:
        th = np.linspace(0.0, 2.0 * np.pi, self.prm.n_points, endpoint=False)
        return center + radius * np.stack([np.cos(th), np.sin(th)], axis=1)

    def _tol(self, r: float) -> float:
        _, cov = self.agent.estimate()
        s_agent = float(np.sqrt(max(np.trace(cov), 0.0)))
        return 3.0 * (self.prm.range_noise_fraction * r + s_agent) + 0.5 * self.prm.delta_m + (
            1e-9 * self.net.radius_m)

    def _prune_static(self, v: int, pts: FloatArray) -> FloatArray:
        """Keep points that agree with v's localized neighbours and are outside others' shadow."""
        net = self.net
        adj = net.adjacency
        loc = self.loc
        s, e = adj.indptr[v], adj.indptr[v + 1]
        nb = adj.indices[s:e]
        dd = adj.distance_m[s:e]
        keep = np.ones(pts.shape[0], dtype=bool)
        tol = self.pp.range_tolerance_fraction * net.radius_m
        for j, d in zip(nb.tolist(), dd.tolist(), strict=True):
            if loc.localized[j]:
                tj = tol + 4.0 * float(loc.sigma_m[j]) + 3.0 * self.prm.range_noise_fraction * d
                keep &= np.abs(np.linalg.norm(pts - loc.estimate_m[j], axis=1) - d) <= tj
        others = np.flatnonzero(loc.localized)
        others = others[~np.isin(others, nb)]
        others = others[others != v]
        if others.size:
            lim = net.radius_m * (1.0 - self.pp.shadow_margin_fraction) - 3.0 * loc.sigma_m[
                others]
            near = np.linalg.norm(pts[:, None, :] - loc.estimate_m[others][None], axis=2) < lim
            keep &= ~near.any(axis=1)
        return pts[keep]

    def home(self, v: int, scan: RangeScan | None) -> bool:
        """Drive to node ``v`` until it is heard within Delta; assign it. False if given up."""
        prm = self.prm
        net = self.net
        adj = net.adjacency
        pts = np.zeros((0, 2))
        s, e = adj.indptr[v], adj.indptr[v + 1]
        nb = adj.indices[s:e]
        ln = nb[self.loc.localized[nb]]
        if ln.size:
            k = int(np.flatnonzero(self.loc.localized[nb])[0])
            pts = self._prune_static(v, self._circle(self.loc.estimate_m[ln[0]],
                                                     float(adj.distance_m[s + k])))
        if scan is None:
            scan = self.agent.scan()
        history: list[tuple[FloatArray, float]] = []
        for _ in range(prm.max_homing_legs):
            here, _ = self.agent.estimate()
            heard = None
            if scan is not None:
                hit = np.flatnonzero(scan.node == v)
                if hit.size:
                    heard = float(scan.range_m[hit[0]])
            if heard is not None and heard <= prm.delta_m:
                self.assign(v)
                return True
            if heard is not None:
                tol = self._tol(heard)
                if pts.shape[0]:
                    pts = pts[np.abs(np.linalg.norm(pts - here, axis=1) - heard) <= tol]
                if pts.shape[0] == 0:
                    pts = self._prune_static(v, self._circle(here, heard))
                    if pts.shape[0] == 0:
                        pts = self._circle(here, heard)
            elif pts.shape[0]:
                # not heard: outside the radio range of the current place
                pts = pts[np.linalg.norm(pts - here, axis=1) > prm.radio_range_m - self._tol(
                    prm.radio_range_m)]
            if heard is not None:
                history.append((here.copy(), heard))
            if not self.budget_left() or (pts.shape[0] == 0 and not history):
                return False
            target = self._homing_target(pts, here, history)
            scan = self.move(target)
        return False

    def _homing_target(
        self, pts: FloatArray, here: FloatArray, history: list[tuple[FloatArray, float]]
    ) -> FloatArray:
        """Next place to go while homing on a node.

        Ranges heard from >= 3 well-spread places give a least-squares fix (multilateration
        from the agent's own positions); otherwise the centroid of the nearest cluster of
        admissible points; when that is where the agent already stands, a probing move of one
        range length (directions 0, 120, 240 degrees) provides a new, non-collinear range.
        """
        prm = self.prm
        rho = self.net.radius_m
        if len(history) >= 3:
            q = np.array([h for h, _ in history[-6:]])
            r = np.array([d for _, d in history[-6:]])
            c = q - q.mean(axis=0)
            spread = float(np.sqrt(max(np.linalg.eigvalsh(c.T @ c)[0], 0.0) / len(r)))
            if spread >= 0.1 * float(r.min()) and spread > 0:
                x, _ = trilaterate(q, r)
                return x
        if pts.shape[0]:
            d0 = np.linalg.norm(pts - here, axis=1)
            nearest = pts[int(np.argmin(d0))]
            cl = pts[np.linalg.norm(pts - nearest, axis=1) <= prm.cluster_fraction * rho]
            target = cl.mean(axis=0)
            if np.linalg.norm(target - here) > 0.5 * prm.delta_m:
                return target
        r_last = history[-1][1] if history else prm.delta_m
        ang = 2.0 * np.pi / 3.0 * (len(history) % 3)
        return here + r_last * np.array([np.cos(ang), np.sin(ang)])

    # -- exploration ---------------------------------------------------------------------------
    def sweep_points(self, box: tuple[float, float, float, float]) -> FloatArray:
        x0, y0, x1, y1 = box
        step = 0.9 * np.sqrt(2.0) * self.prm.radio_range_m
        xs = np.arange(x0, x1 + 1e-12, step) if x1 > x0 else np.array([x0])
        ys = np.arange(y0, y1 + 1e-12, step) if y1 > y0 else np.array([y0])
        if xs[-1] < x1 - 1e-12:
            xs = np.append(xs, x1)
        if ys[-1] < y1 - 1e-12:
            ys = np.append(ys, y1)
        out: list[tuple[float, float]] = []
        for i, y in enumerate(ys):
            row = xs if i % 2 == 0 else xs[::-1]
            out.extend((x, y) for x in row)
        return np.array(out)

    def explore(self) -> tuple[int, RangeScan] | None:
        """Sweep for an unlocalized node; returns (node, scan where it was heard)."""
        boxes = []
        sr = self.prm.search_region_m
        if self.loc.localized.any():
            p = self.loc.estimate_m[self.loc.localized]
            g = self.prm.radio_range_m
            lo = np.maximum(p.min(axis=0) - g, (sr[0], sr[1]))
            hi = np.minimum(p.max(axis=0) + g, (sr[2], sr[3]))
            boxes.append((float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))
        boxes.append(sr)
        for box in boxes:
            pts = self.sweep_points(box)
            here, _ = self.agent.estimate()
            start = int(np.argmin(np.linalg.norm(pts - here, axis=1)))
            pts = np.roll(pts, -start, axis=0)
            for q in pts:
                if not self.budget_left():
                    return None
                sc = self.move(q)
                found = self._pick_heard(sc)
                if found is not None:
                    return found, sc
        return None

    def _pick_heard(self, sc: RangeScan) -> int | None:
        ok = [i for i, k in enumerate(sc.node.tolist())
              if not self.loc.localized[k] and k not in self.given_up]
        if not ok:
            return None
        best = min(ok, key=lambda i: float(sc.range_m[i]))
        return int(sc.node[best])

    def next_target(self) -> int | None:
        net = self.net
        adj = net.adjacency
        deg = np.diff(adj.indptr)
        best: tuple[int, float] | None = None
        pick = None
        for v in np.flatnonzero(~self.loc.localized).tolist():
            if v in self.given_up:
                continue
            s, e = adj.indptr[v], adj.indptr[v + 1]
            m = self.loc.localized[adj.indices[s:e]]
            if not m.any():
                continue
            key = (-int(deg[v]), float(adj.distance_m[s:e][m].min()))
            if best is None or key < best:
                best, pick = key, v
        return pick


def tight_cooperation(
    net: Network,
    agent: MobileAgent,
    *,
    params: TightParams,
    prop_params: PropagationParams | None = None,
) -> TightResult:
    """Localize an anchor-free network with a mobile agent (Algorithm 1, see module docstring).

    Anchors of ``net`` are ignored (tight cooperation has none).
    """
    pp = prop_params or tight_propagation_params(params.delta_m, net.radius_m,
                                                 params.range_noise_fraction)
    run = _Run(net, agent, params, pp)
    n = net.n_nodes
    while run.budget_left() and run.loc.n_localized < n:
        v = run.next_target()
        if v is not None:
            if not run.home(v, None):
                run.given_up.add(v)
            continue
        found = run.explore()
        if found is None:
            break
        v, sc = found
        if not run.home(v, sc):
            run.given_up.add(v)
    legs = run.legs
    path = np.vstack([g.path_m for g in legs]) if legs else np.zeros((0, 2))
    path_true = np.vstack([g.path_true_m for g in legs]) if legs else np.zeros((0, 2))
    return TightResult(localization=run.loc, assigned=np.array(run.assigned, dtype=np.int64),
                       legs=len(legs), distance_m=float(sum(g.length_m for g in legs)),
                       path_m=path, path_true_m=path_true,
                       complete=bool(run.loc.n_localized == n))
