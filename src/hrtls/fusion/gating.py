"""Kalman measurement update with a chi-square innovation gate, in Joseph form.

Every correction of the position filter goes through :func:`kalman_update`:

* innovation ``nu = z - h(x)`` and its covariance ``S = H P H^T + R``;
* normalized innovation squared ``NIS = nu^T S^-1 nu``, compared with the ``probability``
  quantile of the chi-square distribution with ``dim(z)`` degrees of freedom; a larger NIS
  rejects the observation (state and covariance unchanged);
* gain ``K = P H^T S^-1`` and the Joseph-form covariance
  ``P+ = (I - K H) P (I - K H)^T + K R K^T``, then symmetrized. For the optimal gain it equals the
  textbook ``(I - K H) P`` (Colombo eq. 22, Tarrio eq. 11, Inderst eq. 4.35) but stays symmetric
  positive definite under rounding.

The result carries an :class:`UpdateDiagnostics` record so a report can count what each source
accepted and rejected.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal

import numba
import numpy as np
from scipy import linalg
from scipy.stats import chi2

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray

Status = Literal["accepted", "rejected", "skipped"]

DEFAULT_GATE_PROBABILITY = 0.999
"""Default gate: an observation is rejected when its NIS exceeds the 99.9 % chi-square quantile."""


@lru_cache(maxsize=64)
def chi2_threshold(dof: int, probability: float = DEFAULT_GATE_PROBABILITY) -> float:
    """Chi-square quantile: NIS values above it are rejected with ``1 - probability`` false alarms.

    Parameters
    ----------
    dof:
        Degrees of freedom (dimension of the measurement), >= 1.
    probability:
        Probability mass below the threshold, in (0, 1).
    """
    if dof < 1:
        raise InputError(f"dof = {dof}", where="chi2_threshold", expected="dof >= 1")
    if not 0.0 < probability < 1.0:
        raise InputError(f"probability = {probability}", where="chi2_threshold",
                         expected="a probability in (0, 1)")
    return float(chi2.ppf(probability, dof))


def symmetrize(p: FloatArray) -> FloatArray:
    """``(P + P^T) / 2``."""
    return np.asarray(0.5 * (p + p.T), dtype=np.float64)


def is_spd(p: FloatArray) -> bool:
    """True when ``p`` is finite, symmetric and positive definite (Cholesky succeeds)."""
    if not np.all(np.isfinite(p)) or not np.allclose(p, p.T, rtol=1e-9, atol=1e-12):
        return False
    try:
        np.linalg.cholesky(p)
    except np.linalg.LinAlgError:
        return False
    return True


def nis(innovation: FloatArray, s: FloatArray) -> float:
    """Normalized innovation squared ``nu^T S^-1 nu`` (S must be positive definite)."""
    c = linalg.cho_factor(s, lower=True)
    return float(innovation @ linalg.cho_solve(c, innovation))


@dataclass(frozen=True, slots=True, eq=False)
class UpdateDiagnostics:
    """What one correction did.

    Attributes
    ----------
    kind: correction kind (``"fix"``, ``"rss"``, ``"range"``, ``"tag"``, ``"bearing"``, ...).
    t: time of the observation, s.
    status: ``"accepted"``, ``"rejected"`` (failed the gate or a sanity check) or ``"skipped"``
        (not due, e.g. a position fix while standing still).
    nis: normalized innovation squared (NaN when no innovation was formed).
    dof: measurement dimension.
    threshold: gate threshold on the NIS (``inf`` when not gated).
    innovation: ``z - h(x)``.
    innovation_cov: ``S``.
    source: landmark / anchor / node id, or ``""``.
    reason: short explanation of a rejection or skip, or of the strategy used.
    """

    kind: str
    t: float
    status: Status
    nis: float = float("nan")
    dof: int = 0
    threshold: float = float("inf")
    innovation: FloatArray = field(default_factory=lambda: np.zeros(0))
    innovation_cov: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    source: str = ""
    reason: str = ""

    @property
    def accepted(self) -> bool:
        """True when the observation changed the state."""
        return self.status == "accepted"

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (NaN/inf become None)."""
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {"kind": self.kind, "t": self.t, "status": self.status, "nis": num(self.nis),
                "dof": self.dof, "threshold": num(self.threshold),
                "innovation": np.asarray(self.innovation).tolist(),
                "innovation_cov": np.asarray(self.innovation_cov).tolist(),
                "source": self.source, "reason": self.reason}


def summarize(diagnostics: Iterable[UpdateDiagnostics]) -> dict[str, dict[str, int]]:
    """Counts per kind and status, e.g. ``{"fix": {"accepted": 10, "rejected": 1}}``."""
    counts: dict[str, Counter[str]] = {}
    for d in diagnostics:
        counts.setdefault(d.kind, Counter())[d.status] += 1
    return {k: dict(v) for k, v in counts.items()}


@dataclass(frozen=True, slots=True, eq=False)
class UpdateResult:
    """Posterior state vector and covariance of one update, with its diagnostics."""

    x: FloatArray
    P: FloatArray
    diagnostics: UpdateDiagnostics


@numba.njit(cache=True)
def joseph_kernel(x: FloatArray, p: FloatArray, h: FloatArray, r: FloatArray, nu: FloatArray,
                  threshold: float, angle_index: int, x_out: FloatArray, p_out: FloatArray,
                  s_out: FloatArray) -> tuple[int, float]:  # pragma: no cover - compiled
    """Compiled core of :func:`kalman_update` (any small ``n``, ``m``).

    Returns ``(code, nis)``: 0 accepted (``x_out``, ``p_out`` hold the posterior), 1 failed
    the gate, 2 ``S`` not positive definite (Cholesky fails, as LAPACK's), 3 non-finite input.
    ``s_out`` receives the symmetrized ``S``.
    """
    n = x.shape[0]
    m = nu.shape[0]
    for i in range(m):
        if not np.isfinite(nu[i]):
            return 3, math.nan
        for j in range(n):
            if not np.isfinite(h[i, j]):
                return 3, math.nan
        for j in range(m):
            if not np.isfinite(r[i, j]):
                return 3, math.nan
    hp = h @ p                                   # (m, n)
    a = hp @ h.T + r
    for i in range(m):
        for j in range(m):
            s_out[i, j] = 0.5 * (a[i, j] + a[j, i])
    # Cholesky S = L L^T; a pivot <= 0 (or NaN) means S is not positive definite
    el = np.zeros((m, m))
    for j in range(m):
        d = s_out[j, j]
        for k in range(j):
            d -= el[j, k] * el[j, k]
        if not d > 0.0:
            return 2, math.nan
        el[j, j] = math.sqrt(d)
        for i in range(j + 1, m):
            v = s_out[i, j]
            for k in range(j):
                v -= el[i, k] * el[j, k]
            el[i, j] = v / el[j, j]
    # sol = S^-1 [nu, H P] by forward / back substitution
    rhs = np.empty((m, n + 1))
    for i in range(m):
        rhs[i, 0] = nu[i]
        for j in range(n):
            rhs[i, j + 1] = hp[i, j]
    for c in range(n + 1):
        for i in range(m):
            v = rhs[i, c]
            for k in range(i):
                v -= el[i, k] * rhs[k, c]
            rhs[i, c] = v / el[i, i]
        for i in range(m - 1, -1, -1):
            v = rhs[i, c]
            for k in range(i + 1, m):
                v -= el[k, i] * rhs[k, c]
            rhs[i, c] = v / el[i, i]
    value = 0.0
    for i in range(m):
        value += nu[i] * rhs[i, 0]
    if value > threshold:
        return 1, value
    # K = P H^T S^-1 = (S^-1 H P)^T
    k_gain = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            k_gain[i, j] = rhs[j, i + 1]
    for i in range(n):
        acc = x[i]
        for j in range(m):
            acc += k_gain[i, j] * nu[j]
        x_out[i] = acc
    if angle_index >= 0:
        x_out[angle_index] = np.pi - np.mod(np.pi - x_out[angle_index], 2.0 * np.pi)
    ia = np.eye(n) - k_gain @ h
    q = ia @ p @ ia.T + k_gain @ r @ k_gain.T
    for i in range(n):
        for j in range(n):
            p_out[i, j] = 0.5 * (q[i, j] + q[j, i])
    return 0, value


def kalman_update(x: FloatArray, p: FloatArray, h: FloatArray, r: FloatArray,
                  innovation: FloatArray, *, gate_probability: float | None = None,
                  kind: str = "update", t: float = float("nan"), source: str = "",
                  angle_index: int | None = None) -> UpdateResult:
    """One (extended) Kalman update in Joseph form with a chi-square NIS gate.

    Parameters
    ----------
    x, p:
        Prior state (n,) and covariance (n, n), symmetric positive semi-definite.
    h:
        Measurement Jacobian (m, n).
    r:
        Measurement covariance (m, m), symmetric positive definite.
    innovation:
        ``z - h(x)`` (m,), already wrapped when it is an angle.
    gate_probability:
        Reject when the NIS exceeds the chi-square quantile of this probability; ``None``
        disables the gate.
    kind, t, source:
        Copied into the diagnostics.
    angle_index:
        Index of a state component that is an angle: wrapped to ``(-pi, pi]`` after the update.

    Returns
    -------
    UpdateResult
        With the prior unchanged when the observation was rejected.
    """
    n = x.shape[0]
    m = innovation.shape[0]
    if p.shape != (n, n) or h.shape != (m, n) or r.shape != (m, m):
        raise InputError(f"shapes x{x.shape} P{p.shape} H{h.shape} R{r.shape} nu{innovation.shape}",
                         where=f"{kind} update", expected="consistent Kalman dimensions")
    threshold = float("inf") if gate_probability is None else chi2_threshold(m, gate_probability)
    f64 = np.float64
    xc, pc = np.ascontiguousarray(x, dtype=f64), np.ascontiguousarray(p, dtype=f64)
    x_new = np.empty(n)
    p_new = np.empty((n, n))
    s = np.empty((m, m))
    code, value = joseph_kernel(xc, pc, np.ascontiguousarray(h, dtype=f64),
                                np.ascontiguousarray(r, dtype=f64),
                                np.ascontiguousarray(innovation, dtype=f64), threshold,
                                -1 if angle_index is None else int(angle_index), x_new, p_new, s)
    if code == 3:
        raise InputError("non-finite innovation, Jacobian or noise", where=f"{kind} update",
                         expected="finite values")
    if code == 2:
        diag = UpdateDiagnostics(kind, t, "rejected", dof=m, threshold=threshold,
                                 innovation=innovation.copy(), innovation_cov=s, source=source,
                                 reason="innovation covariance not positive definite")
        return UpdateResult(x, p, diag)
    if code == 1:
        diag = UpdateDiagnostics(kind, t, "rejected", nis=value, dof=m, threshold=threshold,
                                 innovation=innovation.copy(), innovation_cov=s, source=source,
                                 reason="failed the chi-square gate")
        return UpdateResult(x, p, diag)
    diag = UpdateDiagnostics(kind, t, "accepted", nis=value, dof=m, threshold=threshold,
                             innovation=innovation.copy(), innovation_cov=s, source=source)
    return UpdateResult(x_new, p_new, diag)


def skipped(kind: str, t: float, reason: str, source: str = "") -> UpdateDiagnostics:
    """Diagnostics of an observation that was not used (not due, no landmark, ...)."""
    return UpdateDiagnostics(kind, t, "skipped", source=source, reason=reason)


def rejected(kind: str, t: float, reason: str, source: str = "") -> UpdateDiagnostics:
    """Diagnostics of an observation rejected before forming an innovation."""
    return UpdateDiagnostics(kind, t, "rejected", source=source, reason=reason)
