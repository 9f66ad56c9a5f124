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

The 4-state filter's frequent corrections use two compiled special cases on plain arrays,
callable from other compiled code (the tracker's event loop) and from Python:
:func:`scalar_update` (one scalar measurement, any ``h``) and :func:`position_update` (a 2-D
position, ``H = [I2 0]``). Both return an outcome code (:data:`ACCEPTED`, :data:`GATED`,
:data:`NOT_SPD`); :func:`scalar_diagnostics` turns a scalar outcome into
:class:`UpdateDiagnostics`.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray
from hrtls.kernels import njit

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from hrtls.data.landmarks import Landmark

Status = Literal["accepted", "rejected", "skipped"]

ACCEPTED, GATED, TOO_NEAR, NOT_SPD = 0, 1, 2, 3
"""Outcome codes of the compiled corrections: accepted, failed the gate, estimate too near the
landmark (no direction), innovation covariance not positive definite."""
N_FILTER_STATE = 4
"""Size of the rescuer filter state ``[x, y, z, heading]`` the compiled corrections work on."""

DEFAULT_GATE_PROBABILITY = 0.999
"""Default gate: an observation is rejected when its NIS exceeds the 99.9 % chi-square quantile."""

KNOWN_CHI2_QUANTILES: dict[tuple[int, float], float] = {
    (1, 0.997): 8.807468393511947, (2, 0.997): 11.618285980628052,
    (3, 0.997): 13.931422665512084, (1, 0.999): 10.827566170662733,
    (2, 0.999): 13.815510557964274, (3, 0.999): 16.26623619623813}
"""``chi2_threshold`` of the gates the configurations use, the values scipy computes (tested):
starting a tracker then imports no ``scipy.special``."""


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
    known = KNOWN_CHI2_QUANTILES.get((dof, probability))
    if known is not None:
        return known
    from scipy.special import gammaincinv  # scipy.stats is much slower to import

    # chi2.ppf of scipy.stats: 2 P^-1(dof / 2, probability), P the regularized lower
    # incomplete gamma function
    return float(2.0 * gammaincinv(0.5 * dof, probability))


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
    from scipy import linalg

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


@njit(cache=True)
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


@njit(cache=True, error_model="numpy")
def wrap_rad(a: float) -> float:  # pragma: no cover - compiled
    """Angle wrapped to ``(-pi, pi]`` (as :func:`hrtls.frames.wrap_angle`)."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@njit(cache=True, error_model="numpy")
def symmetrize_in_place(p: FloatArray) -> None:  # pragma: no cover - compiled
    """``P <- (P + P^T) / 2`` for the 4x4 filter covariance (the diagonal is kept exactly)."""
    for i in range(N_FILTER_STATE):
        for j in range(i + 1, N_FILTER_STATE):
            m = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = m
            p[j, i] = m


@njit(cache=True, error_model="numpy")
def scalar_update(x: FloatArray, p: FloatArray, h: tuple[float, float, float, float], r: float,
                  nu: float, threshold: float, gated: bool
                  ) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """Gated Joseph-form update of the 4-state filter with one scalar measurement, in place.

    ``h`` is the measurement row, ``r`` its variance, ``nu = z - h(x)``; the heading ``x[3]``
    is wrapped after the update. Returns ``(code, nis, S)`` with ``S = h P h^T + r``; the state
    is unchanged unless the code is :data:`ACCEPTED`. The Joseph form
    ``P+ = (I - k h) P (I - k h)^T + k r k^T`` is expanded without temporaries:
    ``P+_ij = P_ij - k_i (h P)_j - q_i k_j + r k_i k_j`` with ``q = (I - k h) P h^T``, then
    symmetrized.
    """
    ph0 = p[0, 0] * h[0] + p[0, 1] * h[1] + p[0, 2] * h[2] + p[0, 3] * h[3]
    ph1 = p[1, 0] * h[0] + p[1, 1] * h[1] + p[1, 2] * h[2] + p[1, 3] * h[3]
    ph2 = p[2, 0] * h[0] + p[2, 1] * h[1] + p[2, 2] * h[2] + p[2, 3] * h[3]
    ph3 = p[3, 0] * h[0] + p[3, 1] * h[1] + p[3, 2] * h[2] + p[3, 3] * h[3]
    s = r + (h[0] * ph0 + h[1] * ph1 + h[2] * ph2 + h[3] * ph3)
    if not s > 0.0:
        return NOT_SPD, math.nan, s
    nis = nu * nu / s
    if gated and nis > threshold:
        return GATED, nis, s
    k = (ph0 / s, ph1 / s, ph2 / s, ph3 / s)
    ph = (ph0, ph1, ph2, ph3)
    hp = (h[0] * p[0, 0] + h[1] * p[1, 0] + h[2] * p[2, 0] + h[3] * p[3, 0],
          h[0] * p[0, 1] + h[1] * p[1, 1] + h[2] * p[2, 1] + h[3] * p[3, 1],
          h[0] * p[0, 2] + h[1] * p[1, 2] + h[2] * p[2, 2] + h[3] * p[3, 2],
          h[0] * p[0, 3] + h[1] * p[1, 3] + h[2] * p[2, 3] + h[3] * p[3, 3])
    hph = hp[0] * h[0] + hp[1] * h[1] + hp[2] * h[2] + hp[3] * h[3]
    for i in range(N_FILTER_STATE):
        x[i] += k[i] * nu
    x[3] = wrap_rad(x[3])
    for i in range(N_FILTER_STATE):
        qi = ph[i] - k[i] * hph
        for j in range(N_FILTER_STATE):
            p[i, j] = p[i, j] - k[i] * hp[j] - qi * k[j] + k[i] * r * k[j]
    symmetrize_in_place(p)
    return ACCEPTED, nis, s


@njit(cache=True, error_model="numpy")
def position_update(x: FloatArray, p: FloatArray, r00: float, r01: float, r11: float,
                    nu0: float, nu1: float, threshold: float,
                    aux: FloatArray) -> tuple[int, float]:  # pragma: no cover - compiled
    """Gated Joseph update of the 4-state filter with a 2-D position (``H = [I2 0]``), in place.

    ``R = [[r00, r01], [r01, r11]]``, ``nu = (nu0, nu1)``; ``aux`` receives
    ``[nu0, nu1, S00, S01, S11]``. Returns ``(code, nis)``.
    """
    s00 = p[0, 0] + r00
    s11 = p[1, 1] + r11
    s01 = 0.5 * ((p[0, 1] + r01) + (p[1, 0] + r01))
    aux[0] = nu0
    aux[1] = nu1
    aux[2] = s00
    aux[3] = s01
    aux[4] = s11
    det = s00 * s11 - s01 * s01
    if not (s00 > 0.0 and det > 0.0):      # Cholesky of a 2x2 fails
        return NOT_SPD, math.nan
    i00 = s11 / det
    i01 = -s01 / det
    i11 = s00 / det
    nis = nu0 * (i00 * nu0 + i01 * nu1) + nu1 * (i01 * nu0 + i11 * nu1)
    if nis > threshold:
        return GATED, nis
    # K = P H^T S^-1 (4x2)
    kk = np.empty((N_FILTER_STATE, 2))
    for i in range(N_FILTER_STATE):
        kk[i, 0] = p[i, 0] * i00 + p[i, 1] * i01
        kk[i, 1] = p[i, 0] * i01 + p[i, 1] * i11
    for i in range(N_FILTER_STATE):
        x[i] += kk[i, 0] * nu0 + kk[i, 1] * nu1
    x[3] = wrap_rad(x[3])
    a = np.eye(N_FILTER_STATE)
    for i in range(N_FILTER_STATE):
        a[i, 0] -= kk[i, 0]
        a[i, 1] -= kk[i, 1]
    apa = a @ p @ a.T
    for i in range(N_FILTER_STATE):
        for j in range(N_FILTER_STATE):
            krk = (kk[i, 0] * (r00 * kk[j, 0] + r01 * kk[j, 1])
                   + kk[i, 1] * (r01 * kk[j, 0] + r11 * kk[j, 1]))
            p[i, j] = apa[i, j] + krk
    symmetrize_in_place(p)
    return ACCEPTED, nis


def scalar_diagnostics(kind: str, t: float, code: int, nis_value: float, s: float, nu: float,
                       threshold: float, source: str = "") -> UpdateDiagnostics:
    """:class:`UpdateDiagnostics` of a :func:`scalar_update` outcome (as :func:`kalman_update`)."""
    innovation = np.array([nu])
    cov = np.array([[s]])
    if code == ACCEPTED:
        return UpdateDiagnostics(kind, t, "accepted", nis=nis_value, dof=1, threshold=threshold,
                                 innovation=innovation, innovation_cov=cov, source=source)
    reason = ("failed the chi-square gate" if code == GATED
              else "innovation covariance not positive definite")
    return UpdateDiagnostics(kind, t, "rejected", nis=nis_value if code == GATED else math.nan,
                             dof=1, threshold=threshold, innovation=innovation,
                             innovation_cov=cov, source=source, reason=reason)


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


def positioned_readings(indices: ArrayLike, ids: np.ndarray, t_s: FloatArray,
                        landmarks: dict[str, Landmark], *, kind: str, what: str,
                        diagnostics: list[UpdateDiagnostics]
                        ) -> Iterator[tuple[int, float, str, FloatArray]]:
    """``(index, t s, landmark id, landmark xyz m)`` of the readings ``indices`` in order.

    A reading whose landmark is unknown or has no position is not yielded: a skipped
    diagnostic ("``what`` without a known position") is appended to ``diagnostics`` in its
    place, so that the caller's diagnostics stay in reading order.
    """
    for i in np.asarray(indices, dtype=np.int64):
        landmark_id = str(ids[i])
        t = float(t_s[i])
        lm = landmarks.get(landmark_id)
        if lm is None or lm.position is None:
            diagnostics.append(skipped(kind, t, f"{what} without a known position", landmark_id))
            continue
        yield int(i), t, landmark_id, lm.xyz()
