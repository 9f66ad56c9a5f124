"""Fixed-lag range SLAM: poses older than a window leave the smoother's problem as a prior.

With ``SmootherParams.window_s`` set, after each solve (:func:`hrtls.mission.graph.smooth`, at
``t_end``) every agent's poses before its cut pose ``c`` (the first pose at or after
``t_end - window_s``; at most its second-last, and at most its last stored row) are removed
from the problem by marginalization, with the segments ``j < j_c`` (``j_c`` the segment of
increment ``c``).

Removed rows. The rows the next problem no longer builds: the ranges before ``t_c``, the
corrections at or before ``t_c``, the increments before ``c``, the scale / rotation walks into
segment ``j_c``, the first-pose, first-segment and height priors, and the previous prior
factor. Linearized at the solution ``x`` with the robust loss's weights ``W`` there, they carry
the information ``H' = J'^T W J'`` and half-gradient ``g' = J'^T W r'``; both are computed as
those of the whole problem minus those of the kept rows (the next problem, built from the data
kept, evaluated at ``x``). With ``m`` the removed columns and ``k`` the prior's (per agent cut
so far its first kept pose and that pose's segment's scale and rotation; every node of the
problem; the height),

    P = H'_kk - H'_km H'_mm^-1 H'_mk,     b = g'_k - H'_km H'_mm^-1 g'_m

is the Gaussian the removed rows imply on the kept variables (the Schur complement: exact for
linear-Gaussian rows). With ``P = V diag(l) V^T`` (eigenvalues below ``MIN_INFO`` relative to
the largest dropped) the prior factor is the residual

    r_p(x_k) = R (x_k - xbar_k) + e,    R = diag(sqrt l) V^T,    e = diag(1 / sqrt l) V^T b

(``R^T R = P``, ``R^T e = b``: ``||r_p||^2 = const + 2 b^T dx + dx^T P dx``). Its Jacobian ``R``
stays the one at ``xbar`` (first estimates: removed rows are never relinearized; later solves
move the kept variables only through the rows that stay). A node first seen after a
marginalization has no prior rows; it joins the prior when one of its rows is removed. A node
in the prior stays in every later problem (its information is kept), even without ranges.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csc_matrix, identity

from hrtls.mission.graph_covariance import spd_lu

if TYPE_CHECKING:
    from hrtls.mission.graph import SmootherResult

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MIN_INFO = 1e-12
"""Eigenvalues of the prior's information below this times the largest are dropped."""


@dataclass(frozen=True, eq=False)
class MarginalPrior:
    """A dense prior factor ``r = R (x_k - xbar) + e`` (module doc).

    Variables ``x_k`` in order: per agent of ``agents`` its first pose (x, y, m) and that
    pose's segment's scale and rotation (rad); per node of ``nodes`` its position (m); the
    height (m). ``r`` (M, D), ``e`` (M,), ``xbar`` (D,).
    """

    agents: tuple[str, ...]
    nodes: tuple[str, ...]
    r: FloatArray
    e: FloatArray
    xbar: FloatArray


@dataclass(frozen=True, eq=False)
class Layout:
    """Columns of one solve.

    Per agent (``names``) its pose times, first pose column, first segment column, number of
    segments, segment of each increment and distance walked before each increment (m, from
    its walk's start); the nodes' first column; the height column.
    """

    names: list[str]
    t: list[FloatArray]
    pose_col: list[int]
    s_col: list[int]
    n_seg: list[int]
    seg: list[IntArray]
    walked_m: list[FloatArray]
    node_ids: list[str]
    node_col: int
    height_col: int
    n: int


def prior_columns(prior: MarginalPrior, lay: Layout) -> IntArray:
    """Columns of the prior's variables in a solve (-1: an agent not in it)."""
    cols: list[int] = []
    for name in prior.agents:
        if name in lay.names:
            a = lay.names.index(name)
            p, s = lay.pose_col[a], lay.s_col[a]
            cols += [p, p + 1, s, s + lay.n_seg[a]]
        else:
            cols += [-1] * 4
    for n in prior.nodes:
        i = lay.node_ids.index(n)
        cols += [lay.node_col + 2 * i, lay.node_col + 2 * i + 1]
    return np.asarray([*cols, lay.height_col], np.int64)


def restrict(prior: MarginalPrior, keep: NDArray[np.bool_]) -> MarginalPrior:
    """The prior with the variables not in ``keep`` marginalized (their agents dropped)."""
    h = prior.r.T @ prior.r
    g = prior.r.T @ prior.e
    p, b = schur(csc_matrix(h), g, np.flatnonzero(keep), np.flatnonzero(~keep))
    agents = tuple(a for i, a in enumerate(prior.agents) if bool(np.all(keep[4 * i:4 * i + 4])))
    return factor(p, b, prior.xbar[keep], agents, prior.nodes)


def schur(h: csc_matrix, g: FloatArray, keep: IntArray, drop: IntArray
          ) -> tuple[FloatArray, FloatArray]:
    """``H_kk - H_kd H_dd^-1 H_dk`` and ``g_k - H_kd H_dd^-1 g_d`` (dense, in ``keep`` order)."""
    h = csc_matrix(h)
    hkk = h[keep][:, keep].toarray()
    if drop.size == 0:
        return 0.5 * (hkk + hkk.T), np.asarray(g[keep], np.float64)
    hdd = csc_matrix(h[drop][:, drop])
    hdk = h[drop][:, keep].toarray()
    lu = spd_lu(csc_matrix(hdd + 1e-12 * identity(drop.size, format="csc")))
    sol = lu.solve(np.column_stack([hdk, g[drop]]))
    p = hkk - hdk.T @ sol[:, :-1]
    return 0.5 * (p + p.T), np.asarray(g[keep] - hdk.T @ sol[:, -1], np.float64)


def factor(p: FloatArray, b: FloatArray, xbar: FloatArray, agents: tuple[str, ...],
           nodes: tuple[str, ...]) -> MarginalPrior:
    """The prior factor of information ``p`` and half-gradient ``b`` at ``xbar`` (module doc)."""
    lam, v = np.linalg.eigh(0.5 * (p + p.T))
    ok = lam > MIN_INFO * max(float(lam[-1]) if lam.size else 0.0, 0.0)
    ok &= lam > 0.0
    lam, v = lam[ok], v[:, ok]
    r = np.sqrt(lam)[:, None] * v.T
    e = (v.T @ b) / np.sqrt(lam)
    return MarginalPrior(agents, nodes, np.asarray(r, np.float64), np.asarray(e, np.float64),
                         np.asarray(xbar, np.float64).copy())


def cut_index(lay: Layout, a: int, t_cut_s: float, last_row_s: float) -> int:
    """Agent ``a``'s first kept pose: the first at or after ``t_cut_s`` (module doc)."""
    t = lay.t[a]
    c = int(np.searchsorted(t, t_cut_s, side="left"))
    c = min(c, len(t) - 2, int(np.searchsorted(t, last_row_s, side="right")) - 1)
    return max(c, 0)


def carried(lay_old: Layout, lay_new: Layout, cut: dict[str, int]) -> IntArray:
    """For each column of the solve after the cut, its column in the solve before (-1: none).

    Agent ``a``'s pose ``k`` was pose ``c + k``; its segment ``i`` was segment ``j_c + i``.
    """
    out = np.full(lay_new.n, -1, np.int64)
    for a, name in enumerate(lay_new.names):
        o = lay_old.names.index(name)
        c = cut.get(name, 0)
        j = int(lay_old.seg[o][c]) if c else 0
        k = min(len(lay_new.t[a]), len(lay_old.t[o]) - c)
        out[lay_new.pose_col[a]:lay_new.pose_col[a] + 2 * k] = \
            lay_old.pose_col[o] + 2 * c + np.arange(2 * k)
        m = min(lay_new.n_seg[a], lay_old.n_seg[o] - j)
        for half in (0, 1):
            new0 = lay_new.s_col[a] + half * lay_new.n_seg[a]
            old0 = lay_old.s_col[o] + half * lay_old.n_seg[o] + j
            out[new0:new0 + m] = old0 + np.arange(m)
    for i, n in enumerate(lay_new.node_ids):
        o = lay_old.node_ids.index(n)
        out[lay_new.node_col + 2 * i:lay_new.node_col + 2 * i + 2] = lay_old.node_col + 2 * o + \
            np.arange(2)
    out[lay_new.height_col] = lay_old.height_col
    return out


def marginalized(lay_old: Layout, h_old: csc_matrix, g_old: FloatArray, x_old: FloatArray,
                 lay_new: Layout, h_new: csc_matrix, g_new: FloatArray, cut: dict[str, int],
                 agents: tuple[str, ...]) -> MarginalPrior:
    """The prior after the cut (module doc): the removed rows' Gaussian on the kept variables.

    ``h_old``, ``g_old``: the solve's information and half-gradient at its solution
    ``x_old``; ``h_new``, ``g_new``: those of the kept rows (the solve after the cut, at the
    same point); ``agents``: the agents of the new prior.
    """
    old_of = carried(lay_old, lay_new, cut)
    ok = old_of >= 0
    emb = csc_matrix((np.ones(int(ok.sum())), (old_of[ok], np.flatnonzero(ok))),
                     shape=(lay_old.n, lay_new.n))
    h = csc_matrix(h_old - emb @ csc_matrix(h_new) @ emb.T)
    g = g_old - emb @ g_new
    placeholder = MarginalPrior(agents, tuple(lay_old.node_ids), np.zeros((0, 0)), np.zeros(0),
                                np.zeros(0))
    keep = old_of[prior_columns(placeholder, lay_new)]
    drop: list[int] = []
    for name, c in cut.items():
        a = lay_old.names.index(name)
        j = int(lay_old.seg[a][c])
        s0 = lay_old.s_col[a]
        drop += list(range(lay_old.pose_col[a], lay_old.pose_col[a] + 2 * c))
        drop += list(range(s0, s0 + j)) + list(range(s0 + lay_old.n_seg[a],
                                                     s0 + lay_old.n_seg[a] + j))
    p, b = schur(h, g, keep, np.asarray(sorted(drop), np.int64))
    return factor(p, b, x_old[keep], agents, tuple(lay_old.node_ids))


def solution_vector(lay: Layout, res: SmootherResult) -> FloatArray:
    """A solve's unknowns (columns of ``lay``) from its result."""
    x = np.zeros(lay.n)
    for a, name in enumerate(lay.names):
        p, s, n_seg = lay.pose_col[a], lay.s_col[a], lay.n_seg[a]
        x[p:p + 2 * len(lay.t[a])] = res.paths[name][1].reshape(-1)
        x[s:s + n_seg] = res.scale[name]
        x[s + n_seg:s + 2 * n_seg] = res.heading_rad[name]
    for i, n in enumerate(lay.node_ids):
        x[lay.node_col + 2 * i:lay.node_col + 2 * i + 2] = res.nodes[n][0]
    x[lay.height_col] = res.height_m
    return x


def trimmed(res: SmootherResult, lay: Layout, cut: dict[str, int]) -> SmootherResult:
    """The result without the poses and segments before the cut (warm start after it)."""
    from hrtls.mission.graph import SmootherResult

    paths, corr = dict(res.paths), dict(res.corrections)
    scale, heading = dict(res.scale), dict(res.heading_rad)
    for name, c in cut.items():
        j = int(lay.seg[lay.names.index(name)][c])
        paths[name] = (paths[name][0][c:], paths[name][1][c:])
        corr[name] = (corr[name][0][c:], corr[name][1][c:])
        scale[name], heading[name] = scale[name][j:], heading[name][j:]
    return SmootherResult(res.nodes, paths, corr, scale, heading, res.height_m, res.rms,
                          res.evaluations, res.last_pose)


def prior_state(p: MarginalPrior | None) -> dict[str, Any] | None:
    """Plain values of a prior (snapshot)."""
    if p is None:
        return None
    return {"agents": list(p.agents), "nodes": list(p.nodes), "r": p.r, "e": p.e,
            "xbar": p.xbar}


def prior_from(d: dict[str, Any] | None) -> MarginalPrior | None:
    """A prior from :func:`prior_state` values."""
    if d is None:
        return None
    return MarginalPrior(tuple(str(a) for a in d["agents"]), tuple(str(n) for n in d["nodes"]),
                         np.asarray(d["r"], np.float64).reshape(-1, len(d["xbar"])),
                         np.asarray(d["e"], np.float64), np.asarray(d["xbar"], np.float64))
