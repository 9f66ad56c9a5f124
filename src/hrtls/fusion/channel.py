"""Online re-estimation of the path-loss channel ``A`` and ``eta`` (after Tarrio et al.).

Recursive least squares with exponential forgetting on ``rss = A - 10 eta log10(d/d0)`` where
``d`` is the distance from the current position estimate to the anchor. Each reading is weighted
by ``sigma^2 / (sigma^2 + (10 eta / ln 10)^2 var_d / d^2)`` so that readings taken while the
position is uncertain count less; readings nearer than ``min_distance_m`` or taken with a
position variance above ``max_position_var_m2`` are skipped. The prior ``(A, eta)`` with its
covariance regularizes the start; the covariance is capped at the prior to avoid wind-up when
the geometry does not excite both parameters. The shadowing ``sigma`` is re-estimated as the
exponentially weighted RMS of the prior residuals (floored at 1e-6 dB^2).

:func:`channel_update` is the compiled update of one reading on records and plain arrays;
:meth:`ChannelEstimator.update` and the tracker's event loop both call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar, finite_vector
from hrtls.fusion._records import to_record
from hrtls.fusion.path_loss import LN10, PathLossModel
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True)
class ChannelEstimatorParams:
    """Parameters of :class:`ChannelEstimator`.

    Attributes
    ----------
    forgetting: RLS forgetting factor in (0, 1]; effective memory ``1 / (1 - forgetting)``.
    sigma_a_prior_db: 1-sigma of the prior ``A``, dB.
    sigma_eta_prior: 1-sigma of the prior ``eta``.
    min_distance_m: readings estimated nearer than this are skipped.
    max_position_var_m2: readings taken with ``trace(P_xy)`` above this are skipped.
    eta_bounds: admissible ``eta`` range (estimates are clipped).
    """

    forgetting: float = 0.999
    sigma_a_prior_db: float = 10.0
    sigma_eta_prior: float = 1.0
    min_distance_m: float = 1.0
    max_position_var_m2: float = 25.0
    eta_bounds: tuple[float, float] = (1.0, 6.0)

    def __post_init__(self) -> None:
        f = finite_scalar(self.forgetting, where="ChannelEstimatorParams.forgetting",
                          positive=True)
        if f > 1.0:
            raise InputError(f"{f}", where="ChannelEstimatorParams.forgetting",
                             expected="a value in (0, 1]")
        for name in ("sigma_a_prior_db", "sigma_eta_prior", "min_distance_m",
                     "max_position_var_m2"):
            finite_scalar(getattr(self, name), where=f"ChannelEstimatorParams.{name}",
                          positive=True)

    def record(self) -> np.ndarray:
        """The parameters as a one-element :data:`CHANNEL_ESTIMATOR_DTYPE` array."""
        return to_record(CHANNEL_ESTIMATOR_DTYPE, self, eta_min=self.eta_bounds[0],
                         eta_max=self.eta_bounds[1])


CHANNEL_ESTIMATOR_DTYPE = np.dtype([
    ("forgetting", np.float64), ("sigma_a_prior_db", np.float64),
    ("sigma_eta_prior", np.float64), ("min_distance_m", np.float64),
    ("max_position_var_m2", np.float64), ("eta_min", np.float64), ("eta_max", np.float64)])
"""Record of :class:`ChannelEstimatorParams` for compiled code (``eta_bounds`` as two fields)."""

CHANNEL_STATE_DTYPE = np.dtype([("a_dbm", np.float64), ("eta", np.float64),
                                ("residual_var_db2", np.float64), ("count", np.int64)])
"""Scalars of :class:`ChannelState` for compiled code (``theta = [a_dbm, eta]``; the 2x2
covariance is a separate array)."""


@dataclass(frozen=True, slots=True, eq=False)
class ChannelState:
    """RLS state: ``theta = [A, eta]``, its covariance, the residual variance, the count."""

    theta: FloatArray
    cov: FloatArray
    residual_var_db2: float
    count: int = 0

    def model(self, d0_m: float = 1.0) -> PathLossModel:
        """The current path-loss model."""
        return PathLossModel(a_dbm=float(self.theta[0]), eta=float(self.theta[1]),
                             sigma_db=math.sqrt(self.residual_var_db2), d0_m=d0_m)

    def record(self) -> np.ndarray:
        """The scalars as a one-element :data:`CHANNEL_STATE_DTYPE` array."""
        return to_record(CHANNEL_STATE_DTYPE, self, a_dbm=self.theta[0], eta=self.theta[1])

    @classmethod
    def from_record(cls, rec: np.record, cov: FloatArray) -> ChannelState:
        """From a :data:`CHANNEL_STATE_DTYPE` record and the covariance (copied)."""
        return cls(np.array([rec["a_dbm"], rec["eta"]]), np.array(cov, dtype=np.float64),
                   float(rec["residual_var_db2"]), int(rec["count"]))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"theta": self.theta.tolist(), "cov": self.cov.tolist(),
                "residual_var_db2": self.residual_var_db2, "count": self.count}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ChannelState:
        """Inverse of :meth:`to_dict`."""
        return cls(finite_vector(data["theta"], where="channel theta", length=2),
                   np.asarray(data["cov"], dtype=np.float64),
                   float(data["residual_var_db2"]), int(data.get("count", 0)))


class ChannelEstimator:
    """Recursive least squares with forgetting for ``A`` and ``eta`` (see the module docstring)."""

    def __init__(self, params: ChannelEstimatorParams | None = None) -> None:
        self.params = params or ChannelEstimatorParams()

    def start(self, prior: PathLossModel) -> ChannelState:
        """Initial state at the prior model."""
        prm = self.params
        cov = np.diag([prm.sigma_a_prior_db**2, prm.sigma_eta_prior**2])
        return ChannelState(np.array([prior.a_dbm, prior.eta]), cov, prior.sigma_db**2, 0)

    def update(self, cstate: ChannelState, *, rss_dbm: ArrayLike, distance_m: ArrayLike,
               distance_var_m2: ArrayLike | float = 0.0, d0_m: float = 1.0
               ) -> tuple[ChannelState, int]:
        """Feed readings with the distances to the current position estimate.

        Returns the new state and how many readings were used.
        """
        r = finite_vector(np.atleast_1d(np.asarray(rss_dbm, dtype=np.float64)),
                          where="channel rss_dbm")
        d = finite_vector(np.atleast_1d(np.asarray(distance_m, dtype=np.float64)),
                          where="channel distance_m", length=r.size)
        dv = np.ascontiguousarray(np.broadcast_to(
            np.asarray(distance_var_m2, dtype=np.float64), (r.size,)))
        rec = cstate.record()
        cov = np.array(cstate.cov, dtype=np.float64)
        used = channel_update_readings(self.params.record()[0], rec, cov, r, d, dv,
                                       finite_scalar(d0_m, where="channel d0_m", positive=True))
        return ChannelState.from_record(rec[0], cov), used


@njit(cache=True, error_model="numpy")
def channel_update(prm: np.record, cs: np.record, cov: FloatArray, rss_dbm: float,
                   distance_m: float, distance_var_m2: float, d0_m: float
                   ) -> bool:  # pragma: no cover - compiled
    """One reading of the RLS with forgetting, in place; False when the reading is skipped.

    ``prm``: a :data:`CHANNEL_ESTIMATOR_DTYPE` record; ``cs``: a :data:`CHANNEL_STATE_DTYPE`
    record; ``cov``: the 2x2 covariance of ``[A, eta]``. Regressor ``phi = [1, -10 log10(d/d0)]``,
    gain ``k = P phi / (lambda / w + phi^T P phi)`` with the reading weight ``w``,
    ``P+ = (P - k phi^T P) / lambda`` (see the module docstring).
    """
    if distance_m < prm.min_distance_m or distance_var_m2 > prm.max_position_var_m2:
        return False
    lam = prm.forgetting
    d = distance_m
    phi0 = 1.0
    phi1 = -10.0 * math.log10(d / d0_m)
    e = rss_dbm - (phi0 * cs.a_dbm + phi1 * cs.eta)
    slope = 10.0 * cs.eta / LN10
    res_var = cs.residual_var_db2
    # residual variance of this reading: shadowing + position error through the slope
    s2 = res_var + slope * slope * distance_var_m2 / (d * d)
    pp0 = cov[0, 0] * phi0 + cov[0, 1] * phi1
    pp1 = cov[1, 0] * phi0 + cov[1, 1] * phi1
    # bounded pull of one reading (2.5 sigma of its predicted residual): an outlier or a wrong
    # position estimate cannot drag A and eta away
    lim = 2.5 * math.sqrt(s2 + (phi0 * pp0 + phi1 * pp1))
    e = min(max(e, -lim), lim)
    w = res_var / s2
    den = lam / w + (phi0 * pp0 + phi1 * pp1)
    k0 = pp0 / den
    k1 = pp1 / den
    cs.a_dbm += k0 * e
    cs.eta += k1 * e
    c00 = (cov[0, 0] - k0 * pp0) / lam
    c01 = (cov[0, 1] - k0 * pp1) / lam
    c10 = (cov[1, 0] - k1 * pp0) / lam
    c11 = (cov[1, 1] - k1 * pp1) / lam
    m = 0.5 * (c01 + c10)
    cov[0, 0] = c00
    cov[0, 1] = m
    cov[1, 0] = m
    cov[1, 1] = c11
    # cap at the prior (no wind-up without excitation)
    cap = prm.sigma_a_prior_db ** 2 + prm.sigma_eta_prior ** 2
    tr = c00 + c11
    if tr > cap:
        f = cap / tr
        for i in range(2):
            for j in range(2):
                cov[i, j] *= f
    # eta clipped to its bounds: move A along their correlation (conditional mean)
    eta_c = min(max(cs.eta, prm.eta_min), prm.eta_max)
    if eta_c != cs.eta:
        cs.a_dbm += cov[0, 1] / cov[1, 1] * (eta_c - cs.eta)
        cs.eta = eta_c
    cs.residual_var_db2 = max(lam * res_var + (1.0 - lam) * e * e, 1e-6)
    cs.count += 1
    return True


@njit(cache=True, error_model="numpy")
def channel_update_readings(prm: np.record, cs: np.ndarray, cov: FloatArray, rss_dbm: FloatArray,
                            distance_m: FloatArray, distance_var_m2: FloatArray, d0_m: float
                            ) -> int:  # pragma: no cover - compiled
    """:func:`channel_update` for each reading in order; ``cs`` a one-element state array."""
    used = 0
    for i in range(rss_dbm.shape[0]):
        if channel_update(prm, cs[0], cov, rss_dbm[i], distance_m[i], distance_var_m2[i], d0_m):
            used += 1
    return used
