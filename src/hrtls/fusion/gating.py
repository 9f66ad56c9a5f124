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

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal

import numpy as np
from scipy import linalg
from scipy.stats import chi2

from hrtls.errors import InputError
from hrtls.frames import wrap_angle
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
    if not (np.all(np.isfinite(innovation)) and np.all(np.isfinite(h))
            and np.all(np.isfinite(r))):
        raise InputError("non-finite innovation, Jacobian or noise", where=f"{kind} update",
                         expected="finite values")
    threshold = float("inf") if gate_probability is None else chi2_threshold(m, gate_probability)
    s = symmetrize(h @ p @ h.T + r)
    try:
        np.linalg.cholesky(s)           # positive definite? (small m: numpy is faster)
    except np.linalg.LinAlgError:
        diag = UpdateDiagnostics(kind, t, "rejected", dof=m, threshold=threshold,
                                 innovation=innovation.copy(), innovation_cov=s, source=source,
                                 reason="innovation covariance not positive definite")
        return UpdateResult(x, p, diag)
    sol = np.linalg.solve(s, np.column_stack([innovation, h @ p]))
    value = float(innovation @ sol[:, 0])
    if value > threshold:
        diag = UpdateDiagnostics(kind, t, "rejected", nis=value, dof=m, threshold=threshold,
                                 innovation=innovation.copy(), innovation_cov=s, source=source,
                                 reason="failed the chi-square gate")
        return UpdateResult(x, p, diag)
    # K = P H^T S^-1, computed as (S^-1 H P)^T
    k = sol[:, 1:].T
    x_new = x + k @ innovation
    if angle_index is not None:
        x_new[angle_index] = float(wrap_angle(x_new[angle_index]))
    a = np.eye(n) - k @ h
    p_new = symmetrize(a @ p @ a.T + k @ r @ k.T)
    diag = UpdateDiagnostics(kind, t, "accepted", nis=value, dof=m, threshold=threshold,
                             innovation=innovation.copy(), innovation_cov=s, source=source)
    return UpdateResult(x_new, p_new, diag)


def skipped(kind: str, t: float, reason: str, source: str = "") -> UpdateDiagnostics:
    """Diagnostics of an observation that was not used (not due, no landmark, ...)."""
    return UpdateDiagnostics(kind, t, "skipped", source=source, reason=reason)


def rejected(kind: str, t: float, reason: str, source: str = "") -> UpdateDiagnostics:
    """Diagnostics of an observation rejected before forming an innovation."""
    return UpdateDiagnostics(kind, t, "rejected", source=source, reason=reason)
