"""Localization of a dropped node from moving agents' ranges (Inderst thesis Sec. 3.2, 5.3).

Agents with an estimated position act as temporary nodes (loose cooperation): every range an agent
measures to an unlocalized node, taken at the agent's estimated position ``a_k``, is a
trilateration constraint. Unlike a fixed anchor, the agent's estimate is wrong by an error that is
strongly correlated over one pass (dead-reckoning drift changes slowly): treating the ranges of a
pass as independent would count the same agent error many times and make the node's covariance
far too small. Each pass ``g`` of an agent therefore carries its own position offset ``b_g``
(the agent's error during that pass). The passes of one agent (one ``chain``) are not independent
either: its error at a later pass is the error at the earlier one plus the drift in between. The
offsets of a chain are a random walk, ``b_g = sum_{j <= g} w_j`` over the chain's passes in time
order, with independent increments ``w_j ~ N(0, D_j)``, ``D_1 = P_1``, ``D_j = [P_j - S_{j-1}]+``
(``P_j`` the agent's own covariance during pass ``j``, ``S_{j-1} = D_1 + ... + D_{j-1}``, ``[.]+``
the positive semi-definite part), so every pass's offset has a prior covariance ``S_j >= P_j``.
The node position ``p`` is estimated jointly with the increments by weighted Gauss-Newton (the
least-squares refinement of Sec. 3.5, step 3, with the agent's uncertainty):

    minimize  sum_k ((r_k - ||p - a_k + b_g(k)||) / s_k)^2 + sum_j w_j^T D_j^-1 w_j

The node's covariance is the ``p`` block of the inverse normal matrix, i.e. the range information
with every pass's offset marginalized out (the sandwich form of the correlated errors). Passes of
different chains (agents) are taken as independent.

The range term of reading ``k`` has two more parts when the readings carry their times. The
offset is the agent's error at the pass's middle reading; its error at ``k`` differs by the drift
in between, of variance ``q_k`` from the growth of the agent's own covariance
(:func:`drift_variance`), so ``s_k^2 = sigma_k^2 + q_k``. The range errors of one pass (the same
walls between agent and node, the antennas' height difference) are correlated in time, a
first-order autoregressive sequence of correlation time ``range_correlation_s``: each reading's
variance is multiplied by :func:`pass_inflation`, so that a pass of many readings carries the
information of its effectively independent ones, not of its count.
With ``MissionParams.smooth_readings_s`` the readings carry an agent's smoothed position and
covariance: what that changes for the offsets and the drift term is in :mod:`hrtls.mission.bridge`.

Checks before a node counts as localized:

* enough ranges and passes, and agent positions that are not collinear;
* NLOS gate: the reading with the largest normalized residual is dropped while it fails the
  chi-square gate (walls lengthen ranges), at most ``max_outlier_passes`` times;
* leave-one-pass-out consistency: a pass whose removal moves the estimate by more than the
  chi-square gate on the covariance of that difference (``C_without - C_with``) is dropped;
* mirror ambiguity: when the reflection of the estimate across the agents' best-fit line converges
  to a second solution that explains the ranges about as well, the node is left unlocalized;
* fit: the kept readings' residuals at the solution, each whitened by its prior spread (range
  noise plus its pass's agent error, ``s_k^2 + u_k^T S_g u_k``), must be explainable by the
  agents' errors: their mean square ``z`` passes the chi-square gate ``J z <= chi2_J(p)``, ``J``
  the kept passes (the readings of one pass share one agent error, so a pass counts as about one
  independent sample, not as its ``n`` readings). A solution far from where the ranges put the
  node (Gauss-Newton converged to another basin from a stale start, or the NLOS and pass checks
  dropped the passes that disagreed with a wrong solution) fails here; the caller may solve
  again from the linear initial position;
* the position sigma must be below ``max_sigma_m``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from hrtls.errors import InputError
from hrtls.kernels import njit

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, kw_only=True)
class NodeEstimatorParams:
    """Parameters of :class:`NodeEstimator`.

    Attributes
    ----------
    min_ranges:
        Fewest accepted readings of a localized node.
    min_spread_m:
        RMS distance of the agents' positions from their best-fit line, at least, m.
    max_sigma_m:
        Largest accepted 1-sigma of the node position along its worst axis, m.
    outlier_gate_probability:
        Chi-square (1 dof) gate of one normalized range residual (NLOS gate).
    consistency_gate_probability:
        Chi-square (2 dof) gate of the leave-one-pass-out shift.
    fit_gate_probability:
        Chi-square (``J`` dof, ``J`` the kept passes) gate of the kept readings' fit (module doc).
    ambiguity_margin:
        A mirror solution whose cost is within this of the best one makes the node ambiguous.
    max_mirror_passes:
        A node with at most this many kept passes is also checked for a mirror solution across
        each straight pass (spread below ``min_spread_m``), not only across all agents' line.
    max_outlier_passes:
        Readings dropped by the NLOS gate at most.
    max_consistency_passes:
        Passes dropped by the leave-one-pass-out check at most.
    max_iterations:
        Gauss-Newton iterations per solve.
    agent_cov_scale:
        The agents' reported covariances are multiplied by this (their filters' own NEES at the
        readings, measured on development seeds, is above its 2 dof expectation).
    agent_correlation:
        Part ``rho`` of the agents' errors common to all agents (same floor, same entrance,
        same magnetic disturbances): one offset ``c ~ N(0, rho * P_min)`` shared by every pass,
        ``P_min`` the smallest (trace) scaled pass covariance; each chain's walk models the rest.
    range_correlation_s:
        Correlation time ``tau`` of the range errors within a pass (the same walls between agent
        and node, the antenna heights), s: the errors of one pass are taken as a first-order
        autoregressive sequence; 0: independent (module doc, :func:`pass_inflation`).
    """

    min_ranges: int = 4
    min_spread_m: float = 0.5
    max_sigma_m: float = 5.0
    outlier_gate_probability: float = 0.999
    consistency_gate_probability: float = 0.999
    fit_gate_probability: float = 0.999
    ambiguity_margin: float = 9.0
    max_mirror_passes: int = 64
    max_outlier_passes: int = 10
    max_consistency_passes: int = 2
    max_iterations: int = 30
    agent_cov_scale: float = 2.0
    agent_correlation: float = 0.5
    range_correlation_s: float = 20.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.agent_correlation < 1.0:
            raise InputError(f"agent_correlation = {self.agent_correlation}",
                             where="NodeEstimatorParams", expected="in [0, 1)")
        for name in ("outlier_gate_probability", "consistency_gate_probability",
                     "fit_gate_probability"):
            v = getattr(self, name)
            if not 0.0 < v < 1.0:
                raise InputError(f"{name} = {v}", where="NodeEstimatorParams",
                                 expected="a probability in (0, 1)")
        if self.min_ranges < 3:
            raise InputError(f"min_ranges = {self.min_ranges}", where="NodeEstimatorParams",
                             expected=">= 3 (a planar position needs three ranges)")
        if not self.range_correlation_s >= 0.0:
            raise InputError(f"range_correlation_s = {self.range_correlation_s}",
                             where="NodeEstimatorParams", expected=">= 0")
        for name in ("min_spread_m", "max_sigma_m", "ambiguity_margin", "agent_cov_scale"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} = {getattr(self, name)}",
                                 where="NodeEstimatorParams", expected="> 0")


@dataclass(frozen=True, eq=False)
class NodeRanges:
    """Ranges from agents to one node.

    Attributes
    ----------
    agent_xy_m:
        ``(k, 2)`` agent's estimated position at each reading, m.
    agent_cov_m2:
        ``(k, 2, 2)`` covariance of that estimate, m^2.
    range_m:
        ``(k,)`` measured distance, m.
    range_sigma_m:
        ``(k,)`` 1-sigma of the distance (LOS), m.
    group:
        ``(k,)`` pass of each reading: readings of one group share one agent error.
    chain:
        ``(k,)`` agent of each reading: the passes of one chain, in increasing ``group`` order,
        are its passes in time order and their offsets a random walk (module doc).
    t_s:
        ``(k,)`` time of each reading, s (None: unknown, the readings' range errors are taken
        as independent).
    """

    agent_xy_m: FloatArray
    agent_cov_m2: FloatArray
    range_m: FloatArray
    range_sigma_m: FloatArray
    group: IntArray
    chain: IntArray
    t_s: FloatArray | None = None

    def __post_init__(self) -> None:
        k = self.range_m.shape[0] if self.range_m.ndim == 1 else -1
        shapes = {"agent_xy_m": (k, 2), "agent_cov_m2": (k, 2, 2), "range_m": (k,),
                  "range_sigma_m": (k,), "group": (k,), "chain": (k,)}
        if self.t_s is not None:
            shapes["t_s"] = (k,)
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise InputError(f"{name} has shape {getattr(self, name).shape}",
                                 where="NodeRanges", expected=f"shape {shape}")
        for name in ("agent_xy_m", "agent_cov_m2", "range_m", "range_sigma_m"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise InputError(f"non-finite {name}", where="NodeRanges", expected="finite")
        if np.any(self.range_m < 0) or np.any(self.range_sigma_m <= 0):
            raise InputError("negative range or non-positive sigma", where="NodeRanges",
                             expected="range_m >= 0, range_sigma_m > 0")

    @classmethod
    def build(cls, *, agent_xy_m: object, agent_cov_m2: object, range_m: object,
              range_sigma_m: object, group: object, chain: object | None = None,
              t_s: object | None = None) -> NodeRanges:
        """Arrays converted to float64 / int64; no ``chain``: every pass its own agent."""
        return cls(np.asarray(agent_xy_m, np.float64).reshape(-1, 2),
                   np.asarray(agent_cov_m2, np.float64).reshape(-1, 2, 2),
                   np.asarray(range_m, np.float64).reshape(-1),
                   np.asarray(range_sigma_m, np.float64).reshape(-1),
                   np.asarray(group, np.int64).reshape(-1),
                   np.asarray(group if chain is None else chain, np.int64).reshape(-1),
                   None if t_s is None else np.asarray(t_s, np.float64).reshape(-1))

    def __len__(self) -> int:
        return int(self.range_m.shape[0])


@dataclass(frozen=True, eq=False)
class NodeEstimate:
    """Result of :meth:`NodeEstimator.estimate`.

    Attributes
    ----------
    position_m:
        ``(2,)`` estimated position (NaN when no solution was computed).
    covariance_m2:
        ``(2, 2)`` its covariance with every pass's agent error marginalized (NaN likewise).
    localized:
        All checks passed.
    reason:
        Why not localized (empty when localized).
    used:
        ``(k,)`` readings kept by the NLOS and consistency checks.
    normalized_rms:
        RMS of the whitened residuals of the kept readings (about 1 when the model fits).
    iterations:
        Gauss-Newton iterations of the last solve.
    """

    position_m: FloatArray
    covariance_m2: FloatArray
    localized: bool
    reason: str
    used: BoolArray
    normalized_rms: float
    iterations: int


@dataclass(frozen=True, eq=False)
class _Solve:
    p: FloatArray
    cov: FloatArray
    cost: float
    whitened: FloatArray
    iterations: int
    ok: bool


@dataclass(frozen=True, eq=False)
class _Offsets:
    """The pass offsets of the kept readings: ``b = anc @ w`` (per axis), ``w_j ~ N(0, D_j)``."""

    g: IntArray          # (k,) pass index 0..J-1 of each kept reading
    anc: FloatArray      # (J, M) 1 where increment m is part of pass g's offset (M = J or J + 1)
    d_inv: FloatArray    # (M, 2, 2) inverse increment priors (the last: common offset, if any)
    s: FloatArray        # (J, 2, 2) prior covariance of each pass's offset


@njit(cache=True)
def psd_part_kernel(m: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """The positive semi-definite part of the symmetric part of a square matrix."""
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * np.maximum(w, 0.0)) @ v.T


def pass_inflation(*, n: int, span_s: float, tau_s: float) -> float:
    """Variance factor of each of a pass's ``n`` readings for autocorrelated range errors.

    Errors ``e_i`` of ``n`` readings equally spaced over ``span_s``, stationary first-order
    autoregressive with correlation ``rho = exp(-dt / tau_s)`` between neighbours
    (``dt = span_s / (n - 1)``): their generalized-least-squares mean has variance
    ``sigma^2 (1 + rho) / (n (1 - rho) + 2 rho)``, that of ``n_eff = (n (1 - rho) + 2 rho) /
    (1 + rho)`` independent readings. Returns ``n / n_eff`` (>= 1; 1 for ``n = 1`` or
    ``tau_s = 0``; ``n`` when the readings coincide in time), so that ``n`` readings taken as
    independent with their variance times the factor carry the pass's information.
    """
    if n <= 1 or tau_s <= 0.0:
        return 1.0
    rho = float(np.exp(-max(span_s, 0.0) / (n - 1) / tau_s))
    return n * (1.0 + rho) / (n * (1.0 - rho) + 2.0 * rho)


def drift_variance(cov_m2: FloatArray, t_s: FloatArray) -> FloatArray:
    """Variance of a pass's agent errors about the error at its middle reading, per reading.

    An agent's error drifts during a pass: at reading ``k`` it is the error at the middle
    reading ``m`` plus the drift accumulated in between, whose covariance is the growth of the
    agent's own covariance over that interval, ``Q_k = [sign(t_k - t_m) (P_k - P_m)]+`` (the
    positive semi-definite part; 0 where a correction shrank it). Returns ``tr(Q_k) / 2``, the
    variance along a direction averaged over directions, m^2 (``cov_m2`` ``(n, 2, 2)``).
    """
    n = t_s.shape[0]
    if n < 2:
        return np.zeros(n)
    mid = int(np.argsort(t_s, kind="stable")[n // 2])
    d = np.sign(t_s - t_s[mid])[:, None, None] * (cov_m2 - cov_m2[mid])
    w = np.linalg.eigvalsh(0.5 * (d + np.swapaxes(d, 1, 2)))
    return np.asarray(0.5 * np.sum(np.maximum(w, 0.0), axis=1), dtype=np.float64)


def _drift(obs: NodeRanges, use: BoolArray) -> FloatArray:
    """:func:`drift_variance` of each kept reading in its pass (zeros without times)."""
    k = int(np.count_nonzero(use))
    if obs.t_s is None:
        return np.zeros(k)
    out = np.zeros(k)
    grp, t, cov = obs.group[use], obs.t_s[use], obs.agent_cov_m2[use]
    for g in np.unique(grp).tolist():
        m = grp == g
        out[m] = drift_variance(cov[m], t[m])
    return out


def _inflation(obs: NodeRanges, use: BoolArray, tau_s: float) -> FloatArray:
    """:func:`pass_inflation` of each kept reading's pass (ones without times)."""
    k = int(np.count_nonzero(use))
    if obs.t_s is None or tau_s <= 0.0:
        return np.ones(k)
    groups, inv = np.unique(obs.group[use], return_inverse=True)
    t = obs.t_s[use]
    lo = np.full(groups.size, np.inf)
    hi = np.full(groups.size, -np.inf)
    np.minimum.at(lo, inv, t)
    np.maximum.at(hi, inv, t)
    n = np.bincount(inv, minlength=groups.size)
    f = np.array([pass_inflation(n=int(n[j]), span_s=float(hi[j] - lo[j]), tau_s=tau_s)
                  for j in range(groups.size)])
    return np.asarray(f[inv], dtype=np.float64)


def _offsets(obs: NodeRanges, use: BoolArray, prm: NodeEstimatorParams) -> _Offsets:
    """Random-walk offset model of the kept readings' passes (module doc)."""
    groups, inv = np.unique(obs.group[use], return_inverse=True)
    n_g = groups.size
    pg = np.zeros((n_g, 2, 2))
    np.add.at(pg, inv, obs.agent_cov_m2[use])
    pg *= prm.agent_cov_scale / np.bincount(inv, minlength=n_g)[:, None, None]
    common = np.zeros((2, 2))
    if prm.agent_correlation > 0.0:
        common = prm.agent_correlation * pg[int(np.argmin(np.trace(pg, axis1=1, axis2=2)))]
    chain = np.zeros(n_g, dtype=np.int64)
    chain[inv] = obs.chain[use]
    anc = np.zeros((n_g, n_g + (prm.agent_correlation > 0.0)))
    inc = np.zeros((anc.shape[1], 2, 2))
    cum = np.zeros((n_g, 2, 2))
    for c in np.unique(chain).tolist():
        members = np.flatnonzero(chain == c)            # groups sorted: time order in chain
        total = common.copy()
        for pos, j in enumerate(members.tolist()):
            inc[j] = psd_part_kernel(pg[j] - total) + 1e-9 * np.eye(2)
            total = total + inc[j]
            cum[j] = total
            anc[j, members[:pos + 1]] = 1.0
    if anc.shape[1] > n_g:
        anc[:, n_g] = 1.0
        inc[n_g] = common + 1e-9 * np.eye(2)
    return _Offsets(inv.astype(np.int64), anc, np.asarray(np.linalg.inv(inc), np.float64), cum)


def _solve(obs: NodeRanges, use: BoolArray, p0: FloatArray, prm: NodeEstimatorParams) -> _Solve:
    """Joint Gauss-Newton over the node and the offset increments (Levenberg damping)."""
    a = obs.agent_xy_m[use]
    r = obs.range_m[use]
    s0 = np.sqrt(obs.range_sigma_m[use] ** 2 + _drift(obs, use))   # range noise + drift
    s = s0 * np.sqrt(_inflation(obs, use, prm.range_correlation_s))   # weights of the solve
    off = _offsets(obs, use, prm)
    max_iterations = prm.max_iterations
    g, pinv, anc_k = off.g, off.d_inv, off.anc[off.g]
    n_g = pinv.shape[0]
    n = 2 + 2 * n_g
    k = a.shape[0]
    theta = np.zeros(n)
    theta[:2] = p0

    def parts(th: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        w = th[2:].reshape(n_g, 2)
        diff = th[:2] - a + anc_k @ w
        h = np.maximum(np.linalg.norm(diff, axis=1), 1e-9)
        u = diff / h[:, None]
        res = (r - h) / s
        cost = float(res @ res + np.einsum("gi,gij,gj->", w, pinv, w))
        return res, u, cost

    def normal(th: FloatArray, res: FloatArray, u: FloatArray) -> tuple[FloatArray, FloatArray]:
        jw = u / s[:, None]                      # d h / d p = d h / d w_j (j in the pass) = u
        jac = np.concatenate([jw, (anc_k[:, :, None] * jw[:, None, :]).reshape(k, 2 * n_g)],
                             axis=1)
        hess = jac.T @ jac
        grad = -(jac.T @ res)                    # gradient of 0.5 * cost w.r.t. theta
        w = th[2:].reshape(n_g, 2)
        for j in range(n_g):
            sl = slice(2 + 2 * j, 4 + 2 * j)
            hess[sl, sl] += pinv[j]
            grad[sl] += pinv[j] @ w[j]
        return hess, grad

    res, u, cost = parts(theta)
    lam = 1e-6
    it = 0
    for it in range(1, max_iterations + 1):  # noqa: B007
        hess, grad = normal(theta, res, u)
        damped = hess + lam * np.diag(np.maximum(np.diag(hess), 1e-12))
        try:
            step = np.linalg.solve(damped, -grad)
        except np.linalg.LinAlgError:
            break
        cand = theta + step
        res_c, u_c, cost_c = parts(cand)
        if cost_c <= cost:
            theta, res, u, cost = cand, res_c, u_c, cost_c
            lam = max(lam / 10.0, 1e-12)
            if np.max(np.abs(step)) < 1e-6:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    hess, _ = normal(theta, res, u)
    try:
        cov_full = np.linalg.inv(hess)
        ok = bool(np.all(np.isfinite(cov_full)))
    except np.linalg.LinAlgError:
        cov_full = np.full((n, n), np.nan)
        ok = False
    cov = cov_full[:2, :2]
    cov = 0.5 * (cov + cov.T)
    # per-reading residual whitened by its prior spread (range noise + the pass's agent error)
    pg = off.s[g]
    var = s0 ** 2 + np.einsum("ki,kij,kj->k", u, pg, u)
    whitened = (r - (np.linalg.norm(theta[:2] - a, axis=1))) / np.sqrt(var)
    return _Solve(p=theta[:2].copy(), cov=cov, cost=cost, whitened=whitened, iterations=it, ok=ok)


def _initial(a: FloatArray, r: FloatArray) -> FloatArray | None:
    """Linear least squares of ``||p - a_k||^2 = r_k^2`` relative to the centroid."""
    c = a.mean(axis=0)
    d = a - c
    lhs = 2.0 * d
    rhs = np.sum(d ** 2, axis=1) - r ** 2
    rhs = rhs - rhs.mean()
    lhs = lhs - lhs.mean(axis=0)
    sol, _, rank, _ = np.linalg.lstsq(lhs, rhs, rcond=None)
    if rank < 2:
        return None
    return np.asarray(c + sol, dtype=np.float64)


def _spread(a: FloatArray) -> tuple[float, FloatArray, FloatArray]:
    """RMS distance from the best-fit line, the line's centre and unit normal."""
    c = a.mean(axis=0)
    w, v = np.linalg.eigh(np.cov((a - c).T, bias=True).reshape(2, 2))
    return float(np.sqrt(max(w[0], 0.0))), c, v[:, 0]


class NodeEstimator:
    """Weighted Gauss-Newton localization of one node from agents' ranges (see module doc)."""

    def __init__(self, params: NodeEstimatorParams | None = None) -> None:
        self.params = params or NodeEstimatorParams()
        self._gate1 = float(chi2.ppf(self.params.outlier_gate_probability, 1))
        self._gate2 = float(chi2.ppf(self.params.consistency_gate_probability, 2))
        self._fit_gates: dict[int, float] = {}

    def estimate(self, obs: NodeRanges, *, initial_m: FloatArray | None = None) -> NodeEstimate:
        """Localize one node; ``initial_m`` (e.g. the previous estimate) seeds Gauss-Newton."""
        prm = self.params
        k = len(obs)
        use = np.ones(k, dtype=bool)
        nan2 = np.full(2, np.nan)
        nan22 = np.full((2, 2), np.nan)

        def fail(reason: str, sol: _Solve | None = None) -> NodeEstimate:
            if sol is None:
                return NodeEstimate(nan2, nan22, False, reason, use, float("nan"), 0)
            return NodeEstimate(sol.p, sol.cov, False, reason, use.copy(),
                                _rms(sol.whitened), sol.iterations)

        if k < prm.min_ranges:
            return fail(f"{k} ranges (needs {prm.min_ranges})")
        if _spread(obs.agent_xy_m)[0] < prm.min_spread_m:
            return fail("agents' positions are collinear")
        p0 = initial_m if initial_m is not None else _initial(obs.agent_xy_m, obs.range_m)
        if p0 is None or not np.all(np.isfinite(p0)):
            return fail("no initial position")
        sol = _solve(obs, use, np.asarray(p0, np.float64), prm)
        for _ in range(prm.max_outlier_passes):          # NLOS gate, worst reading first
            idx = np.flatnonzero(use)
            worst = int(np.argmax(sol.whitened ** 2))
            if sol.whitened[worst] ** 2 <= self._gate1 or idx.size <= prm.min_ranges:
                break
            use[idx[worst]] = False
            sol = _solve(obs, use, sol.p, prm)
        for _ in range(prm.max_consistency_passes):      # leave one pass out
            bad = self._worst_pass(obs, use, sol)
            if bad is None:
                break
            use[(obs.group == bad) & use] = False
            if np.count_nonzero(use) < prm.min_ranges:
                return fail("ranges of the passes disagree")
            sol = _solve(obs, use, sol.p, prm)
        if not sol.ok:
            return fail("singular geometry", sol)
        if np.count_nonzero(use) < prm.min_ranges:
            return fail("too few ranges left after the NLOS gate", sol)
        if _spread(obs.agent_xy_m[use])[0] < prm.min_spread_m:
            return fail("agents' positions are collinear", sol)
        ambiguous = self._mirror(obs, use, sol)
        if ambiguous:
            return fail(ambiguous, sol)
        n_pass = int(np.unique(obs.group[use]).size)
        fit, fit_gate = float(np.mean(sol.whitened ** 2)), self._fit_gate(n_pass)
        if fit > fit_gate:
            return fail(f"ranges inconsistent with the solution (mean whitened residual^2 "
                        f"{fit:.1f} above {fit_gate:.1f})", sol)
        sigma_max = float(np.sqrt(max(np.linalg.eigvalsh(sol.cov)[-1], 0.0)))
        if sigma_max > prm.max_sigma_m:
            return fail(f"sigma {sigma_max:.1f} m above {prm.max_sigma_m:g} m", sol)
        return NodeEstimate(sol.p, sol.cov, True, "", use.copy(), _rms(sol.whitened),
                            sol.iterations)

    def _mirror(self, obs: NodeRanges, use: BoolArray, sol: _Solve) -> str:
        """Why the solution is ambiguous (empty when it is not).

        Ambiguous: a reflection of it across the best-fit line of all kept agent positions, or
        of one straight pass (at most ``max_mirror_passes`` kept), converges to a distant second
        solution that explains the ranges about as well.
        """
        lines = [("the agents' path", use)]
        groups = np.unique(obs.group[use])
        for grp in groups.tolist() if groups.size <= self.params.max_mirror_passes else []:
            m = use & (obs.group == grp)
            straight = _spread(obs.agent_xy_m[m])[0] < self.params.min_spread_m
            if np.count_nonzero(m) >= 3 and straight:
                lines.append((f"pass {grp}", m))
        tried = [sol.p]
        far = 3.0 * np.sqrt(np.trace(sol.cov))
        for name, m in lines:
            _, centre, normal = _spread(obs.agent_xy_m[m])
            mirror = sol.p - 2.0 * float((sol.p - centre) @ normal) * normal
            if min(float(np.linalg.norm(mirror - t)) for t in tried) < max(far, 1e-3):
                continue
            tried.append(mirror)
            alt = _solve(obs, use, mirror, self.params)
            if (np.linalg.norm(alt.p - sol.p) > far
                    and alt.cost - sol.cost < self.params.ambiguity_margin):
                return f"mirror ambiguity across {name}"
        return ""

    def _fit_gate(self, n_pass: int) -> float:
        """Largest mean square whitened residual of ``n_pass`` passes: ``chi2_J(p) / J``."""
        gate = self._fit_gates.get(n_pass)
        if gate is None:
            gate = float(chi2.ppf(self.params.fit_gate_probability, n_pass)) / n_pass
            self._fit_gates[n_pass] = gate
        return gate

    def _worst_pass(self, obs: NodeRanges, use: BoolArray, sol: _Solve) -> int | None:
        """The pass whose removal shifts the node beyond the gate, the largest such shift."""
        groups = np.unique(obs.group[use])
        if groups.size < 3:
            return None
        worst, worst_d2 = None, self._gate2
        for grp in groups.tolist():
            keep = use & (obs.group != grp)
            if np.count_nonzero(keep) < self.params.min_ranges:
                continue
            if _spread(obs.agent_xy_m[keep])[0] < self.params.min_spread_m:
                continue
            other = _solve(obs, keep, sol.p, self.params)
            if not other.ok:
                continue
            diff = other.p - sol.p
            dcov = other.cov - sol.cov
            w, v = np.linalg.eigh(dcov)
            w = np.maximum(w, 1e-6 * max(float(w[-1]), 1e-12))
            d2 = float(np.sum((v.T @ diff) ** 2 / w))
            if d2 > worst_d2:
                worst, worst_d2 = int(grp), d2
        return worst


def _rms(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def largest_variance(cov_m2: FloatArray) -> float:
    """Largest eigenvalue of a covariance, m^2."""
    return float(np.linalg.eigvalsh(cov_m2)[-1])
