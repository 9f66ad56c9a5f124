"""Accuracy metrics of an estimated trajectory against ground truth, as the papers scored.

This module is the only scorer: every job, benchmark and CLI that reports an error computes it
here. Every truth sample and every checkpoint is scored. Where the estimate does not span a truth
time (it starts late or stops early) its first / last position is held there
(:func:`estimate_at`), so a track that ends early is charged for standing still, never
flattered by dropping the truth it did not reach.

* position error against continuous truth (estimate interpolated at truth times) and at
  checkpoints (how Inderst Sec. 6.3 and Basso Sec. IV-A measured): mean, RMSE, median,
  75th / 90th / 95th percentile, maximum, and the empirical CDF (Tarrio Fig. 1);
* error as a percentage of the distance travelled;
* Basso's integral mean error: the error integrated over the distance travelled and divided by
  the path length, then normalized by the path length (Table I "mean position error");
* step count and step length errors (matched steps), heading error, velocity RMSE
  (Colombo Fig. 7), and the activity confusion matrix (Inderst Sec. 6.2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data import Activity, Checkpoints, GroundTruth, StepEvents, Trajectory
from hrtls.errors import InputError
from hrtls.frames import wrap_angle

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class ErrorStats:
    """Summary of non-negative errors (m, or rad for headings)."""

    n: int
    mean: float
    rmse: float
    median: float
    p75: float
    p90: float
    p95: float
    max: float

    def to_dict(self) -> dict[str, float | int]:
        """JSON-able form (NaN when there were no errors)."""
        return asdict(self)


def error_stats(errors: ArrayLike) -> ErrorStats:
    """Mean, RMSE, median, 75/90/95th percentiles (linear interpolation) and maximum."""
    e = np.asarray(errors, dtype=np.float64).ravel()
    if e.size and not np.all(np.isfinite(e)):
        raise InputError("non-finite error", where="errors", expected="finite numbers")
    if e.size == 0:
        nan = float("nan")
        return ErrorStats(0, nan, nan, nan, nan, nan, nan, nan)
    p = np.percentile(e, [50, 75, 90, 95])
    return ErrorStats(n=int(e.size), mean=float(np.mean(e)), rmse=float(np.sqrt(np.mean(e * e))),
                      median=float(p[0]), p75=float(p[1]), p90=float(p[2]), p95=float(p[3]),
                      max=float(np.max(e)))


def error_cdf(errors: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Empirical CDF: sorted errors and the fraction ``(i + 1) / n`` at or below each."""
    e = np.sort(np.asarray(errors, dtype=np.float64).ravel())
    return e, np.arange(1, e.size + 1, dtype=np.float64) / max(e.size, 1)


def estimate_at(estimate: Trajectory, t: ArrayLike) -> FloatArray:
    """Positions (M, 3) of the estimate at ``t``: linear in between, ends held outside its span."""
    if len(estimate) == 0:
        raise InputError("empty trajectory", where="estimate", expected="at least one sample")
    return estimate.position_at(np.asarray(t, dtype=np.float64))


def position_errors(estimate: Trajectory, truth: GroundTruth, *, horizontal: bool = True
                    ) -> tuple[FloatArray, FloatArray]:
    """Times and Euclidean errors of the estimate at every truth sample (ends held)."""
    d = estimate_at(estimate, truth.t) - truth.xyz
    if horizontal:
        d = d[:, :2]
    return truth.t, np.sqrt(np.sum(d * d, axis=1))


def position_errors_2d_3d(estimate: Trajectory, truth: GroundTruth
                          ) -> tuple[FloatArray, FloatArray]:
    """Horizontal and 3-D errors at every truth sample (ends held), the estimate placed once."""
    d = estimate_at(estimate, truth.t) - truth.xyz
    sq = d * d
    horizontal = sq[:, 0] + sq[:, 1]  # summed in the order np.sum(axis=1) adds them
    return np.sqrt(horizontal), np.sqrt(horizontal + sq[:, 2])


def axis_errors(estimate: Trajectory, truth: GroundTruth) -> FloatArray:
    """Absolute east / north errors (N, 2) at every truth sample (ends held)."""
    return np.asarray(np.abs(estimate_at(estimate, truth.t)[:, :2] - truth.xyz[:, :2]),
                      dtype=np.float64)


def checkpoint_errors(estimate: Trajectory, checkpoints: Checkpoints, *,
                      horizontal: bool = True) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """Times, errors and labels at every checkpoint (Inderst eq. 6.1; ends held)."""
    d = estimate_at(estimate, checkpoints.t) - checkpoints.xyz
    if horizontal:
        d = d[:, :2]
    return checkpoints.t, np.sqrt(np.sum(d * d, axis=1)), checkpoints.label


def cumulative_distance(xyz: ArrayLike) -> FloatArray:
    """Horizontal distance travelled up to each sample, m (starts at 0)."""
    p = np.asarray(xyz, dtype=np.float64)
    if len(p) == 0:
        return np.zeros(0)
    step = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    return np.concatenate([[0.0], np.cumsum(step)])


def distance_at(truth: GroundTruth, t: ArrayLike) -> FloatArray:
    """Horizontal distance travelled along the truth at times ``t``, m."""
    return np.interp(np.asarray(t, dtype=np.float64), truth.t, cumulative_distance(truth.xyz))


def integral_mean_error(distance_m: ArrayLike, errors_m: ArrayLike, total_length_m: float
                        ) -> tuple[float, float]:
    """Basso's integral mean error (Sec. IV-A, Table I).

    The errors at way-points (distance travelled ``distance_m``) are integrated over the
    distance by the trapezoidal rule and divided by ``total_length_m`` -- the mean error along
    the path, m -- and that mean is then normalized by the path length (fraction, 0.01 = 1 %).
    Pass the start (distance 0, error 0) when the initial position is known.
    """
    s = np.asarray(distance_m, dtype=np.float64)
    e = np.asarray(errors_m, dtype=np.float64)
    if s.shape != e.shape or s.ndim != 1 or len(s) < 2:
        raise InputError(f"shapes {s.shape} and {e.shape}", where="integral_mean_error",
                         expected="two 1-D arrays of equal length >= 2")
    if np.any(np.diff(s) < 0) or not total_length_m > 0:
        raise InputError("distances not increasing or non-positive length",
                         where="integral_mean_error",
                         expected="non-decreasing distances and a positive total length")
    integral = float(np.sum(0.5 * (e[1:] + e[:-1]) * np.diff(s)))
    mean = integral / total_length_m
    return mean, mean / total_length_m


@dataclass(frozen=True, slots=True)
class StepComparison:
    """Estimated steps against true steps.

    Attributes
    ----------
    n_true, n_estimated: step counts. count_error: ``n_estimated - n_true``.
    count_error_fraction: ``count_error / n_true``.
    length_true_m, length_estimated_m: summed step lengths, m.
    length_error_fraction: ``(estimated - true) / true`` of the summed lengths.
    n_matched: steps paired 1:1 by end time within the tolerance.
    step_length_mae_m, step_length_rmse_m, step_length_bias_m: of matched pairs, m.
    """

    n_true: int
    n_estimated: int
    count_error: int
    count_error_fraction: float
    length_true_m: float
    length_estimated_m: float
    length_error_fraction: float
    n_matched: int
    step_length_mae_m: float
    step_length_rmse_m: float
    step_length_bias_m: float

    def to_dict(self) -> dict[str, float | int]:
        """JSON-able form."""
        return asdict(self)


def match_events(t_est: ArrayLike, t_true: ArrayLike, *, tolerance_s: float
                 ) -> tuple[IntArray, IntArray]:
    """Pair events 1:1, closest first, when their times differ by at most ``tolerance_s``."""
    a = np.asarray(t_est, dtype=np.float64)
    b = np.asarray(t_true, dtype=np.float64)
    if a.size == 0 or b.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    j = np.clip(np.searchsorted(b, a), 1, b.size - 1) if b.size > 1 else np.zeros(a.size, int)
    cand_i, cand_j = [], []
    for jj in (j - 1, j) if b.size > 1 else (j,):
        cand_i.append(np.arange(a.size))
        cand_j.append(jj)
    ii = np.concatenate(cand_i)
    jj_all = np.concatenate(cand_j)
    dt = np.abs(a[ii] - b[jj_all])
    ok = dt <= tolerance_s
    ii, jj_all, dt = ii[ok], jj_all[ok], dt[ok]
    order = np.argsort(dt, kind="stable")
    used_a = np.zeros(a.size, bool)
    used_b = np.zeros(b.size, bool)
    out_a, out_b = [], []
    for k in order:  # at most 2 candidates per estimated step
        if not used_a[ii[k]] and not used_b[jj_all[k]]:
            used_a[ii[k]] = True
            used_b[jj_all[k]] = True
            out_a.append(ii[k])
            out_b.append(jj_all[k])
    ia = np.asarray(out_a, dtype=np.int64)
    ib = np.asarray(out_b, dtype=np.int64)
    srt = np.argsort(ia)
    return ia[srt], ib[srt]


def compare_steps(estimated: StepEvents, true: StepEvents, *, tolerance_s: float = 0.35
                  ) -> StepComparison:
    """Count and length errors of estimated steps, matching step ends within ``tolerance_s``."""
    n_t, n_e = len(true), len(estimated)
    lt, le = true.distance_m, estimated.distance_m
    ia, ib = match_events(estimated.t_end, true.t_end, tolerance_s=tolerance_s)
    diff = estimated.length_m[ia] - true.length_m[ib]
    nan = float("nan")
    return StepComparison(
        n_true=n_t, n_estimated=n_e, count_error=n_e - n_t,
        count_error_fraction=(n_e - n_t) / n_t if n_t else nan,
        length_true_m=lt, length_estimated_m=le,
        length_error_fraction=(le - lt) / lt if lt > 0 else nan, n_matched=int(ia.size),
        step_length_mae_m=float(np.mean(np.abs(diff))) if diff.size else nan,
        step_length_rmse_m=float(np.sqrt(np.mean(diff * diff))) if diff.size else nan,
        step_length_bias_m=float(np.mean(diff)) if diff.size else nan,
    )


def heading_errors(estimate: Trajectory, truth: GroundTruth) -> tuple[FloatArray, FloatArray]:
    """Times and absolute wrapped heading errors (rad) at every truth sample (ends held)."""
    if truth.heading_rad is None:
        raise InputError("truth has no heading", where="truth", expected="a heading column")
    if len(estimate) == 0:
        raise InputError("empty trajectory", where="estimate", expected="at least one sample")
    h = estimate.heading_rad
    ok = np.isfinite(h)
    if ok.sum() < 2:
        return np.zeros(0), np.zeros(0)
    unwrapped = np.unwrap(h[ok])
    est = np.interp(truth.t, estimate.t[ok], unwrapped)
    return truth.t, np.abs(wrap_angle(est - truth.heading_rad))


def heading_change_rad(steps: StepEvents, *, end_fraction: float = 0.2) -> float:
    """Heading change over a walk from its step headings, rad (CCW positive, ENU).

    The mean unwrapped heading of the last ``end_fraction`` of the steps with a heading minus
    that of the first (at least two steps at each end); needs four such steps.
    """
    h = np.asarray(steps.heading_rad, dtype=np.float64)
    h = np.unwrap(h[np.isfinite(h)])
    if len(h) < 4 or not 0.0 < end_fraction <= 0.5:
        raise InputError(f"{len(h)} step headings, end_fraction {end_fraction}",
                         where="heading_change_rad",
                         expected="at least 4 step headings and 0 < end_fraction <= 0.5")
    k = max(2, int(len(h) * end_fraction))
    return float(np.mean(h[-k:]) - np.mean(h[:k]))


def _smoothed_velocities(estimate: Trajectory, truth: GroundTruth, rate_hz: float,
                         window_s: float) -> tuple[FloatArray, FloatArray] | None:
    """Horizontal velocities (M, 2) of estimate and truth on a common grid over the truth span.

    Both tracks are resampled at ``rate_hz`` (the estimate's ends held), smoothed by a
    ``window_s`` moving average and differentiated by central differences (Colombo computed
    the true velocity from camera positions by backward differences). None when too short.
    """
    if len(estimate) == 0:
        raise InputError("empty trajectory", where="estimate", expected="at least one sample")
    t0, t1 = truth.t[0], truth.t[-1]
    n = max(1, round(window_s * rate_hz))
    t = np.arange(t0, t1, 1.0 / rate_hz)
    if t1 - t0 < 3.0 / rate_hz or len(t) < n + 2:
        return None
    kernel = np.ones(n) / n
    tm = np.convolve(t, kernel, mode="valid")  # no padding: ends are dropped, not distorted

    def vel(xy: FloatArray) -> FloatArray:
        sm = np.column_stack([np.convolve(c, kernel, mode="valid") for c in xy.T])
        return np.asarray(np.gradient(sm, tm, axis=0), dtype=np.float64)

    return vel(estimate_at(estimate, t)[:, :2]), vel(truth.position_at(t)[:, :2])


def velocity_rmse(estimate: Trajectory, truth: GroundTruth, *, rate_hz: float = 10.0,
                  window_s: float = 1.0) -> tuple[float, float]:
    """RMSE of the horizontal velocity vector and of the speed over the truth span, m/s."""
    v = _smoothed_velocities(estimate, truth, rate_hz, window_s)
    if v is None:
        return float("nan"), float("nan")
    ve, vt = v
    dv = ve - vt
    ds = np.linalg.norm(ve, axis=1) - np.linalg.norm(vt, axis=1)
    return float(np.sqrt(np.mean(np.sum(dv * dv, axis=1)))), float(np.sqrt(np.mean(ds * ds)))


def moving_speed_rmse(estimate: Trajectory, truth: GroundTruth, *, moving_m_s: float,
                      rate_hz: float = 10.0, window_s: float = 1.0) -> float:
    """Speed RMSE (m/s) where the smoothed true speed exceeds ``moving_m_s`` (Colombo Fig. 7).

    NaN when the truth never moves that fast.
    """
    v = _smoothed_velocities(estimate, truth, rate_hz, window_s)
    if v is None:
        return float("nan")
    s_est, s_true = (np.linalg.norm(x, axis=1) for x in v)
    moving = s_true > moving_m_s
    if not np.any(moving):
        return float("nan")
    return float(np.sqrt(np.mean((s_est[moving] - s_true[moving]) ** 2)))


ACTIVITY_CLASSES = (Activity.STANDING, Activity.WALKING, Activity.RUNNING, Activity.UPSTAIRS,
                    Activity.DOWNSTAIRS, Activity.UNKNOWN)


@dataclass(frozen=True, slots=True)
class ActivityConfusion:
    """Confusion matrix: rows true class, columns estimated class (``ACTIVITY_CLASSES``).

    ``accuracy`` counts samples whose estimated class equals the true one over all samples.
    """

    labels: tuple[str, ...]
    matrix: IntArray
    accuracy: float

    def to_dict(self) -> dict[str, object]:
        """JSON-able form."""
        return {"labels": list(self.labels), "matrix": self.matrix.tolist(),
                "accuracy": self.accuracy}


def hold_previous(t_change: ArrayLike, values: ArrayLike, t_query: ArrayLike) -> IntArray:
    """Value of a step function (held from each change time) at ``t_query``."""
    tc = np.asarray(t_change, dtype=np.float64)
    v = np.asarray(values)
    idx = np.clip(np.searchsorted(tc, np.asarray(t_query, dtype=np.float64), side="right") - 1,
                  0, len(tc) - 1)
    return np.asarray(v[idx], dtype=np.int64)


def activity_confusion(true_t: ArrayLike, true_codes: ArrayLike, est_t: ArrayLike,
                       est_codes: ArrayLike) -> ActivityConfusion:
    """Confusion of estimated activity samples against the true activity held at their times."""
    et = np.asarray(est_t, dtype=np.float64)
    ec = np.asarray(est_codes, dtype=np.int64)
    if len(np.asarray(true_t)) == 0 or et.size == 0:
        raise InputError("no activity samples", where="activity", expected="non-empty series")
    tc = hold_previous(true_t, true_codes, et)
    k = len(ACTIVITY_CLASSES)
    lut = np.full(max(int(c) for c in Activity) + 2, k - 1, dtype=np.int64)  # code + 1 -> row
    for i, c in enumerate(ACTIVITY_CLASSES):
        lut[int(c) + 1] = i

    def index(codes: IntArray) -> IntArray:
        ok = (codes >= -1) & (codes < len(lut) - 1)
        return np.where(ok, lut[np.clip(codes + 1, 0, len(lut) - 1)], k - 1)

    rows, cols = index(tc), index(ec)
    m = np.zeros((k, k), dtype=np.int64)
    np.add.at(m, (rows, cols), 1)
    return ActivityConfusion(labels=tuple(c.label for c in ACTIVITY_CLASSES), matrix=m,
                             accuracy=float(np.trace(m) / m.sum()))


def class_weighted_error(truth: np.ndarray, predicted: np.ndarray,
                         weights: Mapping[Activity, int]) -> float:
    """Error rate, %, with each true class's error rate weighted by ``weights``.

    NaN when a weighted class has no window in ``truth``.
    """
    total = 0.0
    for cls, w in weights.items():
        mine = truth == int(cls)
        if not mine.any():
            return math.nan
        total += w * float(np.mean(predicted[mine] != int(cls)))
    return 100.0 * total / sum(weights.values())
