"""Refinement of localized positions with noisy ranges (Inderst thesis Sec. 3.5, step 3).

Once TLA / SELA / an agent have given every localizable node an initial position, all positions
are adjusted together by weighted nonlinear least squares over every measured link between
localized nodes (Gauss-Newton with Levenberg damping on a sparse Jacobian):

    minimize  sum_links ((d_ab - ||p_a - p_b||) / sigma_ab)^2 + sum_priors ||p_i - m_i||^2 / s_i^2

Anchors are held fixed; nodes placed by an agent (tight cooperation) can carry a soft prior. With
Gaussian range errors this is the Bayesian (maximum a posteriori) estimate with a static model, and
the inverse of the Gauss-Newton normal matrix gives each node's 2x2 covariance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.linalg import splu

from hrtls.errors import InputError
from hrtls.wsn.network import Network
from hrtls.wsn.trilateration import Localization

FloatArray = NDArray[np.float64]
DENSE_COVARIANCE_MAX_UNKNOWNS = 4000
"""Above this many unknowns the covariance blocks come from batched sparse LU solves."""
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, kw_only=True)
class RefineParams:
    """Parameters of the least-squares refinement.

    Attributes
    ----------
    range_sigma_fraction:
        Range standard deviation as a fraction of the measured distance (0.02 = 2 %).
    range_sigma_floor_m:
        Lower bound of the range standard deviation, m.
    max_iterations:
        Gauss-Newton iterations at most.
    step_tolerance_m:
        Stop when the largest position update is below this, m.
    covariance:
        Compute the per-node 2x2 covariance.
    """

    range_sigma_fraction: float = 0.02
    range_sigma_floor_m: float = 1e-6
    max_iterations: int = 30
    step_tolerance_m: float = 1e-10
    covariance: bool = True

    def __post_init__(self) -> None:
        if not (self.range_sigma_fraction >= 0 and self.range_sigma_floor_m > 0):
            raise InputError("range sigma must be positive", where="RefineParams",
                             expected="range_sigma_fraction >= 0 and range_sigma_floor_m > 0")
        if self.max_iterations < 1:
            raise InputError(f"max_iterations = {self.max_iterations}", where="RefineParams",
                             expected=">= 1")


@dataclass(frozen=True, eq=False)
class Refinement:
    """Refined positions and their uncertainty.

    Attributes
    ----------
    estimate_m:
        ``(n, 2)`` refined positions (initial values where not refined).
    covariance_m2:
        ``(n, 2, 2)`` covariance of every refined node (zeros for fixed or unlocalized nodes).
    refined:
        ``(n,)`` mask of the nodes that were adjusted.
    iterations:
        Gauss-Newton iterations used.
    normalized_rms:
        RMS of the normalized range residuals after refinement (about 1 when the noise model
        fits).
    """

    estimate_m: FloatArray
    covariance_m2: FloatArray
    refined: BoolArray
    iterations: int
    normalized_rms: float


def refine_positions(
    edges: IntArray,
    distance_m: FloatArray,
    initial_m: FloatArray,
    active: BoolArray,
    *,
    prior_m: FloatArray | None = None,
    prior_sigma_m: FloatArray | None = None,
    params: RefineParams | None = None,
) -> Refinement:
    """Array-level refinement.

    Parameters
    ----------
    edges, distance_m:
        Links ``(m, 2)`` and measured distances ``(m,)``.
    initial_m:
        ``(n, 2)`` initial positions (used where ``active``).
    active:
        ``(n,)`` nodes that take part (localized ones).
    prior_m, prior_sigma_m:
        Prior position and its standard deviation per node: ``0`` = fixed (anchor),
        ``inf`` = no prior, positive = soft prior. Default: nothing fixed.
    params:
        :class:`RefineParams`.
    """
    prm = params or RefineParams()
    x = np.array(initial_m, dtype=np.float64, copy=True)
    n = x.shape[0]
    act = np.asarray(active, dtype=bool)
    if not np.all(np.isfinite(x[act])):
        raise InputError("non-finite initial position", where="refine", expected="finite")
    ps = np.full(n, np.inf) if prior_sigma_m is None else np.asarray(prior_sigma_m, float)
    pm = x.copy() if prior_m is None else np.asarray(prior_m, float)
    fixed = act & (ps <= 0)
    free = act & ~fixed
    soft = free & np.isfinite(ps)
    col = np.full(n, -1, dtype=np.int64)
    nf = int(np.count_nonzero(free))
    col[free] = np.arange(nf)
    cov = np.zeros((n, 2, 2))
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    d = np.asarray(distance_m, dtype=np.float64)
    use = act[e[:, 0]] & act[e[:, 1]] & (free[e[:, 0]] | free[e[:, 1]])
    e, d = e[use], d[use]
    if nf == 0 or e.shape[0] == 0:
        return Refinement(estimate_m=x, covariance_m2=cov, refined=free, iterations=0,
                          normalized_rms=0.0)
    if not np.any(fixed) and not np.any(soft):
        raise InputError("no fixed or prior node", where="refine",
                         expected="anchors or agent-placed nodes with a prior (gauge)")
    sig = np.maximum(prm.range_sigma_fraction * d, prm.range_sigma_floor_m)
    problem = _RangeProblem(edges=e, distance_m=d, weight=1.0 / sig, column=col, n_free=nf,
                            soft=np.flatnonzero(soft), prior_m=pm, prior_sigma_m=ps)
    x, h, it = _levenberg_marquardt(problem, x, free, prm)
    _, _, res = problem.normal_equations(x)
    if prm.covariance:
        cov = _covariance_blocks(h, nf, free, n)
    return Refinement(estimate_m=x, covariance_m2=cov, refined=free, iterations=it,
                      normalized_rms=float(np.sqrt(np.mean(res**2))))


@dataclass(frozen=True, eq=False, kw_only=True)
class _RangeProblem:
    """Weighted range residuals of the used links plus the soft priors, over the free nodes.

    ``column[i]`` is the index of free node ``i`` among the unknowns (-1 when not free);
    ``soft`` are the free nodes with a finite prior.
    """

    edges: IntArray
    distance_m: FloatArray
    weight: FloatArray
    column: IntArray
    n_free: int
    soft: IntArray
    prior_m: FloatArray
    prior_sigma_m: FloatArray

    def normal_equations(self, xx: FloatArray) -> tuple[sp.csc_matrix, FloatArray, FloatArray]:
        """Gauss-Newton ``J^T J`` (plus prior weights), gradient ``J^T res`` and residuals."""
        e, d, w, col, nf = self.edges, self.distance_m, self.weight, self.column, self.n_free
        diff = xx[e[:, 0]] - xx[e[:, 1]]
        r = np.linalg.norm(diff, axis=1)
        r = np.maximum(r, 1e-12)
        u = diff / r[:, None]
        res = (d - r) * w
        rows: list[IntArray] = []
        cols: list[IntArray] = []
        vals: list[FloatArray] = []
        for end, sign in ((0, -1.0), (1, 1.0)):
            c = col[e[:, end]]
            ok = c >= 0
            k = np.flatnonzero(ok)
            for ax in (0, 1):
                rows.append(k)
                cols.append(2 * c[ok] + ax)
                vals.append(sign * u[ok, ax] * w[ok])
        jac = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                            shape=(e.shape[0], 2 * nf))
        # J is d(res)/dx with res = (d - r) w: d r/dx_a = u, so d res / dx_a = -u w
        h = (jac.T @ jac).tocsc()
        g = jac.T @ res
        if self.soft.size:
            wp = 1.0 / self.prior_sigma_m[self.soft] ** 2
            diag = np.zeros(2 * nf)
            cc = col[self.soft]
            diag[2 * cc] = wp
            diag[2 * cc + 1] = wp
            h = h + sp.diags(diag, format="csc")
            pr = (xx[self.soft] - self.prior_m[self.soft]) * wp[:, None]
            g[2 * cc] += pr[:, 0]
            g[2 * cc + 1] += pr[:, 1]
        return h, g, res

    def cost(self, xx: FloatArray) -> float:
        """Sum of the squared weighted residuals and prior terms."""
        e = self.edges
        r = np.linalg.norm(xx[e[:, 0]] - xx[e[:, 1]], axis=1)
        c = float(np.sum(((self.distance_m - r) * self.weight) ** 2))
        if self.soft.size:
            c += float(np.sum(np.sum((xx[self.soft] - self.prior_m[self.soft]) ** 2, axis=1)
                              / self.prior_sigma_m[self.soft] ** 2))
        return c


def _levenberg_marquardt(problem: _RangeProblem, x: FloatArray, free: BoolArray,
                         prm: RefineParams) -> tuple[FloatArray, sp.csc_matrix, int]:
    """Damped Gauss-Newton from ``x``: the positions, the last ``J^T J`` and the iterations."""
    lam = 1e-9
    it = 0
    c0 = problem.cost(x)
    h, g, _ = problem.normal_equations(x)
    for it in range(1, prm.max_iterations + 1):  # noqa: B007
        dg = h.diagonal()
        a = (h + sp.diags(lam * np.maximum(dg, 1e-12), format="csc")).tocsc()
        try:
            step = splu(a).solve(-g)
        except RuntimeError:
            lam = lam * 100 + 1e-6
            continue
        xn = x.copy()
        xn[free] += step.reshape(-1, 2)
        cn = problem.cost(xn)
        if cn <= c0:
            x, c0 = xn, cn
            lam = max(lam / 10, 1e-12)
            h, g, _ = problem.normal_equations(x)
            if np.max(np.abs(step)) < prm.step_tolerance_m:
                break
        else:
            lam *= 10
            if lam > 1e8:
                break
    return x, h, it


def _covariance_blocks(h: sp.csc_matrix, nf: int, free: BoolArray, n: int) -> FloatArray:
    """2x2 diagonal blocks of ``h^-1`` (dense below 4000 unknowns, batched sparse solves above)."""
    cov = np.zeros((n, 2, 2))
    idx = np.flatnonzero(free)
    dim = 2 * nf
    # tiny regularization keeps unobservable (flexible) nodes finite instead of singular
    hr = (h + sp.identity(dim, format="csc") * (1e-12 * max(h.diagonal().max(), 1.0))).tocsc()
    if dim <= DENSE_COVARIANCE_MAX_UNKNOWNS:
        inv = np.linalg.inv(hr.toarray())
        blocks = np.stack([inv[0::2, 0::2].diagonal(), inv[0::2, 1::2].diagonal(),
                           inv[1::2, 1::2].diagonal()], axis=1)
    else:
        lu = splu(hr)
        blocks = np.zeros((nf, 3))
        step = 512
        for s in range(0, nf, step):
            k = np.arange(s, min(nf, s + step))
            rhs = np.zeros((dim, 2 * k.size))
            rhs[2 * k, 2 * np.arange(k.size)] = 1.0
            rhs[2 * k + 1, 2 * np.arange(k.size) + 1] = 1.0
            sol = lu.solve(rhs)
            blocks[k, 0] = sol[2 * k, 2 * np.arange(k.size)]
            blocks[k, 1] = sol[2 * k, 2 * np.arange(k.size) + 1]
            blocks[k, 2] = sol[2 * k + 1, 2 * np.arange(k.size) + 1]
    cov[idx, 0, 0] = blocks[:, 0]
    cov[idx, 0, 1] = blocks[:, 1]
    cov[idx, 1, 0] = blocks[:, 1]
    cov[idx, 1, 1] = blocks[:, 2]
    return cov


def refine_network(
    net: Network,
    loc: Localization,
    *,
    params: RefineParams | None = None,
    prior_sigma_m: FloatArray | None = None,
    agent_positions_m: FloatArray | None = None,
    agent_links: Sequence[tuple[int, int, float]] = (),
    agent_sigma_m: float = 0.0,
) -> Refinement:
    """Refine the localized nodes of ``net`` (anchors fixed).

    ``prior_sigma_m`` (per node) adds soft priors at the current estimates, e.g. for nodes an
    agent placed; anchors are always fixed. Ranges measured by an agent at way points enter as
    links to temporary nodes at ``agent_positions_m`` (``agent_links`` holds ``(way-point index,
    node index, range)``) held fixed (``agent_sigma_m = 0``) or with a soft prior; ``loc`` is then
    the localization of the augmented framework (``n + k`` entries) or of the ``n`` nodes.
    Returned arrays cover the ``n`` network nodes only.
    """
    n = net.n_nodes
    ap = np.zeros((0, 2)) if agent_positions_m is None else np.asarray(agent_positions_m, float)
    k = ap.shape[0]
    nt = n + k
    est = np.zeros((nt, 2))
    act = np.zeros(nt, dtype=bool)
    est[:n] = loc.estimate_m[:n]
    act[:n] = loc.localized[:n]
    est[n:] = ap
    act[n:] = True
    ps = np.full(nt, np.inf)
    if prior_sigma_m is not None:
        ps[:n] = np.asarray(prior_sigma_m, float)[:n]
    ps[:n][net.anchor] = 0.0
    ps[n:] = agent_sigma_m
    edges = net.edges
    dist = net.distance_m
    if agent_links:
        arr = np.array(agent_links, dtype=np.float64).reshape(-1, 3)
        a = arr[:, 0].astype(np.int64) + n
        b = arr[:, 1].astype(np.int64)
        edges = np.vstack([edges, np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)])
        dist = np.concatenate([dist, np.maximum(arr[:, 2], 1e-9 * net.radius_m)])
    r = refine_positions(edges, dist, est, act, prior_m=est, prior_sigma_m=ps, params=params)
    return Refinement(estimate_m=r.estimate_m[:n], covariance_m2=r.covariance_m2[:n],
                      refined=r.refined[:n], iterations=r.iterations,
                      normalized_rms=r.normalized_rms)
