"""RSS of beacons fused with the position filter (Tarrio, Besada, Casar).

The path loss (eq. 1) is :mod:`hrtls.fusion.path_loss`, the scan positions (eq. 2) are
:mod:`hrtls.fusion.rss_scans`, the channel re-estimation is :mod:`hrtls.fusion.channel`.

* :func:`rss_update` -- the tighter variant: each RSS reading corrects the position filter
  directly by an EKF in the dB domain (``h(p) = A - 10 eta log10(|p - a|/d0)``, variance
  ``sigma^2``, compiled in :func:`rss_db_correction`), or, with ``domain="range"``, as a range
  ``d`` with ``sigma_d`` through :func:`hrtls.fusion.ranges.range_update`.
* :func:`update_rss_readings` -- the tight variant over several readings, optionally
  re-estimating the channel first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.errors import InputError
from hrtls.fusion._checks import (
    FloatArray,
    finite_scalar,
    finite_vector,
)
from hrtls.fusion.channel import ChannelEstimator, ChannelState
from hrtls.fusion.gating import (
    GATED,
    NOT_SPD,
    TOO_NEAR,
    UpdateDiagnostics,
    chi2_threshold,
    positioned_readings,
    rejected,
    scalar_diagnostics,
    scalar_update,
)
from hrtls.fusion.path_loss import LN10, PathLossModel
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.shadowing import MIN_INFO_FRACTION
from hrtls.fusion.state import FilterState
from hrtls.kernels import njit


# ------------------------------------------------------------------------------------------
# tighter variant: RSS readings straight into the position filter
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class RssUpdate:
    """New state and diagnostics of one reading."""

    state: FilterState
    diagnostics: UpdateDiagnostics


@njit(cache=True, error_model="numpy")
def rss_db_correction(x: FloatArray, p: FloatArray, anchor_x: float, anchor_y: float,
                      anchor_z: float, rss_dbm: float, a_dbm: float, eta: float, d0_m: float,
                      sigma_db: float, min_distance_m: float, threshold: float, gated: bool,
                      use_3d: bool, info_fraction: float = 1.0
                      ) -> tuple[int, float, float, float]:  # pragma: no cover
    """EKF update with one RSS reading in the dB domain on plain arrays, in place.

    ``h(p) = A - 10 eta log10(d/d0)`` with ``A = a_dbm``; ``sigma_db`` is the reading's
    1-sigma. ``info_fraction`` ``w`` in (0, 1]: the reading enters with the variance
    ``sigma^2 / w`` (correlated readings, :mod:`hrtls.fusion.shadowing` eq. 1); the gate tests
    the innovation against the reading's own variance, ``S = H P H^T + sigma^2``. Returns
    ``(code, nis, S, nu)``: :data:`~hrtls.fusion.gating.TOO_NEAR` (NaNs) when the estimate is
    nearer than ``min_distance_m``, else the outcome of the gate and of
    :func:`~hrtls.fusion.gating.scalar_update`.
    """
    dx = x[0] - anchor_x
    dy = x[1] - anchor_y
    if use_3d:
        dz = x[2] - anchor_z
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    else:
        dz = 0.0
        dist = math.sqrt(dx * dx + dy * dy)
    if dist < min_distance_m:
        return TOO_NEAR, math.nan, math.nan, math.nan
    pred = a_dbm - 10.0 * eta * math.log10(dist / d0_m)
    g = -10.0 * eta / LN10 / (dist * dist)     # H = -10 eta / ln10 (p - a)^T / d^2
    nu = rss_dbm - pred
    h = (g * dx, g * dy, g * dz, 0.0)
    r = sigma_db * sigma_db
    if info_fraction >= 1.0:
        code, nis, s = scalar_update(x, p, h, r, nu, threshold, gated)
        return code, nis, s, nu
    hph = 0.0
    for i in range(3):
        for j in range(3):
            hph += h[i] * p[i, j] * h[j]
    s = hph + r
    if not s > 0.0:
        return NOT_SPD, math.nan, s, nu
    nis = nu * nu / s
    if gated and nis > threshold:
        return GATED, nis, s, nu
    code, _, _ = scalar_update(x, p, h, r / max(info_fraction, MIN_INFO_FRACTION), nu,
                               threshold, np.bool_(False))  # not a literal: one build
    return code, nis, s, nu


def rss_update(state: FilterState, anchor_xyz: ArrayLike, rss_dbm: float,
               model: PathLossModel, *, domain: Literal["db", "range"] = "db",
               min_distance_m: float = 0.5, gate_probability: float | None = 0.999,
               use_3d: bool = False, t: float | None = None, source: str = "",
               info_fraction: float = 1.0) -> RssUpdate:
    """EKF update of the position filter with one RSS reading.

    ``domain="db"``: ``z = rss``, ``h = A - 10 eta log10(d/d0)``,
    ``H = -10 eta / ln10 (p - a)^T / d^2``, ``R = sigma^2`` (:func:`rss_db_correction`).
    ``domain="range"``: the reading is converted by eq. 1 to ``d`` with ``sigma_d`` and applied
    by the range EKF. ``d`` is planar, or with ``use_3d`` the slant distance using the state's z
    (anchors at other heights). Estimates nearer than ``min_distance_m`` are rejected (no
    direction). ``info_fraction`` (dB domain): the reading's share of the information of an
    independent one (:mod:`hrtls.fusion.shadowing`; its variance is divided by it).
    """
    a = finite_vector(anchor_xyz, where="rss anchor_xyz", length=3)
    z = finite_scalar(rss_dbm, where="rss rss_dbm")
    w = finite_scalar(info_fraction, where="rss info_fraction")
    if not 0.0 <= w <= 1.0:
        raise InputError(f"{w}", where="rss info_fraction", expected="a value in [0, 1]")
    tt = state.t if t is None else float(t)
    if domain == "range":
        d = float(model.distance(z))
        sigma_d = float(model.distance_sigma(z)) / math.sqrt(max(w, MIN_INFO_FRACTION))
        upd = range_update(state, a, d, sigma_d,
                           params=RangeParams(min_distance_m=min_distance_m, use_3d=use_3d,
                                              gate_probability=gate_probability),
                           t=tt, source=source, kind="rss")
        return RssUpdate(upd.state, upd.diagnostics)
    if domain != "db":
        raise InputError(f"domain {domain!r}", where="rss_update", expected="'db' or 'range'")
    threshold = math.inf if gate_probability is None else chi2_threshold(1, gate_probability)
    x, p = state.x.copy(), state.P.copy()
    code, nis, s, nu = rss_db_correction(x, p, a[0], a[1], a[2], z, model.a_dbm, model.eta,
                                         model.d0_m, model.sigma_db, min_distance_m,
                                         threshold, gate_probability is not None, use_3d, w)
    if code == TOO_NEAR:
        return RssUpdate(state, rejected("rss", tt, "estimate on top of the anchor", source))
    diag = scalar_diagnostics("rss", tt, code, nis, s, nu, threshold, source)
    return RssUpdate(state.evolve(x=x, P=p) if diag.accepted else state, diag)


def update_rss_readings(state: FilterState, rss: RssReadings, indices: ArrayLike,
                        landmarks: dict[str, Landmark], model: PathLossModel, *,
                        domain: Literal["db", "range"] = "db",
                        gate_probability: float | None = 0.999, use_3d: bool = False,
                        estimator: ChannelEstimator | None = None,
                        channel: ChannelState | None = None
                        ) -> tuple[FilterState, list[UpdateDiagnostics], ChannelState | None]:
    """Tight variant over several readings, optionally re-estimating the channel first.

    When ``estimator`` and ``channel`` are given, each reading first updates the channel
    estimate (with the distance to the current position estimate) and is then applied with the
    re-estimated model.
    """
    diags: list[UpdateDiagnostics] = []
    for i, t, anchor, a in positioned_readings(indices, rss.anchor, rss.t, landmarks,
                                               kind="rss", what="anchor", diagnostics=diags):
        if estimator is not None and channel is not None:
            dims = 3 if use_3d else 2
            dist = float(np.linalg.norm(state.x[:dims] - a[:dims]))
            channel, _ = estimator.update(channel, rss_dbm=float(rss.rss_dbm[i]),
                                          distance_m=dist,
                                          distance_var_m2=float(np.trace(state.P[:2, :2])) / 2.0,
                                          d0_m=model.d0_m)
            model = channel.model(model.d0_m)
        upd = rss_update(state, a, float(rss.rss_dbm[i]), model, domain=domain,
                         gate_probability=gate_probability, use_3d=use_3d, t=t, source=anchor)
        state = upd.state
        diags.append(upd.diagnostics)
    return state, diags, channel

