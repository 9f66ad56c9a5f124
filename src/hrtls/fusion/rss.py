"""RSS of beacons: path loss, hyperbolic positioning, Kalman fusion, channel re-estimation.

From Tarrio, Besada, Casar (calibration-free RSS + inertial tracking):

* :class:`PathLossModel` -- log-normal path loss (eq. 1), ``rss = A - 10 eta log10(d/d0) + N(0,
  sigma)``; inverted to a distance ``d = d0 10^((A - rss)/(10 eta))`` whose log is Gaussian with
  standard deviation ``sigma ln(10) / (10 eta)`` (so ``sigma_d ~ d sigma ln10/(10 eta)``).
* :func:`hyperbolic_wls` -- weighted hyperbolic least squares (eq. 2). Subtracting the circle of
  a reference anchor ``r`` from the others linearizes the problem:
  ``2 (a_i - a_r)^T (p - a_r) = |a_i - a_r|^2 - d_i^2 + d_r^2`` with the covariance of the
  right-hand side proportional to ``S = diag(d_i^4) + d_r^4 1 1^T``.
  Reading: the paper writes ``H`` and ``b`` with the first anchor at the origin; we translate the
  coordinates so that the reference anchor is the origin, and choose as reference the anchor with
  the *smallest* estimated distance (its ``d^4`` weight, the common term of ``S``, is then
  smallest). The position covariance is ``4 sigma_ln^2 (H^T S^-1 H)^-1`` (first order,
  ``var(d^2) ~ 4 d^4 sigma_ln^2``).
* :class:`TarrioFusion` -- the linear Kalman filter of eq. 5-13 with the inertial velocity as
  control input: between RSS fixes the position is dead-reckoned (eq. 13), at each fix it is
  predicted (eq. 8) with ``Q`` of eq. 6 and corrected (eq. 10-12, Joseph form, gated).
  Reading of eq. 8: ``Delta T v_k`` is the displacement over the interval; with
  ``control="mean"`` (default) ``v_k`` is the mean inertial velocity over the interval (so the
  prediction equals the dead-reckoned position of eq. 13), with ``control="last"`` it is the last
  velocity sample, literally.
* :func:`rss_update` -- the tighter variant: each RSS reading corrects the position filter
  directly by an EKF in the dB domain (``h(p) = A - 10 eta log10(|p - a|/d0)``, variance
  ``sigma^2``), or, with ``domain="range"``, as a range ``d`` with ``sigma_d`` through
  :func:`hrtls.fusion.ranges.range_update`.
* :class:`ChannelEstimator` -- online re-estimation of ``A`` and ``eta``: recursive least squares
  with exponential forgetting on ``rss = A - 10 eta log10(d/d0)`` where ``d`` is the distance from
  the current position estimate to the anchor. Each reading is weighted by
  ``sigma^2 / (sigma^2 + (10 eta / ln 10)^2 var_d / d^2)`` so that readings taken while the
  position is uncertain count less; readings nearer than ``min_distance_m`` or taken with a
  position variance above ``max_position_var_m2`` are skipped. The prior ``(A, eta)`` with its
  covariance regularizes the start; the covariance is capped at the prior to avoid wind-up when
  the geometry does not excite both parameters. The shadowing ``sigma`` is re-estimated as the
  exponentially weighted RMS of the prior residuals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.data.session import ChannelModel
from hrtls.errors import InputError
from hrtls.fusion._checks import (
    FloatArray,
    finite_scalar,
    finite_vector,
    non_decreasing_time,
    probability,
)
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    kalman_update,
    rejected,
    skipped,
    symmetrize,
)
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.state import IH, N_STATE, FilterState

LN10 = math.log(10.0)


# ------------------------------------------------------------------------------------------
# eq. 1: log-normal path loss
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class PathLossModel:
    """Log-normal path loss (Tarrio eq. 1).

    Attributes
    ----------
    a_dbm: RSS at the reference distance ``d0``, dBm (``A``).
    eta: path-loss exponent.
    sigma_db: shadowing standard deviation, dB.
    d0_m: reference distance, m.
    """

    a_dbm: float = -59.0
    eta: float = 2.0
    sigma_db: float = 4.0
    d0_m: float = 1.0

    def __post_init__(self) -> None:
        finite_scalar(self.a_dbm, where="PathLossModel.a_dbm")
        finite_scalar(self.eta, where="PathLossModel.eta", positive=True)
        finite_scalar(self.sigma_db, where="PathLossModel.sigma_db", positive=True)
        finite_scalar(self.d0_m, where="PathLossModel.d0_m", positive=True)

    @classmethod
    def from_channel(cls, channel: ChannelModel) -> PathLossModel:
        """From a session's ``channel`` block."""
        return cls(a_dbm=channel.a_dbm, eta=channel.eta, sigma_db=channel.sigma_db)

    @property
    def sigma_ln(self) -> float:
        """Standard deviation of ``ln d`` implied by the shadowing."""
        return self.sigma_db * LN10 / (10.0 * self.eta)

    def expected_rss(self, distance_m: ArrayLike) -> FloatArray:
        """Mean RSS at a distance, dBm."""
        d = np.asarray(distance_m, dtype=np.float64)
        return np.asarray(self.a_dbm - 10.0 * self.eta * np.log10(d / self.d0_m))

    def distance(self, rss_dbm: ArrayLike) -> FloatArray:
        """Distance estimate (the median of the log-normal distance), m."""
        r = np.asarray(rss_dbm, dtype=np.float64)
        return np.asarray(self.d0_m * 10.0 ** ((self.a_dbm - r) / (10.0 * self.eta)))

    def distance_sigma(self, rss_dbm: ArrayLike) -> FloatArray:
        """First-order 1-sigma of :meth:`distance`, m."""
        return np.asarray(self.distance(rss_dbm) * self.sigma_ln)


# ------------------------------------------------------------------------------------------
# eq. 2: weighted hyperbolic least squares
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class WlsFix:
    """Position from :func:`hyperbolic_wls`: ``xy`` (m), ``cov`` (2x2, m^2), reference index."""

    xy: FloatArray
    cov: FloatArray
    reference: int


def hyperbolic_wls(anchors_xy: ArrayLike, distances_m: ArrayLike, *,
                   sigma_ln: float = 0.5,
                   reference: Literal["nearest", "first"] = "nearest") -> WlsFix:
    """Weighted hyperbolic least-squares position (Tarrio eq. 2).

    Parameters
    ----------
    anchors_xy:
        Anchor positions, m (N, 2), N >= 3, not collinear.
    distances_m:
        Estimated distances, m (N,), > 0.
    sigma_ln:
        Standard deviation of ``ln d`` (scales the covariance only).
    reference:
        Anchor whose circle is subtracted: the one with the smallest distance (default) or the
        first one, as the paper writes eq. 2.
    """
    a = np.asarray(anchors_xy, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise InputError(f"shape {a.shape}", where="hyperbolic_wls anchors_xy",
                         expected="finite (N, 2) anchor positions")
    d = finite_vector(distances_m, where="hyperbolic_wls distances_m", length=a.shape[0])
    if a.shape[0] < 3:
        raise InputError(f"{a.shape[0]} anchors", where="hyperbolic_wls",
                         expected="at least 3 anchors")
    if np.any(d <= 0.0):
        raise InputError("distance <= 0", where="hyperbolic_wls distances_m",
                         expected="positive distances")
    if reference not in ("nearest", "first"):
        raise InputError(f"reference {reference!r}", where="hyperbolic_wls",
                         expected="'nearest' or 'first'")
    ref = int(np.argmin(d)) if reference == "nearest" else 0
    others = np.array([i for i in range(a.shape[0]) if i != ref])
    rel = a[others] - a[ref]
    h = 2.0 * rel                                                    # H of eq. 2
    b = np.sum(rel * rel, axis=1) - d[others] ** 2 + d[ref] ** 2     # b~ of eq. 2
    # S of eq. 2 is diag(d_i^4) + d_r^4 1 1^T: its inverse by Sherman-Morrison
    dinv = 1.0 / d[others] ** 4
    c_ref = d[ref] ** 4
    k = c_ref / (1.0 + c_ref * float(np.sum(dinv)))

    def s_inv(m: FloatArray) -> FloatArray:
        dm = dinv[:, None] * m if m.ndim == 2 else dinv * m
        return np.asarray(dm - k * np.outer(dinv, dinv @ m).reshape(dm.shape))

    info = h.T @ s_inv(h)
    det = float(info[0, 0] * info[1, 1] - info[0, 1] * info[1, 0])
    tr = float(info[0, 0] + info[1, 1])
    disc = math.sqrt(max(0.25 * tr * tr - det, 0.0))
    lam_min, lam_max = 0.5 * tr - disc, 0.5 * tr + disc
    # (det > 0: with anchors a few ulps apart the eigenvalues pass but det underflows)
    if not lam_min > 0.0 or lam_max / lam_min > 1e12 or not det > 0.0:
        raise InputError("anchors are collinear", where="hyperbolic_wls",
                         expected="anchors spanning the plane")
    inv = np.array([[info[1, 1], -info[0, 1]], [-info[1, 0], info[0, 0]]]) / det
    xy_rel = inv @ (h.T @ s_inv(b))                                  # (H^T S^-1 H)^-1 H^T S^-1 b
    cov = symmetrize(4.0 * sigma_ln**2 * inv)
    if not (np.all(np.isfinite(xy_rel)) and np.all(np.isfinite(cov))):
        raise InputError("anchors are collinear", where="hyperbolic_wls",
                         expected="anchors spanning the plane")
    return WlsFix(xy_rel + a[ref], cov, ref)


# ------------------------------------------------------------------------------------------
# scans: readings grouped per localization period
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class RssScan:
    """Readings of one localization period, averaged per anchor (dB domain)."""

    t: float
    anchor: list[str]
    anchor_xyz: FloatArray
    rss_dbm: FloatArray
    count: FloatArray
    unknown: list[str] = field(default_factory=list)


@dataclass(frozen=True, slots=True, eq=False)
class ScanTable:
    """Scans as columns (what :func:`group_scans` returns, without per-scan objects).

    Attributes
    ----------
    t: scan times, s (S,). first, count: rows of each scan in the row columns (S,).
    anchor: anchor id per row (M,). anchor_xyz: its position, m (M, 3). rss_dbm: mean RSS per
    row, dBm (M,). n_readings: readings averaged per row (M,). unknown: per scan, the anchors
    heard without a known position.
    """

    t: FloatArray
    first: NDArray[np.int64]
    count: NDArray[np.int64]
    anchor: NDArray[np.str_]
    anchor_xyz: FloatArray
    rss_dbm: FloatArray
    n_readings: FloatArray
    unknown: list[list[str]]

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def scans(self) -> list[RssScan]:
        """One :class:`RssScan` per scan."""
        out: list[RssScan] = []
        for i in range(len(self)):
            a, b = int(self.first[i]), int(self.first[i] + self.count[i])
            out.append(RssScan(float(self.t[i]), self.anchor[a:b].tolist(),
                               self.anchor_xyz[a:b].copy(), self.rss_dbm[a:b].copy(),
                               self.n_readings[a:b].copy(), list(self.unknown[i])))
        return out


def scan_table(rss: RssReadings, landmarks: dict[str, Landmark], *, window_s: float,
               sensitivity_dbm: float = -95.0, t_origin: float | None = None) -> ScanTable:
    """:func:`group_scans` vectorized: the scans as columns (same windows, order and means)."""
    w = finite_scalar(window_s, where="group_scans window_s", positive=True)
    empty = ScanTable(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                      np.zeros(0, dtype=str), np.zeros((0, 3)), np.zeros(0), np.zeros(0), [])
    if len(rss) == 0:
        return empty
    t0 = float(rss.t[0]) if t_origin is None else float(t_origin)
    keep = rss.rss_dbm >= sensitivity_dbm
    tt, ids, vals = rss.t[keep], rss.anchor[keep], rss.rss_dbm[keep]
    if tt.size == 0:
        return empty
    bins = np.floor((tt - t0) / w).astype(np.int64)
    # consecutive readings in one window form a scan; its time is that of its last reading
    grp = np.zeros(tt.size, dtype=np.int64)
    grp[1:] = np.cumsum(np.diff(bins) != 0)
    n_scans = int(grp[-1]) + 1
    last = np.flatnonzero(np.append(np.diff(grp) != 0, True))
    names, a_idx = np.unique(ids, return_inverse=True)
    key = grp * len(names) + a_idx.astype(np.int64)
    uk, inv = np.unique(key, return_inverse=True)   # by scan, then by anchor name
    sums = np.bincount(inv, weights=vals, minlength=len(uk))
    counts = np.bincount(inv, minlength=len(uk)).astype(np.float64)
    row_scan = uk // len(names)
    row_name = uk % len(names)
    xyz_of = np.full((len(names), 3), np.nan)
    known_name = np.zeros(len(names), dtype=bool)
    for j, name in enumerate(names.tolist()):
        lm = landmarks.get(str(name))
        if lm is not None and lm.position is not None:
            known_name[j] = True
            xyz_of[j] = lm.xyz()
    known = known_name[row_name]
    unknown: list[list[str]] = [[] for _ in range(n_scans)]
    for i in np.flatnonzero(~known).tolist():
        unknown[int(row_scan[i])].append(str(names[row_name[i]]))
    ks, kn = row_scan[known], row_name[known]
    first = np.searchsorted(ks, np.arange(n_scans), side="left").astype(np.int64)
    count = (np.searchsorted(ks, np.arange(n_scans), side="right") - first).astype(np.int64)
    return ScanTable(tt[last].astype(np.float64), first, count, names[kn].astype(str),
                     xyz_of[kn], sums[known] / counts[known], counts[known], unknown)


def group_scans(rss: RssReadings, landmarks: dict[str, Landmark], *, window_s: float,
                sensitivity_dbm: float = -95.0, t_origin: float | None = None) -> list[RssScan]:
    """Average the readings of each anchor over consecutive windows of ``window_s`` seconds.

    Readings below ``sensitivity_dbm`` are dropped (Tarrio Sec. IV); a scan's time is that of
    its last reading (the position can be computed then); anchors without a known position are
    listed in ``unknown``.
    """
    return scan_table(rss, landmarks, window_s=window_s, sensitivity_dbm=sensitivity_dbm,
                      t_origin=t_origin).scans()


def scan_position(scan: RssScan, model: PathLossModel) -> WlsFix:
    """Eq. 1 + eq. 2 on one scan (raises :class:`InputError` with < 3 anchors)."""
    d = model.distance(scan.rss_dbm)
    # averaging n readings in dB shrinks the shadowing spread by sqrt(n)
    sigma_ln = model.sigma_ln / math.sqrt(float(np.mean(scan.count))) if len(scan.count) \
        else model.sigma_ln
    return hyperbolic_wls(scan.anchor_xyz[:, :2], d, sigma_ln=sigma_ln)


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


def rss_update(state: FilterState, anchor_xyz: ArrayLike, rss_dbm: float,
               model: PathLossModel, *, domain: Literal["db", "range"] = "db",
               min_distance_m: float = 0.5, gate_probability: float | None = 0.999,
               use_3d: bool = False, t: float | None = None, source: str = "") -> RssUpdate:
    """EKF update of the position filter with one RSS reading.

    ``domain="db"``: ``z = rss``, ``h = A - 10 eta log10(d/d0)``,
    ``H = -10 eta / ln10 (p - a)^T / d^2``, ``R = sigma^2``. ``domain="range"``: the reading is
    converted by eq. 1 to ``d`` with ``sigma_d`` and applied by the range EKF. ``d`` is planar,
    or with ``use_3d`` the slant distance using the state's z (anchors at other heights).
    Estimates nearer than ``min_distance_m`` are rejected (no direction).
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
    dims = 3 if use_3d else 2
    delta = state.x[:dims] - a[:dims]
    dist = float(np.linalg.norm(delta))
    if dist < min_distance_m:
        return RssUpdate(state, rejected("rss", tt, "estimate on top of the anchor", source))
    pred = model.a_dbm - 10.0 * model.eta * math.log10(dist / model.d0_m)
    h = np.zeros((1, N_STATE))
    h[0, :dims] = -10.0 * model.eta / LN10 * delta / (dist * dist)
    res = kalman_update(state.x, state.P, h, np.array([[model.sigma_db**2]]),
                        np.array([z - pred]), gate_probability=gate_probability, kind="rss",
                        t=tt, source=source, angle_index=IH)
    return RssUpdate(state.evolve(x=res.x, P=res.P), res.diagnostics)


# ------------------------------------------------------------------------------------------
# online re-estimation of A and eta
# ------------------------------------------------------------------------------------------
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
        prm = self.params
        r = finite_vector(np.atleast_1d(np.asarray(rss_dbm, dtype=np.float64)),
                          where="channel rss_dbm")
        d = finite_vector(np.atleast_1d(np.asarray(distance_m, dtype=np.float64)),
                          where="channel distance_m", length=r.size)
        dv = np.broadcast_to(np.asarray(distance_var_m2, dtype=np.float64), (r.size,))
        theta = cstate.theta.copy()
        cov = cstate.cov.copy()
        res_var = cstate.residual_var_db2
        count = cstate.count
        cap = np.diag([prm.sigma_a_prior_db**2, prm.sigma_eta_prior**2])
        lam = prm.forgetting
        used = 0
        for i in range(r.size):
            if d[i] < prm.min_distance_m or dv[i] > prm.max_position_var_m2:
                continue
            phi = np.array([1.0, -10.0 * math.log10(d[i] / d0_m)])
            e = float(r[i] - phi @ theta)
            slope = 10.0 * theta[1] / LN10
            # residual variance of this reading: shadowing + position error through the slope
            s2 = res_var + slope * slope * dv[i] / (d[i] * d[i])
            pphi = cov @ phi
            # bounded pull of one reading (2.5 sigma of its predicted residual): an outlier or
            # a wrong position estimate cannot drag A and eta away
            lim = 2.5 * math.sqrt(s2 + float(phi @ pphi))
            e = min(max(e, -lim), lim)
            w = res_var / s2
            k = pphi / (lam / w + float(phi @ pphi))
            theta = theta + k * e
            cov = (cov - np.outer(k, pphi)) / lam
            cov = symmetrize(cov)
            # cap at the prior (no wind-up without excitation)
            if np.trace(cov) > np.trace(cap):
                cov = cov * (np.trace(cap) / np.trace(cov))
            # eta clipped to its bounds: move A along their correlation (conditional mean)
            eta_c = float(np.clip(theta[1], *prm.eta_bounds))
            if eta_c != theta[1]:
                theta[0] += cov[0, 1] / cov[1, 1] * (eta_c - theta[1])
                theta[1] = eta_c
            res_var = lam * res_var + (1.0 - lam) * e * e
            count += 1
            used += 1
        return ChannelState(theta, cov, max(res_var, 1e-6), count), used


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

