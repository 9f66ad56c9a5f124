"""Grid point-mass filter of the position from beacon RSS alone (no motion sensors).

Without an IMU nothing says where the walker went between two scans, and one scan of a few
beacons is a multi-modal, far from Gaussian position density. The filter holds the density on
a regular horizontal grid (cells of ``cell_m``, covering the anchors' bounding box plus
``margin_m``) and alternates, for every scan:

* **motion**: with ``velocity_time_s > 0`` the density is first shifted by ``v dt`` (bilinear
  between cells), ``v`` the walker's persistent velocity: an exponential average, time constant
  ``velocity_time_s``, of the posterior mean's displacement per second from scan to scan
  (``v += dt / (velocity_time_s + dt) ((m_k - m_{k-1}) / dt - v)``, speed at most
  ``velocity_max_m_per_s``), so that through seconds of misleading readings the track keeps
  walking; then it is convolved with a Gaussian of standard deviation
  ``sigma_speed_m_per_sqrt_s sqrt(dt)`` per axis (a walker of unknown direction; separable,
  truncated at 3 sigma; mass that leaves the grid is dropped and the rest renormalised).
  With ``mode_turn_deg > 0`` or ``stopped_mode`` the density is joint over position and a
  velocity mode ``m`` (:attr:`GridParams.n_modes` of them): mode ``m`` moves at ``v`` (or,
  with ``mode_speed_m_per_s > 0``, that speed along +x) turned by ``m mode_turn_deg`` (a
  stopped mode: not at all), each mode keeping its mass; before
  that the modes switch as a Markov chain (each left with probability
  ``1 - exp(-mode_switch_per_s dt)``, to the others alike). The update multiplies every mode
  by the same likelihood, so the modes are weighted by how well their predictions explain the
  scan, and the rows, the bias and ``v`` use the position density (the sum over modes);
* **update**: it is multiplied by the likelihood of the scan's mean RSS per anchor (or the
  power mean or median of its window: ``window_statistic``) under the
  log-distance path loss (:func:`hrtls.fusion.path_loss.mean_rss_dbm`, horizontal distance, at
  least ``d0``) with shadowing ``sigma_db`` and an outlier floor:
  ``l = (1 - e) [(1 - q) N(r; mu(d) + o_a, sigma) + q N(r; mu(d) + o_a - att, sigma)]
  + e / RSS_SPAN_DB`` (``q``: ``attenuation_probability``, ``att``: ``attenuation_db``, a body
  or obstacle in the way: it only attenuates), raised to the power ``w`` (the share of the
  averaging window that is new in this scan, so a reading that enters several
  overlapping windows counts once in all; with ``shadowing_time_s > 0`` each new reading
  counts as the share of an independent one that :mod:`hrtls.fusion.shadowing` eq. 1 gives
  it, consecutive readings of an anchor sharing their shadowing).

With ``lag_compensation`` ``g`` > 0 (and a persistent velocity), a scan's window is placed
where the walker was when its readings were taken: ``age`` s before the scan (the rows' mean
reading age, weighted as the rows are), at ``x - g v age`` for the walker now at ``x``. The
bias and burst states are updated over the predicted density shifted back by ``g v age``, and
the likelihood computed on the cells is shifted forward by it
(:func:`~hrtls.fusion.rss_grid_kernels.shift_field`): ``l_now(x) = l(x - g v age)``.

With a radio map (:mod:`hrtls.fusion.radio_map`) ``mu`` of each cell also holds the map's
mean there and ``sigma^2`` its variance.

``o_a`` is a per-anchor RSS offset (starting value: a survey, else zero). With
``offset_gain > 0`` it follows the residual at the posterior mean after each update
(``o_a += offset_gain (r - mu - o_a)``, clipped to ``offset_max_db``). With
``bias_sigma_db > 0`` it is also a Kalman state (variance ``P_a``, prior
``bias_sigma_db^2``, random walk ``bias_walk_db_per_sqrt_s``): the likelihood marginalises it
(``sigma^2 + P_a`` in place of ``sigma^2``) and, before each update, :func:`bias_update` moves
it by the residual over the predicted density, whose spread of ``mu`` enters the innovation
variance (an uncertain position moves the offset little). A bias common to the readings and
the offsets leaves the position unchanged.

With ``burst_sigma_db > 0`` each anchor has a burst state (a multi-second episode of readings
far off the law): a two-state Markov chain (``burst_enter_per_s``, ``burst_exit_per_s``,
:func:`burst_predict`) whose probability ``b_a`` the likelihood marginalises (the Gaussian
above weighted ``1 - b_a``, plus ``b_a (1 - e) N(r; mu + o_a, sqrt(sigma^2 + P_a +
burst_sigma_db^2))``) and :func:`burst_update` updates from each reading over the predicted
density.

The first scan starts from a uniform density, so the first row is what the first scan's
likelihood says (no start at an arbitrary point). Each scan gives one row: the mean and
covariance of the density (the default, ``point_estimate = "mean"``), or with ``"median"`` its
per-axis median and its spread about that point (the covariance plus the outer product of the
mean's offset from it). Forward only (causal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion._records import to_record
from hrtls.fusion.path_loss import PATH_LOSS_DTYPE, PathLossModel
from hrtls.fusion.rss_grid_kernels import (
    RSS_SPAN_DB,
    IntArray,
    apply_likelihood,
    bias_update,
    blur,
    burst_predict,
    burst_update,
    follow_velocity,
    log_likelihood,
    map_mean,
    median_row,
    mix_modes,
    moments,
    move_modes,
    shift,
    shift_field,
    window_medians,
)
from hrtls.kernels import njit

__all__ = [
    "GRID_DTYPE",
    "RSS_SPAN_DB",
    "GridGeometry",
    "GridParams",
    "GridRows",
    "GridScans",
    "GridState",
    "RssGridFilter",
    "apply_likelihood",
    "bias_update",
    "blur",
    "burst_predict",
    "burst_update",
    "causal_scans",
    "follow_velocity",
    "grid_kernel",
    "log_likelihood",
    "map_mean",
    "median_row",
    "mix_modes",
    "moments",
    "move_modes",
    "shift",
    "shift_field",
    "window_medians",
]


NO_RECORD = (np.zeros((0, 0, 0), dtype=np.float32), np.zeros((0, 3)))   # grid_kernel: none
WINDOW_STATISTICS = ("mean-db", "mean-power", "median")
"""Values of :attr:`GridParams.window_statistic`."""


@dataclass(frozen=True, kw_only=True)
class GridParams:
    """Grid filter settings.

    Attributes
    ----------
    cell_m: grid cell size, m (larger when needed to keep within ``max_cells``).
    max_cells: most cells of the grid (the cost of a scan is cells x anchors heard).
    margin_m: grid extent beyond the anchors' bounding box, m.
    sigma_speed_m_per_sqrt_s: per-axis diffusion of the motion model, m/sqrt(s).
    scan_s: scan period: readings are grouped into windows of this length, s.
    average_s: causal window of the per-anchor mean RSS at a scan, s (>= scan_s).
    outlier_probability: weight ``e`` of the uniform outlier density.
    offset_gain: gain of the causal per-anchor RSS offset (0: no offsets).
    offset_max_db: bound of the per-anchor offsets, dB.
    shadowing_time_s: correlation time of an anchor's shadowing error, s (0: independent
        readings; :mod:`hrtls.fusion.shadowing`).
    attenuation_probability: weight ``q`` of the attenuated component (a body or obstacle
        between the device and the anchor; 0: none).
    attenuation_db: mean attenuation of that component, dB.
    bias_sigma_db: prior standard deviation of each anchor's RSS bias, dB (0: no bias state).
    bias_walk_db_per_sqrt_s: random walk of the biases, dB/sqrt(s).
    velocity_time_s: time constant of the persistent-velocity estimate, s (0: no velocity,
        diffusion only).
    velocity_max_m_per_s: bound of the persistent speed, m/s.
    mode_turn_deg: angle between the velocity modes, deg: the persistent velocity turned by
        0, 1, ... ``round(360 / mode_turn_deg) - 1`` times this angle (0: one mode, today's
        filter; at most 180).
    mode_speed_m_per_s: with it (> 0) the modes turn a fixed velocity of this speed along +x
        instead of the persistent velocity (modes of fixed heading), m/s.
    stopped_mode: one more mode that does not move.
    mode_switch_per_s: rate of leaving a velocity mode (for the others alike), 1/s.
    burst_sigma_db: extra spread of an anchor's readings during a burst, dB (0: no burst
        state).
    burst_enter_per_s: rate at which an anchor enters a burst, 1/s.
    burst_exit_per_s: rate at which a burst ends, 1/s.
    window_statistic: what a row holds of an anchor's readings in its window: ``mean-db``
        (their mean in dBm), ``mean-power`` (their mean power, in dBm: a deep fade of one
        reading moves it less) or ``median``.
    point_estimate: what a row's position is: the density's ``mean`` or its per-axis
        ``median`` (then its covariance is the spread about that point); the persistent
        velocity and the offsets follow the mean either way.
    lag_compensation: share ``g`` (0 ... 1) of the window's mean reading age by which its
        readings are placed behind the walker along the persistent velocity (0: at the
        walker's position at the scan; needs ``velocity_time_s`` > 0 to act).
    smoother_lag_s: delay of the fixed-lag smoother's rows, s (0: off; one velocity mode).
    """

    cell_m: float = 0.25
    max_cells: int = 40_000
    margin_m: float = 2.0
    sigma_speed_m_per_sqrt_s: float = 1.5
    scan_s: float = 0.5
    average_s: float = 2.0
    outlier_probability: float = 0.05
    offset_gain: float = 0.0
    offset_max_db: float = 10.0
    shadowing_time_s: float = 0.0
    attenuation_probability: float = 0.0
    attenuation_db: float = 8.0
    bias_sigma_db: float = 3.0
    bias_walk_db_per_sqrt_s: float = 0.0
    velocity_time_s: float = 8.0
    velocity_max_m_per_s: float = 1.5
    mode_turn_deg: float = 0.0
    mode_speed_m_per_s: float = 0.0
    stopped_mode: bool = False
    mode_switch_per_s: float = 0.5
    burst_sigma_db: float = 0.0
    burst_enter_per_s: float = 0.05
    burst_exit_per_s: float = 0.3
    window_statistic: Literal["mean-db", "mean-power", "median"] = "mean-db"
    point_estimate: Literal["mean", "median"] = "mean"
    lag_compensation: float = 0.0
    smoother_lag_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("cell_m", "scan_s", "average_s", "max_cells"):
            finite_scalar(getattr(self, name), where=f"GridParams.{name}", positive=True)
        for name in ("margin_m", "sigma_speed_m_per_sqrt_s", "offset_gain", "offset_max_db",
                     "outlier_probability", "shadowing_time_s", "attenuation_probability",
                     "attenuation_db", "bias_sigma_db", "bias_walk_db_per_sqrt_s",
                     "velocity_time_s", "velocity_max_m_per_s", "mode_turn_deg", "smoother_lag_s",
                     "mode_speed_m_per_s", "mode_switch_per_s", "burst_sigma_db",
                     "burst_enter_per_s", "burst_exit_per_s", "lag_compensation"):
            finite_scalar(getattr(self, name), where=f"GridParams.{name}", non_negative=True)
        if self.window_statistic not in WINDOW_STATISTICS:
            raise InputError(f"window_statistic = {self.window_statistic!r}",
                             where="GridParams.window_statistic",
                             expected=" or ".join(WINDOW_STATISTICS))
        if self.point_estimate not in ("mean", "median"):
            raise InputError(f"point_estimate = {self.point_estimate!r}",
                             where="GridParams.point_estimate", expected="mean or median")
        if self.average_s < self.scan_s:
            raise InputError(f"average_s = {self.average_s} s < scan_s = {self.scan_s} s",
                             where="GridParams.average_s", expected="at least scan_s")
        if self.mode_turn_deg > 180.0 or (self.mode_speed_m_per_s > 0.0
                                           and self.mode_turn_deg == 0.0):
            raise InputError(f"mode_turn_deg = {self.mode_turn_deg}, mode_speed_m_per_s = "
                             f"{self.mode_speed_m_per_s}", where="GridParams",
                             expected="mode_turn_deg at most 180 deg, and above 0 with a "
                                      "mode speed")
        if self.lag_compensation > 1.0:
            raise InputError(f"lag_compensation = {self.lag_compensation}",
                             where="GridParams.lag_compensation", expected="0 ... 1")
        if not (self.outlier_probability < 1.0 and self.offset_gain <= 1.0
                and self.attenuation_probability < 1.0):
            raise InputError(f"outlier_probability = {self.outlier_probability}, offset_gain = "
                             f"{self.offset_gain}, attenuation_probability = "
                             f"{self.attenuation_probability}", where="GridParams",
                             expected="outlier_probability < 1, offset_gain <= 1 and "
                                      "attenuation_probability < 1")

    def record(self) -> np.ndarray:
        """The settings as a one-element :data:`GRID_DTYPE` array."""
        return to_record(GRID_DTYPE, self,
                         median_point=float(self.point_estimate == "median"))

    @property
    def n_modes(self) -> int:
        """Number of velocity modes: the turned velocities, plus one if ``stopped_mode``."""
        turns = max(round(360.0 / self.mode_turn_deg), 1) if self.mode_turn_deg > 0.0 else 1
        return turns + int(self.stopped_mode)

    @property
    def burst_start(self) -> float:
        """Burst probability of an anchor before its first reading (the chain's stationary)."""
        rate = self.burst_enter_per_s + self.burst_exit_per_s
        return self.burst_enter_per_s / rate if self.burst_sigma_db > 0.0 and rate > 0.0 \
            else 0.0


GRID_DTYPE = np.dtype([(n, np.float64) for n in (
    "cell_m", "max_cells", "margin_m", "sigma_speed_m_per_sqrt_s", "scan_s", "average_s",
    "outlier_probability", "offset_gain", "offset_max_db", "attenuation_probability",
    "attenuation_db", "bias_sigma_db", "bias_walk_db_per_sqrt_s", "velocity_time_s",
    "velocity_max_m_per_s", "mode_turn_deg", "mode_speed_m_per_s", "stopped_mode",
    "mode_switch_per_s", "burst_sigma_db", "burst_enter_per_s", "burst_exit_per_s",
    "median_point", "lag_compensation")])
"""Record of :class:`GridParams` for compiled code (same field names; ``median_point`` is 1
for ``point_estimate = "median"``, else 0)."""


@dataclass(frozen=True, slots=True, eq=False)
class GridGeometry:
    """The cells: centre of cell (0, 0) at ``(x0_m, y0_m)``; ``ny`` rows (y), ``nx`` columns."""

    x0_m: float
    y0_m: float
    cell_m: float
    nx: int
    ny: int

    @classmethod
    def around(cls, anchors_xy: FloatArray, *, cell_m: float, margin_m: float,
               max_cells: int) -> GridGeometry:
        """The anchors' bounding box plus ``margin_m`` on every side, at most ``max_cells``."""
        a = np.asarray(anchors_xy, dtype=np.float64).reshape(-1, 2)
        if len(a) == 0 or not np.all(np.isfinite(a)):
            raise InputError(f"{len(a)} anchors", where="rss grid",
                             expected="at least one anchor with a finite position")
        lo, hi = a.min(axis=0) - margin_m, a.max(axis=0) + margin_m
        span = np.maximum(hi - lo, 1e-9)
        cell_m = max(cell_m, float(np.sqrt(np.prod(span) / max_cells)))
        while np.prod(np.ceil(span / cell_m) + 1) > max_cells:
            cell_m *= 1.05
        n = np.maximum(np.ceil((hi - lo) / cell_m).astype(np.int64), 1) + 1
        return cls(float(lo[0]), float(lo[1]), float(cell_m), int(n[0]), int(n[1]))

    def centres(self) -> tuple[FloatArray, FloatArray]:
        """Cell centre coordinates: x (nx,), y (ny,), m."""
        return (self.x0_m + self.cell_m * np.arange(self.nx, dtype=np.float64),
                self.y0_m + self.cell_m * np.arange(self.ny, dtype=np.float64))

    def distances(self, anchors_xy: FloatArray, d0_m: float) -> FloatArray:
        """Horizontal distance of every cell to every anchor, at least ``d0_m``: (A, ny, nx)."""
        x, y = self.centres()
        a = np.asarray(anchors_xy, dtype=np.float64).reshape(-1, 2)
        d = np.hypot(x[None, None, :] - a[:, 0, None, None], y[None, :, None] - a[:, 1, None, None])
        return np.ascontiguousarray(np.maximum(d, d0_m))


@dataclass(slots=True, eq=False)
class GridState:
    """Density, time, offsets and velocity.

    ``density``: the joint density of the velocity mode and the position (K, ny, nx; sums to
    1); a (ny, nx) density (one mode; older snapshots) is also read, shared equally among the
    modes (:meth:`modes`). ``offsets_var_db2``: variance of each anchor's offset (the bias
    state; zero without it);
    ``velocity_m_per_s``: the persistent velocity (x, y), m/s (zero without it);
    ``burst_probability``: each anchor's probability of a burst (None: the chain's stationary
    value, :attr:`GridParams.burst_start`).
    """

    t: float
    density: FloatArray
    offsets_db: FloatArray
    started: bool = False
    offsets_var_db2: FloatArray | None = None
    velocity_m_per_s: FloatArray | None = None
    burst_probability: FloatArray | None = None

    def __post_init__(self) -> None:
        if self.offsets_var_db2 is None:
            self.offsets_var_db2 = np.zeros(len(self.offsets_db))
        if self.velocity_m_per_s is None:
            self.velocity_m_per_s = np.zeros(2)

    @classmethod
    def empty(cls, geometry: GridGeometry, n_anchors: int, n_modes: int = 1) -> GridState:
        """Before the first scan (uniform prior)."""
        d = np.full((n_modes, geometry.ny, geometry.nx),
                    1.0 / (n_modes * geometry.nx * geometry.ny))
        return cls(-math.inf, d, np.zeros(n_anchors))

    def modes(self, n_modes: int) -> FloatArray:
        """A copy of the density as ``n_modes`` modes (K, ny, nx).

        A density with another number of modes (or none: (ny, nx)) gives its position density
        shared equally among the ``n_modes``.
        """
        d = np.asarray(self.density, dtype=np.float64)
        if d.ndim == 3 and d.shape[0] == n_modes:
            return d.copy()
        pos = d.sum(axis=0) if d.ndim == 3 else d
        return np.repeat(pos[None, :, :] / n_modes, n_modes, axis=0)


@dataclass(frozen=True, slots=True, eq=False)
class GridRows:
    """One row per scan: time, point estimate and the position's covariance about it.

    ``t`` (S,); ``mean_xy`` (S, 2): the mean or the median (:attr:`GridParams.point_estimate`);
    ``cov_xy`` (S, 2, 2).
    """

    t: FloatArray
    mean_xy: FloatArray
    cov_xy: FloatArray


@dataclass(frozen=True, slots=True, eq=False)
class GridScans:
    """Scans as rows: scan ``k`` holds rows ``first[k] : first[k] + count[k]``.

    ``anchor`` indexes the anchors of the geometry's distance table; ``rss_dbm`` is the causal
    mean over ``average_s``; ``weight`` the likelihood exponent of each row; ``age_s`` (S,)
    each scan's mean reading age (None: zero), s.
    """

    t: FloatArray
    first: IntArray
    count: IntArray
    anchor: IntArray
    rss_dbm: FloatArray
    weight: FloatArray
    age_s: FloatArray | None = None


@njit(cache=True, error_model="numpy")
def grid_kernel(prm: np.record, model: np.record, x0: float, y0: float, dist: FloatArray,
                rmap: FloatArray, rvar: FloatArray, density: FloatArray,
                offsets_db: FloatArray, offsets_var: FloatArray,
                velocity: FloatArray, burst: FloatArray, t_prev: float, started: bool,
                t: FloatArray, first: IntArray, count: IntArray, anchor: IntArray,
                rss_dbm: FloatArray, weight: FloatArray, age: FloatArray,
                out: FloatArray, kept: FloatArray, moved: FloatArray) -> float:
    # pragma: no cover - compiled
    """Run the scans through the filter; density (K, ny, nx) and the other states in place.

    ``out`` (S, 5): mean x, y and covariance xx, xy, yy per scan; ``age`` (S,): each scan's
    mean reading age, s. Returns the last scan time. ``kept`` (S, ny, nx; (0, 0, 0): none),
    ``moved`` (S, 3): each scan's position density after its update, its prediction's v and dt.
    ``rmap``, ``rvar``: the radio map's mean and variance (A, ny, nx; (0, 0, 0): no map).
    """
    ny, nx = density.shape[1], density.shape[2]
    cell = prm.cell_m
    tmp = np.empty((ny, nx))
    ll = np.empty((ny, nx))
    pos = np.empty((ny, nx))        # the position density (sum over the modes)
    seen = np.empty((ny, nx))       # where the window's readings were taken
    prev = np.zeros(5)              # moments of the previous scan's posterior
    moving = prm.velocity_time_s > 0.0
    base = np.zeros(2)              # what the modes turn when not the persistent velocity
    base[0] = prm.mode_speed_m_per_s
    fixed = prm.mode_speed_m_per_s > 0.0
    turn = math.radians(prm.mode_turn_deg)
    if started and moving:
        pos[:] = density.sum(axis=0)
        moments(pos, x0, y0, cell, prev)
    for k in range(t.shape[0]):
        dt = 0.0
        if started:
            dt = max(t[k] - t_prev, 0.0)
            mix_modes(density, 1.0 - math.exp(-prm.mode_switch_per_s * dt))
            if prm.burst_sigma_db > 0.0:
                burst_predict(burst, dt, prm.burst_enter_per_s, prm.burst_exit_per_s)
            spread = prm.sigma_speed_m_per_sqrt_s * math.sqrt(dt) / cell
            v = velocity if moving and not fixed else base
            if kept.shape[0] > 0:
                moved[k, 0], moved[k, 1], moved[k, 2] = v[0], v[1], dt
            move_modes(density, v, turn, prm.stopped_mode > 0.0, dt, cell, spread, tmp)
        a, b = first[k], first[k] + count[k]
        pos[:] = density.sum(axis=0)
        seen[:] = pos
        # readings taken lag s ago, at x - v lag (module docstring)
        lag = prm.lag_compensation * age[k] / cell if moving and started else 0.0
        shift(seen, -velocity[0] * lag, -velocity[1] * lag, tmp)
        if prm.bias_sigma_db > 0.0:
            offsets_var += prm.bias_walk_db_per_sqrt_s ** 2 * dt
            bias_update(dist, rmap, rvar, seen, anchor[a:b], rss_dbm[a:b], weight[a:b],
                        offsets_db, offsets_var, model)
        log_likelihood(dist, rmap, rvar,
                       anchor[a:b], rss_dbm[a:b], weight[a:b], offsets_db, offsets_var,
                       burst, model, prm, ll)
        shift_field(ll, velocity[0] * lag, velocity[1] * lag, tmp)
        if prm.burst_sigma_db > 0.0:
            burst_update(dist, rmap, rvar, seen, anchor[a:b], rss_dbm[a:b], weight[a:b],
                         offsets_db, offsets_var, burst, model, prm)
        apply_likelihood(density, ll, pos)
        if kept.shape[0] > 0:
            kept[k] = pos
        moments(pos, x0, y0, cell, out[k])
        if moving and started:
            follow_velocity(velocity, prev[:2], out[k, :2], dt, prm.velocity_time_s,
                            prm.velocity_max_m_per_s)
        prev[:] = out[k]
        if prm.offset_gain > 0.0:
            ci = min(max(round((out[k, 1] - y0) / cell), 0), ny - 1)
            cj = min(max(round((out[k, 0] - x0) / cell), 0), nx - 1)
            for r in range(a, b):
                an = anchor[r]
                mu = map_mean(dist, rmap, an, ci, cj, model)
                o = offsets_db[an] + prm.offset_gain * (rss_dbm[r] - mu - offsets_db[an])
                offsets_db[an] = min(max(o, -prm.offset_max_db), prm.offset_max_db)
        if prm.median_point > 0.0:
            median_row(pos, x0, y0, cell, out[k])
        t_prev = t[k]
        started = True
    return t_prev


def causal_scans(t: FloatArray, anchor: IntArray, rss_dbm: FloatArray, *, n_anchors: int,
                 scan_s: float, average_s: float, t_origin: float,
                 t_from: float = -math.inf, info: FloatArray | None = None,
                 statistic: str = "mean-db") -> GridScans:
    """Scans of the readings ``t`` (s), ``anchor`` (index) and ``rss_dbm`` after ``t_from``.

    A scan ends each ``scan_s`` window with readings (at its last reading); its rows: per
    anchor heard in ``(t_scan - average_s, t_scan]``, the ``statistic`` of its readings
    (:attr:`GridParams.window_statistic`; the mean power is ``10 log10`` of the mean of
    ``10^(r / 10)``). ``t`` sorted; bins start
    at ``t_origin``. Weight of a row: the readings that are new in this scan (not in the
    previous scan's window of that anchor), each counted as ``info`` (its information
    fraction, default 1), over the readings averaged. Age of a scan: the mean over its rows
    of ``t_scan`` minus the mean time of the row's readings, weighted as the rows.
    """
    tt = np.asarray(t, dtype=np.float64)
    w_in = np.ones(tt.size) if info is None else np.asarray(info, dtype=np.float64)
    if tt.size == 0:
        z = np.zeros(0)
        zi = np.zeros(0, dtype=np.int64)
        return GridScans(z, zi, zi, zi, z, z, z)
    bins = np.floor((tt - t_origin) / scan_s).astype(np.int64)
    last = np.flatnonzero(np.append(np.diff(bins) != 0, True))
    ts = tt[last]
    ts = ts[ts > t_from]
    s = len(ts)
    means = np.full((s, n_anchors), np.nan)
    weights = np.zeros((s, n_anchors))
    ages = np.zeros((s, n_anchors))
    for a in range(n_anchors):
        sel = anchor == a
        ta, ra = tt[sel], np.asarray(rss_dbm, dtype=np.float64)[sel]
        cs = np.concatenate([[0.0], np.cumsum(10.0 ** (ra / 10.0) if statistic == "mean-power"
                                              else ra)])
        cw = np.concatenate([[0.0], np.cumsum(w_in[sel])])
        ct = np.concatenate([[0.0], np.cumsum(ta - t_origin)])
        hi = np.searchsorted(ta, ts, side="right")
        lo = np.searchsorted(ta, ts - average_s, side="right")
        n = hi - lo
        ok = n > 0
        means[ok, a] = (cs[hi[ok]] - cs[lo[ok]]) / n[ok]
        if statistic == "mean-power":
            means[ok, a] = 10.0 * np.log10(means[ok, a])
        elif statistic == "median":
            means[ok, a] = window_medians(ra, lo[ok], hi[ok])
        prev_hi = np.concatenate([[np.searchsorted(ta, t_from, side="right")], hi[:-1]])
        weights[ok, a] = (cw[hi[ok]] - cw[np.maximum(prev_hi[ok], lo[ok])]) / n[ok]
        ages[ok, a] = ts[ok] - t_origin - (ct[hi[ok]] - ct[lo[ok]]) / n[ok]
    heard = np.isfinite(means)
    count = heard.sum(axis=1).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    rows, cols = np.nonzero(heard)
    del rows
    wsum = weights.sum(axis=1)
    age = np.where(wsum > 0.0, (weights * ages).sum(axis=1) / np.maximum(wsum, 1e-300), 0.0)
    return GridScans(ts, first, count, cols.astype(np.int64), means[heard], weights[heard], age)


class RssGridFilter:
    """The grid filter over a fixed set of anchors (state in :class:`GridState`)."""

    def __init__(self, anchors_xy: FloatArray, *, model: PathLossModel,
                 params: GridParams | None = None,
                 radio_map: tuple[FloatArray, FloatArray] | None = None) -> None:
        """The filter; ``radio_map``: mean and variance of each anchor's RSS over the law.

        (A, ny, nx) each on :attr:`geometry`'s cells, dB and dB^2 (:mod:`hrtls.fusion.radio_map`;
        None: no map).
        """
        self.params = params or GridParams()
        self.model = model
        self.anchors_xy = np.asarray(anchors_xy, dtype=np.float64).reshape(-1, 2)
        self.geometry = GridGeometry.around(self.anchors_xy, cell_m=self.params.cell_m,
                                            margin_m=self.params.margin_m,
                                            max_cells=self.params.max_cells)
        self.dist = self.geometry.distances(self.anchors_xy, model.d0_m)
        self.rmap = self.rvar = np.zeros((0, 0, 0))
        if radio_map is not None:
            self.rmap, self.rvar = (np.ascontiguousarray(m, dtype=np.float64)
                                    for m in radio_map)
            if self.rmap.shape != self.dist.shape or self.rvar.shape != self.dist.shape:
                raise InputError(f"radio map of shape {self.rmap.shape} / {self.rvar.shape}",
                                 where="RssGridFilter", expected=f"{self.dist.shape}")
        self._prm = self.params.record()[0]
        self._model = np.zeros(1, dtype=PATH_LOSS_DTYPE)
        self._model[0] = model.record()[0]

    def start(self, offsets_db: FloatArray | None = None) -> GridState:
        """The state before the first scan; ``offsets_db``: starting per-anchor offsets, dB."""
        state = GridState.empty(self.geometry, len(self.anchors_xy), self.params.n_modes)
        if offsets_db is not None:
            state.offsets_db[:] = np.clip(np.asarray(offsets_db, dtype=np.float64),
                                          -self.params.offset_max_db, self.params.offset_max_db)
        state.offsets_var_db2 = np.full(len(self.anchors_xy), self.params.bias_sigma_db ** 2)
        state.burst_probability = np.full(len(self.anchors_xy), self.params.burst_start)
        return state

    def update(self, state: GridState, scans: GridScans, *,
               record: tuple[np.ndarray, FloatArray] = NO_RECORD) -> tuple[GridRows, GridState]:
        """Rows of ``scans`` after ``state.t``; the new state; ``record`` filled (not ``state``)."""
        s = len(scans.t)
        out = np.zeros((s, 5))
        density = state.modes(self.params.n_modes)
        offsets = state.offsets_db.copy()
        var = np.asarray(state.offsets_var_db2, dtype=np.float64).copy()
        vel = np.asarray(state.velocity_m_per_s, dtype=np.float64).copy()
        burst = np.full(len(offsets), self.params.burst_start) if state.burst_probability \
            is None else np.asarray(state.burst_probability, dtype=np.float64).copy()
        g = self.geometry
        t_last = state.t
        if s:
            t_last = grid_kernel(self._prm, self._model[0], g.x0_m, g.y0_m, self.dist,
                                 self.rmap, self.rvar, density, offsets, var, vel, burst,
                                 state.t, state.started, scans.t, scans.first, scans.count,
                                 scans.anchor, scans.rss_dbm, scans.weight,
                                 np.zeros(s) if scans.age_s is None else scans.age_s, out,
                                 *record)
        cov = np.stack([out[:, 2], out[:, 3], out[:, 3], out[:, 4]], axis=1).reshape(s, 2, 2)
        rows = GridRows(scans.t.copy(), out[:, :2].copy(), cov)
        return rows, GridState(float(t_last), density, offsets, state.started or s > 0, var,
                               vel, burst)
