"""Mission-level range SLAM: the agents' paths and the dropped nodes solved jointly.

:class:`hrtls.mission.nodes.NodeEstimator` localizes each node alone from the agents' filtered
estimates, so it cannot remove an error the agents share (a walker's step-length scale and heading
drift persist over the whole walk; only the tags at the entrance anchor the frame). This module
solves one nonlinear least-squares problem over every agent's decimated path and every node
(range-only SLAM on a pose chain).

Path model. Agent ``a``'s causal estimate rows are taken every ``decimate_s`` (``f_k`` at
``t_k``). Its tracker's corrections (every update that moved the position) are removed from
them: ``g_k`` is the dead reckoning (the rows without the corrections' jumps,
:mod:`hrtls.mission.correction_factors`; ``g = f`` for an agent without records; with
``heading_updates`` ``"chain"`` the magnetic heading's and tag bearings' jumps stay in it), with
increments ``d_k = g_{k+1} - g_k``. The poses ``x_k`` are unknowns tied by

    x_0 = f_0 + N(0, P_0),    x_{k+1} = x_k + (1 + s_j) R(phi_j) d_k + N(0, Q_k)

``P_0`` the agent's covariance at its first row (the start at the entrance), ``j`` the segment
(``segment_m`` walked) of increment ``k``, ``Q_k`` by ``increment_noise``
(:mod:`hrtls.mission.increment_noise`); a segment's step-length scale correction ``s_j`` and
rotation ``phi_j`` are random walks over the segments (``s_0 ~ N(0, scale_sigma^2)``,
``s_j - s_{j-1} ~ N(0, scale_walk_sigma^2)``, likewise ``heading_sigma_rad`` /
``heading_walk_rad``): the persistent part of the dead-reckoning error. These model a walker;
an agent with its own model (``AgentPath.chain``: a robot's from its odometry EKF,
:func:`hrtls.mission.increment_noise.robot_chain`) has its ``"length"`` increments, priors and
walks from it. An agent's position at
a range's or a correction's time is interpolated between its poses.

Corrections. Each correction after the first pose is a factor ``W (x(t) - z)`` with
``W^T W = P1^-1 - P0^-1`` (the information the update added to the tracker's position,
``(m0, P0) -> (m1, P1)``) and ``z`` the position it measured (derivation, and what it
approximates for other than position measurements: :mod:`hrtls.mission.correction_factors`):
the tags pin the map's shift and rotation. No factor: the ranges to nodes that are not the
agent's known landmarks (the problem's own nodes, or peers: their raw ranges are the
problem's) and, unless ``heading_updates`` is ``"factor"``, the magnetic heading and tag
bearings (their heading is already in the increments' directions).

Ranges. A range ``r`` from agent ``a`` at ``t`` to node ``p`` is
``sqrt(||p - x_a(t)||^2 + h^2) + e``, ``h`` one height difference between the agents' antennas
and the nodes (estimated, prior ``N(0, height_sigma_m^2)``), ``e`` the range noise (its sigma as
received, times ``sqrt(n)`` for ``n`` ranges of the pair within ``range_correlation_s``,
:mod:`hrtls.mission.range_weights`); walls lengthen ranges (NLOS): a robust loss (``loss``,
scale ``loss_scale`` sigmas). Ranges between agents tie their paths
(:mod:`hrtls.mission.graph_peers`), under the same loss.

Node covariances are the node blocks of ``(J^T W J)^-1`` at the solution (``W`` the robust
loss's weights there), times the mean square inlier residual (``|e| < 3 loss_scale``) whitened
by the sigmas as received when above one: of all ranges, or of the node's own when larger
(a node seen mostly through walls), and reported times the calibration ``node_cov_scale``
(``link_cov_scale`` too for a node with links). A node is solved with ``min_ranges`` ranges
at least from positions spread ``min_spread_m`` off a line, and counts as localized with a spread of
``localize_spread_m`` at least (seen from nearly a line, e.g. one corridor, a node helps the
poses but its position across the line is poorly known) and a sigma below ``max_sigma_m``.
Older poses may have left the problem as a dense prior factor
(:mod:`hrtls.mission.graph_window`), which then replaces the priors of its agents' first poses
and segments and of the height. Parameters: :class:`hrtls.mission.graph_params.SmootherParams`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, csr_matrix, diags

from hrtls.mission.graph_covariance import inverse_blocks, node_inflation, robust_weights, spd_lu
from hrtls.mission.graph_init import extend, linear_init, select_nodes
from hrtls.mission.graph_links import LinkRows, NodeLinks, select_linked
from hrtls.mission.graph_params import SmootherParams
from hrtls.mission.graph_peers import PeerRows, PeerSet, pose_weights
from hrtls.mission.graph_window import Layout, MarginalPrior, prior_columns, restrict
from hrtls.mission.increment_noise import ChainNoise, whitening
from hrtls.mission.range_weights import correlated_sigma

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class AgentPath:
    """One agent's causal estimate rows: name, time (s), xy (m), first row's covariance (m^2).

    ``dead_reckoning_m``: the rows without the tracker's correction jumps (None: the rows are
    the motion); ``factors``: its corrections as position factors, ``(t (K,), z (K, 2),
    W (K, 2, 2))`` (:mod:`hrtls.mission.correction_factors`), or None; ``walked0_m``: the
    distance walked before the first row (a path cut by :mod:`hrtls.mission.graph_window`);
    ``growth_m2``: the tracker's covariance growth curve at the rows
    (:mod:`hrtls.mission.increment_noise`), or None; ``chain``: the agent's own chain noise
    (its increments' ``"length"`` model and its segments' priors and walks), or None: the
    smoother's parameters.
    """

    name: str
    t: FloatArray
    xy_m: FloatArray
    start_cov_m2: FloatArray
    dead_reckoning_m: FloatArray | None = None
    factors: tuple[FloatArray, FloatArray, FloatArray] | None = None
    walked0_m: float = 0.0
    growth_m2: FloatArray | None = None
    chain: ChainNoise | None = None


@dataclass(frozen=True, eq=False)
class RangeSet:
    """Ranges to the nodes: agent index, time (s), node id, range (m), 1-sigma (m).

    ``floor``: the agent's floor at each range (:mod:`hrtls.mission.floors`; the solve does
    not read it), or None.
    """

    agent: IntArray
    t: FloatArray
    node: NDArray[np.str_]
    range_m: FloatArray
    sigma_m: FloatArray
    floor: IntArray | None = None


@dataclass(frozen=True, eq=False)
class SmootherResult:
    """Result of :func:`smooth`.

    ``nodes``: id -> (position (2,), covariance (2, 2), localized); per agent name: ``paths``
    its pose times and corrected poses, ``corrections`` its poses minus its rows there (warm
    start of the next solve), ``scale`` / ``heading_rad`` its segment corrections;
    ``height_m``: the estimated height difference; ``rms``: RMS whitened inlier range residual;
    ``evaluations``: cost evaluations of the solve; ``last_pose``: per agent the time, position
    and marginal covariance (inflated as the nodes') of its last pose.
    """

    nodes: dict[str, tuple[FloatArray, FloatArray, bool]]
    paths: dict[str, tuple[FloatArray, FloatArray]]
    corrections: dict[str, tuple[FloatArray, FloatArray]]
    scale: dict[str, FloatArray]
    heading_rad: dict[str, FloatArray]
    height_m: float
    rms: float
    evaluations: int
    last_pose: dict[str, tuple[float, FloatArray, FloatArray]] = field(default_factory=dict)


def _decimate(path: AgentPath, step_s: float
              ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """Pose times, the rows there, the dead reckoning there and the growth curve there."""
    t0, t1 = float(path.t[0]), float(path.t[-1])
    tq = np.arange(t0, t1, step_s)
    if tq.size == 0 or tq[-1] < t1:
        tq = np.append(tq, t1)
    dr = path.xy_m if path.dead_reckoning_m is None else path.dead_reckoning_m
    xy, g = (np.column_stack([np.interp(tq, path.t, a[:, 0]), np.interp(tq, path.t, a[:, 1])])
             for a in (path.xy_m, dr))
    gr = None if path.growth_m2 is None else np.stack(
        [np.interp(tq, path.t, path.growth_m2[:, i, j]) for i in (0, 1) for j in (0, 1)],
        axis=1).reshape(-1, 2, 2)
    return tq, xy, g, gr


class _Problem:
    """Unknowns, residuals and Jacobian of one solve.

    Columns: per agent its poses, then its segments' scales and rotations; the nodes; the
    height last. With a ``prior`` (:mod:`hrtls.mission.graph_window`) its agents' first-pose
    and first-segment priors and the height prior are its own; its rows come last.
    """

    def __init__(self, paths: list[AgentPath], ranges: RangeSet, node_ids: list[str],
                 prm: SmootherParams, prior: MarginalPrior | None = None,
                 links: NodeLinks | None = None, peers: PeerSet | None = None) -> None:
        self.prm = prm
        self.node_ids = node_ids
        self.t, self.f, self.pose_col, self.s_col, self.n_seg = [], [], [], [], []
        self.seg: list[IntArray] = []
        self.walked: list[FloatArray] = []
        odo: list[tuple[IntArray, IntArray, FloatArray, FloatArray]] = []
        self.chain = [p.chain or ChainNoise(
            odo_sigma_m=prm.odo_sigma_m, odo_fraction=prm.odo_fraction,
            scale_sigma=prm.scale_sigma, scale_walk_sigma=prm.scale_walk_sigma,
            heading_sigma_rad=prm.heading_sigma_rad, heading_walk_rad=prm.heading_walk_rad)
            for p in paths]
        col = 0
        for a, p in enumerate(paths):
            t, f, g, gr = _decimate(p, prm.decimate_s)
            d = np.diff(g, axis=0)
            walked = p.walked0_m + (np.cumsum(np.hypot(d[:, 0], d[:, 1]))
                                    - np.hypot(d[:, 0], d[:, 1]))
            seg = (np.floor(walked / prm.segment_m)
                   - math.floor(p.walked0_m / prm.segment_m)).astype(np.int64)
            self.seg.append(seg)
            self.walked.append(walked)
            n_seg = int(seg[-1]) + 1 if seg.size else 1
            self.t.append(t)
            self.f.append(f)
            self.pose_col.append(col)
            self.s_col.append(col + 2 * len(t))
            self.n_seg.append(n_seg)
            ch = self.chain[a]
            q = whitening(d, odo_sigma_m=ch.odo_sigma_m, odo_fraction=ch.odo_fraction,
                          growth_m2=gr if prm.increment_noise == "tracker" and p.chain is None
                          else None)
            odo.append((col + 2 * np.arange(len(t) - 1), col + 2 * len(t) + seg, d, q))
            col += 2 * len(t) + 2 * n_seg
        self.odo_k = np.concatenate([o[0] for o in odo]).astype(np.int64)
        self.odo_s = np.concatenate([o[1] for o in odo]).astype(np.int64)
        self.odo_phi = self.odo_s + np.repeat(np.asarray(self.n_seg, np.int64),
                                              [len(o[0]) for o in odo])
        self.odo_d = np.concatenate([o[2] for o in odo]).reshape(-1, 2)
        self.odo_w = np.concatenate([o[3] for o in odo]).reshape(-1, 2, 2)
        self.node_col = col
        self.height_col = col + 2 * len(node_ids)
        self.n = self.height_col + 1
        self.p0 = [np.linalg.cholesky(np.linalg.inv(p.start_cov_m2 + 1e-6 * np.eye(2))).T
                   for p in paths]
        self._ranges(ranges)
        self.links = LinkRows(links or NodeLinks.empty(), node_ids, self.node_col)
        self.peers = PeerRows(peers or PeerSet.empty(), self._at,
                              correlation_s=prm.range_correlation_s)
        self.n_robust = len(self.r) + len(self.links) + len(self.peers)
        self._factors(paths)
        self.names = [p.name for p in paths]
        self.first_w = np.array([0.0 if prior is not None and p.name in prior.agents else 1.0
                                 for p in paths])
        self.height_w = 1.0 if prior is None else 0.0
        self.prior, self.prior_cols = prior, np.zeros(0, np.int64)
        if prior is not None:
            cols = prior_columns(prior, self.layout())
            self.prior = prior if np.all(cols >= 0) else restrict(prior, cols >= 0)
            self.prior_cols = cols[cols >= 0]

    def layout(self) -> Layout:
        return Layout(self.names, self.t, self.pose_col, self.s_col, self.n_seg, self.seg,
                      self.walked, self.node_ids, self.node_col, self.height_col, self.n)

    def weighted(self, x: FloatArray) -> tuple[FloatArray, FloatArray, csr_matrix]:
        """Residuals, square roots of their IRLS weights and ``diag(sqrt w) J`` at ``x``.

        ``w``: the robust loss's ``rho'`` on the range rows, 1 on the others.
        """
        res = self.residuals(x)
        n_r = self.n_robust
        w = np.ones(res.size)
        w[:n_r] = robust_weights(res[:n_r] ** 2 / self.prm.loss_scale ** 2, self.prm.loss)
        sw = np.sqrt(w)
        return res, sw, csr_matrix(diags(sw) @ self.jacobian(x))

    def _prior_rows(self, x: FloatArray) -> FloatArray:
        p = self.prior
        if p is None:
            return np.zeros(0)
        return np.asarray(p.r @ (x[self.prior_cols] - p.xbar) + p.e, np.float64)

    def _at(self, a: int, tq: FloatArray) -> tuple[IntArray, IntArray, FloatArray]:
        """Columns of the poses around each of agent ``a``'s times and the weight of the later."""
        return pose_weights(self.t[a], self.pose_col[a], tq)

    def _factors(self, paths: list[AgentPath]) -> None:
        """The corrections after each agent's first pose (that pose's prior holds the earlier)."""
        parts: list[tuple[IntArray, IntArray, FloatArray, FloatArray, FloatArray]] = []
        for a, p in enumerate(paths):
            if p.factors is None:
                continue
            tf, z, wm = p.factors
            m = (tf > self.t[a][0]) & (tf <= self.t[a][-1])
            parts.append((*self._at(a, tf[m]), z[m], wm[m]))
        self.fc0 = np.concatenate([q[0] for q in parts]) if parts else np.zeros(0, np.int64)
        self.fc1 = np.concatenate([q[1] for q in parts]) if parts else np.zeros(0, np.int64)
        self.fw = np.concatenate([q[2] for q in parts]) if parts else np.zeros(0)
        self.fz = np.concatenate([q[3] for q in parts]) if parts else np.zeros((0, 2))
        self.fW = np.concatenate([q[4] for q in parts]) if parts else np.zeros((0, 2, 2))

    def _factor_parts(self, x: FloatArray) -> FloatArray:
        w = self.fw[:, None]
        xa = (1.0 - w) * _pairs(x, self.fc0) + w * _pairs(x, self.fc1)
        return np.einsum("nij,nj->ni", self.fW, xa - self.fz)

    def _ranges(self, ranges: RangeSet) -> None:
        index = {n: i for i, n in enumerate(self.node_ids)}
        keep = np.array([str(n) in index for n in ranges.node], dtype=bool)
        agent = ranges.agent[keep]
        self.rt = ranges.t[keep]
        self.rnode = np.array([index[str(n)] for n in ranges.node[keep]], dtype=np.int64)
        self.ragent = agent
        self.r = ranges.range_m[keep]
        self.s_raw = ranges.sigma_m[keep]
        self.s = correlated_sigma(agent, self.rnode, self.rt, self.s_raw,
                                  window_s=self.prm.range_correlation_s)
        self.c0 = np.zeros(len(self.rt), dtype=np.int64)
        self.c1 = np.zeros(len(self.rt), dtype=np.int64)
        self.w = np.zeros(len(self.rt))
        for a in range(len(self.t)):
            m = agent == a
            self.c0[m], self.c1[m], self.w[m] = self._at(a, self.rt[m])

    # ---------------------------------------------------------------- residuals
    def _range_parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        w = self.w[:, None]
        xa = (1.0 - w) * _pairs(x, self.c0) + w * _pairs(x, self.c1)
        diff = _pairs(x, self.node_col + 2 * self.rnode) - xa
        h = np.sqrt(np.sum(diff * diff, axis=1) + x[self.height_col] ** 2)
        return (self.r - h) / self.s, diff, h

    def _odo_parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        phi, k = x[self.odo_phi], 1.0 + x[self.odo_s]
        c, sn = np.cos(phi), np.sin(phi)
        d = self.odo_d
        rd = np.column_stack([c * d[:, 0] - sn * d[:, 1], sn * d[:, 0] + c * d[:, 1]])
        e = np.einsum("nij,nj->ni", self.odo_w,
                      _pairs(x, self.odo_k + 2) - _pairs(x, self.odo_k) - k[:, None] * rd)
        return e, rd, np.column_stack([-rd[:, 1], rd[:, 0]])

    def residuals(self, x: FloatArray) -> FloatArray:
        prm = self.prm
        out = [self._range_parts(x)[0], self.links.parts(x)[0], self.peers.parts(x)[0],
               self._odo_parts(x)[0].reshape(-1), self._factor_parts(x).reshape(-1)]
        for a, col in enumerate(self.pose_col):
            out.append(self.first_w[a] * self.p0[a] @ (x[col:col + 2] - self.f[a][0]))
            sc, n_seg = self.s_col[a], self.n_seg[a]
            sv, ph = x[sc:sc + n_seg], x[sc + n_seg:sc + 2 * n_seg]
            ch = self.chain[a]
            out.append(self.first_w[a] * np.array([sv[0] / ch.scale_sigma,
                                                   ph[0] / ch.heading_sigma_rad]))
            out.append(np.diff(sv) / ch.scale_walk_sigma)
            out.append(np.diff(ph) / ch.heading_walk_rad)
        out.append(np.array([self.height_w * x[self.height_col] / prm.height_sigma_m]))
        out.append(self._prior_rows(x))
        return np.concatenate(out)

    def jacobian(self, x: FloatArray) -> csr_matrix:
        prm = self.prm
        rows: list[IntArray] = []
        cols: list[IntArray] = []
        vals: list[FloatArray] = []

        def put(r: object, c: object, v: object) -> None:
            r_, c_ = np.atleast_1d(np.asarray(r, np.int64)), np.atleast_1d(np.asarray(c, np.int64))
            v_ = np.broadcast_to(np.asarray(v, np.float64), r_.shape)
            rows.append(r_)
            cols.append(c_)
            vals.append(np.array(v_))

        _, diff, h = self._range_parts(x)
        n_r = len(self.r)
        ri = np.arange(n_r)
        u = diff / (h * self.s)[:, None]
        for ax in (0, 1):
            put(ri, self.node_col + 2 * self.rnode + ax, -u[:, ax])
            put(ri, self.c0 + ax, (1.0 - self.w) * u[:, ax])
            put(ri, self.c1 + ax, self.w * u[:, ax])
        put(ri, np.full(n_r, self.height_col), -x[self.height_col] / (h * self.s))
        for r_, c_, v_ in zip(*self.links.jacobian(x, n_r), strict=True):
            put(r_, c_, v_)
        for r_, c_, v_ in zip(*self.peers.jacobian(x, n_r + len(self.links)), strict=True):
            put(r_, c_, v_)
        n_r = self.n_robust
        _, rd, rdp = self._odo_parts(x)
        k = 1.0 + x[self.odo_s]
        oi = n_r + 2 * np.arange(len(self.odo_k))
        wrd = np.einsum("nij,nj->ni", self.odo_w, rd)
        wrdp = np.einsum("nij,nj->ni", self.odo_w, rdp)
        for i in (0, 1):
            for ax in (0, 1):
                put(oi + i, self.odo_k + 2 + ax, self.odo_w[:, i, ax])
                put(oi + i, self.odo_k + ax, -self.odo_w[:, i, ax])
            put(oi + i, self.odo_s, -wrd[:, i])
            put(oi + i, self.odo_phi, -k * wrdp[:, i])
        row = n_r + 2 * len(self.odo_k)
        fi = row + 2 * np.arange(len(self.fw))
        for i in (0, 1):
            for ax in (0, 1):
                put(fi + i, self.fc0 + ax, (1.0 - self.fw) * self.fW[:, i, ax])
                put(fi + i, self.fc1 + ax, self.fw * self.fW[:, i, ax])
        row += 2 * len(self.fw)
        for a, col in enumerate(self.pose_col):
            for i in (0, 1):
                put([row + i, row + i], [col, col + 1], self.first_w[a] * self.p0[a][i])
            sc, n_seg, ch = self.s_col[a], self.n_seg[a], self.chain[a]
            put([row + 2, row + 3], [sc, sc + n_seg],
                self.first_w[a] * np.array([1.0 / ch.scale_sigma, 1.0 / ch.heading_sigma_rad]))
            row += 4
            for base, sig in ((sc, ch.scale_walk_sigma), (sc + n_seg, ch.heading_walk_rad)):
                j = np.arange(n_seg - 1)
                put(row + j, base + j + 1, 1.0 / sig)
                put(row + j, base + j, -1.0 / sig)
                row += n_seg - 1
        put(row, self.height_col, self.height_w / prm.height_sigma_m)
        m, d = (0, 0) if self.prior is None else self.prior.r.shape
        put(row + 1 + np.repeat(np.arange(m), d), np.tile(self.prior_cols, m),
            np.zeros(0) if self.prior is None else self.prior.r.reshape(-1))
        return csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(row + 1 + m, self.n))


def _pairs(x: FloatArray, col: IntArray) -> FloatArray:
    return np.column_stack([x[col], x[col + 1]])


def _initial(prob: _Problem, paths: list[AgentPath], initial_nodes: dict[str, FloatArray],
             warm: SmootherResult | None) -> FloatArray:
    x0 = np.zeros(prob.n)
    for a, col in enumerate(prob.pose_col):
        poses = prob.f[a].copy()
        name = paths[a].name
        if warm is not None and name in warm.corrections and len(warm.corrections[name][0]):
            tc, dc = warm.corrections[name]
            poses[:, 0] += np.interp(prob.t[a], tc, dc[:, 0])
            poses[:, 1] += np.interp(prob.t[a], tc, dc[:, 1])
            sc, n_seg = prob.s_col[a], prob.n_seg[a]
            for base, v in ((sc, warm.scale[name]), (sc + n_seg, warm.heading_rad[name])):
                m = min(n_seg, v.size)
                if m:
                    x0[base:base + n_seg] = v[m - 1]
                    x0[base:base + m] = v[:m]
            extend(poses, prob.f[a], int(np.searchsorted(prob.t[a], tc[-1], side="right")),
                    float(warm.scale[name][-1]), float(warm.heading_rad[name][-1]))
        x0[col:col + 2 * len(prob.t[a])] = poses.reshape(-1)
    x0[prob.height_col] = max(warm.height_m, 0.1) if warm is not None else 1.0
    raw = _pairs(x0, prob.c0) * (1.0 - prob.w[:, None]) + _pairs(x0, prob.c1) * prob.w[:, None]
    for i, n in enumerate(prob.node_ids):
        init = warm.nodes[n][0] if warm is not None and n in warm.nodes else initial_nodes.get(n)
        if init is None:
            m = prob.rnode == i
            init = linear_init(raw[m], np.sqrt(np.maximum(prob.r[m] ** 2 - x0[prob.height_col]
                                                           ** 2, 0.0)))
            if init is None or not np.all(np.isfinite(init)):
                init = raw[m].mean(axis=0)
        x0[prob.node_col + 2 * i:prob.node_col + 2 * i + 2] = init
    return x0


def smooth(paths: list[AgentPath], ranges: RangeSet, *, params: SmootherParams | None = None,
           initial_nodes: dict[str, FloatArray] | None = None,
           warm: SmootherResult | None = None, prior: MarginalPrior | None = None,
           links: NodeLinks | None = None, peers: PeerSet | None = None) -> SmootherResult:
    """Solve the agents' paths and the nodes jointly (module doc).

    ``initial_nodes``: starting positions of nodes (others: linear trilateration from the
    agents' rows); ``warm``: a previous solution to start from (its nodes and corrections);
    ``prior``: the marginalized older poses (:mod:`hrtls.mission.graph_window`; its nodes
    stay in the problem); ``links``: ranges between nodes (:mod:`hrtls.mission.graph_links`);
    ``peers``: ranges between agents (:mod:`hrtls.mission.graph_peers`).
    """
    prm = params or SmootherParams()
    initial = dict(initial_nodes or {})
    if prior is not None:
        for i, n in enumerate(prior.nodes):
            initial.setdefault(n, prior.xbar[4 * len(prior.agents) + 2 * i:][:2])
    start = {**initial, **({n: v[0] for n, v in warm.nodes.items() if v[2]} if warm else {})}
    spread, joined = select_linked(paths, ranges, links or NodeLinks.empty(),
                                   select_nodes(paths, ranges, prm), start, prm,
                                   max(warm.height_m, 0.1) if warm is not None else 1.0)
    for n, p in joined.items():
        initial.setdefault(n, p)
    ids = sorted(set(spread) | set(prior.nodes)) if prior is not None else list(spread)
    prob = _Problem(paths, ranges, ids, prm, prior, links, peers)
    x0 = _initial(prob, paths, initial, warm)
    x, evaluations = _solve(prob, x0)
    res, _, jac = prob.weighted(x)
    n_r = len(prob.r)
    inl = np.abs(res[:n_r]) < 3.0 * prm.loss_scale
    rms = float(np.sqrt(np.mean(res[:n_r][inl] ** 2))) if inl.any() else float("nan")
    last = [c + 2 * len(t) - 2 for c, t in zip(prob.pose_col, prob.t, strict=True)]
    pose_inflation = max(rms ** 2, 1.0) if math.isfinite(rms) else 1.0
    raw = res[:n_r] * prob.s / prob.s_raw          # whitened by the sigmas as received
    inflation = np.concatenate([node_inflation(raw, np.abs(raw) < 3.0 * prm.loss_scale,
                                               prob.rnode, len(prob.node_ids)),
                                np.full(len(last), pose_inflation)])
    cov = inverse_blocks(csc_matrix(jac.T @ jac), [prob.node_col + 2 * i for i in
                                            range(len(prob.node_ids))] + last, inflation)
    nodes: dict[str, tuple[FloatArray, FloatArray, bool]] = {}
    cov_k = prob.links.cov_scale(len(prob.node_ids), prob.node_col, prm)
    for i, n in enumerate(prob.node_ids):
        c = cov[i]
        ok = spread.get(n, 0.0) >= prm.localize_spread_m and bool(np.all(np.isfinite(c))) and \
            float(np.sqrt(max(np.linalg.eigvalsh(c)[-1], 0.0))) <= prm.max_sigma_m
        nodes[n] = (x[prob.node_col + 2 * i:prob.node_col + 2 * i + 2].copy(), cov_k[i] * c, ok)
    out_paths, corr, scale, heading = {}, {}, {}, {}
    for a, col in enumerate(prob.pose_col):
        name = paths[a].name
        poses = x[col:col + 2 * len(prob.t[a])].reshape(-1, 2).copy()
        out_paths[name] = (prob.t[a], poses)
        corr[name] = (prob.t[a], poses - prob.f[a])
        sc, n_seg = prob.s_col[a], prob.n_seg[a]
        scale[name] = x[sc:sc + n_seg].copy()
        heading[name] = x[sc + n_seg:sc + 2 * n_seg].copy()
    k = len(prob.node_ids)
    last_pose = {paths[a].name: (float(prob.t[a][-1]), x[c:c + 2].copy(), cov[k + a])
                 for a, c in enumerate(last)}
    return SmootherResult(nodes, out_paths, corr, scale, heading, float(abs(x[prob.height_col])),
                          rms, evaluations, last_pose)


def _cost(prob: _Problem, x: FloatArray) -> float:
    """Robust cost: ``sum rho`` of the range rows plus the squared prior and odometry rows."""
    res = prob.residuals(x)
    n_r = prob.n_robust
    c2 = prob.prm.loss_scale ** 2
    z = res[:n_r] ** 2 / c2
    loss = prob.prm.loss
    if loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "cauchy":
        rho = np.log1p(z)
    elif loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    else:
        rho = z
    return float(c2 * np.sum(rho) + np.sum(res[n_r:] ** 2))


def _solve(prob: _Problem, x0: FloatArray) -> tuple[FloatArray, int]:
    """Levenberg-Marquardt with iteratively reweighted range rows and a sparse direct solve.

    Returns the solution and the cost evaluations spent.
    """
    x, cost, lam, evaluations = x0.copy(), _cost(prob, x0), 1e-3, 1
    while evaluations < prob.prm.max_evaluations:
        res, sw, jw = prob.weighted(x)
        hess = csc_matrix(jw.T @ jw)
        grad = jw.T @ (sw * res)
        step = None
        while evaluations < prob.prm.max_evaluations and lam < 1e8:
            damped = csc_matrix(hess + diags(lam * (hess.diagonal() + 1e-9)))
            cand = x - spd_lu(damped).solve(grad)
            c = _cost(prob, cand)
            evaluations += 1
            if c < cost:
                step, x, cost, lam = cand - x, cand, c, max(lam / 3.0, 1e-7)
                break
            lam *= 5.0
        if step is None or float(np.max(np.abs(step))) < 1e-4:
            break
    return x, evaluations


def linearize(paths: list[AgentPath], ranges: RangeSet, node_ids: list[str], *,
              params: SmootherParams, prior: MarginalPrior | None,
              point: Callable[[Layout], FloatArray], links: NodeLinks | None = None,
              peers: PeerSet | None = None) -> tuple[Layout, csc_matrix, FloatArray]:
    """A solve's columns, information ``J^T W J`` and half-gradient ``J^T W r`` at a point.

    ``point``: the unknowns from the solve's columns; ``W``: the robust loss's weights there.
    """
    prob = _Problem(paths, ranges, node_ids, params, prior, links, peers)
    lay = prob.layout()
    res, sw, jw = prob.weighted(point(lay))
    return lay, csc_matrix(jw.T @ jw), np.asarray(jw.T @ (sw * res), np.float64)
