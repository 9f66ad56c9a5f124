"""RSS of beacons fused with the position filter (Tarrio, Besada, Casar).

The path loss (eq. 1) is :mod:`hrtls.fusion.path_loss`, the scan positions (eq. 2) are
:mod:`hrtls.fusion.rss_scans`, the channel re-estimation is :mod:`hrtls.fusion.channel`.

* :class:`TarrioFusion` -- the linear Kalman filter of eq. 5-13 with the inertial velocity as
  control input: between RSS fixes the position is dead-reckoned (eq. 13), at each fix it is
  predicted (eq. 8) with ``Q`` of eq. 6 and corrected (eq. 10-12, Joseph form, gated).
  Reading of eq. 8: ``Delta T v_k`` is the displacement over the interval; with
  ``control="mean"`` (default) ``v_k`` is the mean inertial velocity over the interval (so the
  prediction equals the dead-reckoned position of eq. 13), with ``control="last"`` it is the last
  velocity sample, literally.
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
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.errors import InputError
from hrtls.fusion._checks import (
    FloatArray,
    finite_scalar,
    finite_vector,
    non_decreasing_time,
    probability,
)
from hrtls.fusion.channel import ChannelEstimator, ChannelState
from hrtls.fusion.gating import (
    TOO_NEAR,
    UpdateDiagnostics,
    chi2_threshold,
    kalman_update,
    rejected,
    scalar_diagnostics,
    scalar_update,
    skipped,
)
from hrtls.fusion.path_loss import LN10, PathLossModel
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.state import IH, N_STATE, FilterState


# ------------------------------------------------------------------------------------------
# eq. 5-13: Kalman fusion with inertial velocity as control input
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class TarrioParams:
    """Parameters of the Tarrio Kalman fusion (values of the paper as defaults).

    Attributes
    ----------
    sigma_a_m_s2: acceleration noise of eq. 6, m/s^2.
    sigma_v_m_s: velocity noise of eq. 6, m/s.
    sigma_p_m: 1-sigma of an RSS position (``R = sigma_p^2 I``, eq. 7), m.
    use_wls_covariance: use the covariance of :func:`hyperbolic_wls` instead of ``sigma_p``.
    control: ``"mean"`` or ``"last"`` (reading of eq. 8, see the module docstring).
    gate_probability: chi-square gate; None disables it.
    """

    sigma_a_m_s2: float = 0.1
    sigma_v_m_s: float = 0.1
    sigma_p_m: float = 2.0
    use_wls_covariance: bool = False
    control: Literal["mean", "last"] = "mean"
    gate_probability: float | None = 0.999

    def __post_init__(self) -> None:
        for name in ("sigma_a_m_s2", "sigma_v_m_s", "sigma_p_m"):
            finite_scalar(getattr(self, name), where=f"TarrioParams.{name}", positive=True)
        if self.control not in ("mean", "last"):
            raise InputError(f"control {self.control!r}", where="TarrioParams.control",
                             expected="'mean' or 'last'")
        if self.gate_probability is not None:
            probability(self.gate_probability, where="TarrioParams.gate_probability")

    def q(self, dt: float) -> FloatArray:
        """Eq. 6: ``Q = I (sigma_a dt^2 / 2)^2 + I (sigma_v dt)^2``."""
        return np.eye(2) * ((0.5 * self.sigma_a_m_s2 * dt * dt) ** 2
                            + (self.sigma_v_m_s * dt) ** 2)


@dataclass(frozen=True, slots=True, eq=False)
class TarrioState:
    """Causal state of :class:`TarrioFusion`.

    Attributes
    ----------
    filter: dead-reckoned state now (``x`` eq. 13) with the covariance of the last update.
    x_update: filtered position at the last update, m (2,).
    t_update: time of the last update, s.
    last_velocity: last inertial velocity sample, m/s (2,).
    """

    filter: FilterState
    x_update: FloatArray
    t_update: float
    last_velocity: FloatArray

    @classmethod
    def start(cls, state: FilterState) -> TarrioState:
        """Begin at ``state`` (e.g. the first RSS position, as in the paper)."""
        return cls(state, state.x[:2].copy(), state.t, np.zeros(2))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"filter": self.filter.to_dict(), "x_update": self.x_update.tolist(),
                "t_update": self.t_update, "last_velocity": self.last_velocity.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TarrioState:
        """Inverse of :meth:`to_dict`."""
        return cls(FilterState.from_dict(data["filter"]),
                   finite_vector(data["x_update"], where="x_update", length=2),
                   float(data["t_update"]),
                   finite_vector(data["last_velocity"], where="last_velocity", length=2))


@dataclass(frozen=True, slots=True, eq=False)
class TarrioResult:
    """Per-sample track (``t``, ``xy``, ``cov_xy``), the filtered fixes and the new state."""

    t: FloatArray
    xy: FloatArray
    cov_xy: FloatArray
    t_fix: FloatArray
    xy_fix: FloatArray
    diagnostics: list[UpdateDiagnostics]
    state: TarrioState


class TarrioFusion:
    """Tarrio eq. 5-13: RSS positions fused with inertial velocity in a linear Kalman filter."""

    def __init__(self, params: TarrioParams | None = None) -> None:
        self.params = params or TarrioParams()

    def run(self, state: TarrioState, *, t: ArrayLike, speed_m_s: ArrayLike,
            heading_rad: ArrayLike, fix_t: ArrayLike, fix_xy: ArrayLike,
            fix_cov: ArrayLike | None = None) -> TarrioResult:
        """Dead-reckon through the velocity samples and fuse the RSS positions.

        Parameters
        ----------
        state:
            State before the chunk.
        t, speed_m_s, heading_rad:
            Inertial velocity samples (speed and direction, eq. 5), applied over
            ``(t_{i-1}, t_i]`` (eq. 13).
        fix_t, fix_xy:
            RSS position times (non-decreasing, within the chunk) and positions (M, 2).
        fix_cov:
            Their covariances (M, 2, 2), used with ``use_wls_covariance``.
        """
        prm = self.params
        tt = finite_vector(t, where="tarrio t")
        n = tt.size
        non_decreasing_time(tt, where="tarrio t", after=state.filter.t)
        v = finite_vector(np.broadcast_to(np.asarray(speed_m_s, dtype=np.float64), (n,)),
                          where="tarrio speed_m_s")
        th = finite_vector(heading_rad, where="tarrio heading_rad", length=n)
        ft = finite_vector(fix_t, where="tarrio fix_t")
        non_decreasing_time(ft, where="tarrio fix_t", after=state.filter.t)
        fxy = np.asarray(fix_xy, dtype=np.float64).reshape(-1, 2)
        if fxy.shape[0] != ft.size or not np.all(np.isfinite(fxy)):
            raise InputError(f"shape {fxy.shape}", where="tarrio fix_xy",
                             expected=f"finite ({ft.size}, 2) positions")
        fcov = None
        if fix_cov is not None:
            fcov = np.asarray(fix_cov, dtype=np.float64).reshape(-1, 2, 2)
        vel = np.column_stack([v * np.cos(th), v * np.sin(th)])
        dt = np.diff(np.concatenate(([state.filter.t], tt)))
        step = vel * dt[:, None]
        # eq. 13 between fixes: cumulative sums restarted after every fix
        fix_pos = np.searchsorted(tt, ft, side="right")   # samples <= fix time come before it
        xy_out = np.empty((n, 2))
        cov_out = np.empty((n, 2, 2))
        diags: list[UpdateDiagnostics] = []
        t_fixes: list[float] = []
        xy_fixes: list[FloatArray] = []
        x_now = state.filter.x.copy()
        p_upd = state.filter.P.copy()
        x_upd = state.x_update.copy()
        t_upd = state.t_update
        last_v = state.last_velocity.copy()
        start = 0
        for k in range(ft.size + 1):
            stop = n if k == ft.size else int(fix_pos[k])
            if stop > start:
                xy_out[start:stop] = x_now[:2] + np.cumsum(step[start:stop], axis=0)
                el = tt[start:stop] - t_upd
                qd = (0.5 * prm.sigma_a_m_s2 * el * el) ** 2 + (prm.sigma_v_m_s * el) ** 2
                cov_out[start:stop] = p_upd[:2, :2] + qd[:, None, None] * np.eye(2)
                x_now[:2] = xy_out[stop - 1]
                last_v = vel[stop - 1]
                x_now[IH] = th[stop - 1]
                start = stop
            if k == ft.size:
                break
            tf = float(ft[k])
            d_t = tf - t_upd
            # eq. 8: prediction from the last filtered position with the inertial control
            x_pred = x_now.copy()
            if prm.control == "last":
                x_pred[:2] = x_upd + d_t * last_v
            p_pred = p_upd.copy()
            p_pred[:2, :2] += prm.q(d_t)                                      # eq. 9
            r = (fcov[k] if (prm.use_wls_covariance and fcov is not None)
                 else np.eye(2) * prm.sigma_p_m**2)                          # eq. 7
            h = np.zeros((2, N_STATE))
            h[0, 0] = h[1, 1] = 1.0
            res = kalman_update(x_pred, p_pred, h, r, fxy[k] - x_pred[:2],
                                gate_probability=prm.gate_probability, kind="rss_position",
                                t=tf)                                         # eq. 10-12
            diags.append(res.diagnostics)
            x_now, p_upd = res.x, res.P
            x_upd = x_now[:2].copy()
            t_upd = tf
            t_fixes.append(tf)
            xy_fixes.append(x_upd.copy())
        t_end = float(tt[-1]) if n else state.filter.t
        t_end = max(t_end, t_upd)
        new_filter = FilterState(t_end, x_now, p_upd, state.filter.input_heading_rad,
                                 state.filter.has_input_heading,
                                 state.filter.reference_pending)
        new_state = TarrioState(new_filter, x_upd, t_upd, last_v)
        return TarrioResult(tt, xy_out, cov_out, np.asarray(t_fixes),
                            np.asarray(xy_fixes).reshape(-1, 2), diags, new_state)


def hold_last_fix(t: ArrayLike, fix_t: ArrayLike, fix_xy: ArrayLike) -> FloatArray:
    """Tarrio's "RSS alone" baseline: at each time the position of the last RSS fix (m, (N, 2)).

    Times before the first fix take the first fix. (The "RSS + PDR without filtering" baseline
    is :class:`TarrioFusion` with a tiny ``sigma_p_m`` and no gate: every fix resets the
    dead reckoning.)
    """
    tt = finite_vector(t, where="hold t")
    ft = finite_vector(fix_t, where="hold fix_t")
    non_decreasing_time(ft, where="hold fix_t")
    fxy = np.asarray(fix_xy, dtype=np.float64).reshape(-1, 2)
    if fxy.shape[0] != ft.size or ft.size == 0:
        raise InputError(f"{fxy.shape[0]} positions for {ft.size} times", where="hold fix_xy",
                         expected="one position per fix time, at least one fix")
    idx = np.maximum(np.searchsorted(ft, tt, side="right") - 1, 0)
    return np.asarray(fxy[idx], dtype=np.float64)


# ------------------------------------------------------------------------------------------
# tighter variant: RSS readings straight into the position filter
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class RssUpdate:
    """New state and diagnostics of one reading."""

    state: FilterState
    diagnostics: UpdateDiagnostics


@numba.njit(cache=True, error_model="numpy")
def rss_db_correction(x: FloatArray, p: FloatArray, anchor_x: float, anchor_y: float,
                      anchor_z: float, rss_dbm: float, a_dbm: float, eta: float, d0_m: float,
                      sigma_db: float, min_distance_m: float, threshold: float, gated: bool,
                      use_3d: bool) -> tuple[int, float, float, float]:  # pragma: no cover
    """EKF update with one RSS reading in the dB domain on plain arrays, in place.

    ``h(p) = A - 10 eta log10(d/d0)`` with ``A = a_dbm``; ``sigma_db`` is the reading's
    1-sigma. Returns ``(code, nis, S, nu)``: :data:`~hrtls.fusion.gating.TOO_NEAR` (NaNs) when
    the estimate is nearer than ``min_distance_m``, else the outcome of
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
    code, nis, s = scalar_update(x, p, (g * dx, g * dy, g * dz, 0.0), sigma_db * sigma_db, nu,
                                 threshold, gated)
    return code, nis, s, nu


def rss_update(state: FilterState, anchor_xyz: ArrayLike, rss_dbm: float,
               model: PathLossModel, *, domain: Literal["db", "range"] = "db",
               min_distance_m: float = 0.5, gate_probability: float | None = 0.999,
               use_3d: bool = False, t: float | None = None, source: str = "") -> RssUpdate:
    """EKF update of the position filter with one RSS reading.

    ``domain="db"``: ``z = rss``, ``h = A - 10 eta log10(d/d0)``,
    ``H = -10 eta / ln10 (p - a)^T / d^2``, ``R = sigma^2`` (:func:`rss_db_correction`).
    ``domain="range"``: the reading is converted by eq. 1 to ``d`` with ``sigma_d`` and applied
    by the range EKF. ``d`` is planar, or with ``use_3d`` the slant distance using the state's z
    (anchors at other heights). Estimates nearer than ``min_distance_m`` are rejected (no
    direction).
    """
    a = finite_vector(anchor_xyz, where="rss anchor_xyz", length=3)
    z = finite_scalar(rss_dbm, where="rss rss_dbm")
    tt = state.t if t is None else float(t)
    if domain == "range":
        d = float(model.distance(z))
        upd = range_update(state, a, d, float(model.distance_sigma(z)),
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
                                         threshold, gate_probability is not None, use_3d)
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
    for i in np.asarray(indices, dtype=np.int64):
        anchor = str(rss.anchor[i])
        t = float(rss.t[i])
        lm = landmarks.get(anchor)
        if lm is None or lm.position is None:
            diags.append(skipped("rss", t, "anchor without a known position", anchor))
            continue
        a = lm.xyz()
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

