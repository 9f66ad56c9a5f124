"""Calibration of the step length models from walks of known length (Basso Sec. II-D).

Each calibration walk gives the detected steps and the true distance ``D``:

* Weinberg: ``D_i = K * S_i`` with ``S_i = sum_k (a_max - a_min)^(1/4)``, so the least-squares
  ``K = sum_i D_i S_i / sum_i S_i^2``.
* Frequency law: every walk is one point ``(f_bar_i, SL_bar_i)`` with the mean frequency of
  eq. 1, ``f_bar = (1/N sum_k 1/f_k)^(-1)``, and the mean step length of eq. 2,
  ``SL_bar = D / N``; the walking line is the least-squares fit of the points below
  ``split_hz``, the running line of those above. With too narrow a frequency spread a segment
  keeps the default slope and fits its intercept; with no walk it keeps the default line.
* Pendulum (:mod:`hrtls.gait.step_length_pendulum`): ``D_i = K * U_i`` with
  ``U_i = sum_k 2 sqrt(2 L h_k - h_k^2)``, so ``K = sum_i D_i U_i / sum_i U_i^2`` (``L`` is
  kept from the base model).
* Weinberg with a running constant: ``D_i = K_walk S_walk,i + K_run S_run,i`` over the steps
  classified walking / running, jointly by least squares.

:func:`walks_between_marks` cuts a recording's steps into calibration walks at marked times.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity, StepEvents
from hrtls.errors import InputError
from hrtls.gait._state import FloatArray
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length import FrequencyLawModel, WeinbergModel
from hrtls.gait.step_length_pendulum import PendulumModel


@dataclass(frozen=True, slots=True)
class CalibrationWalk:
    """Steps detected on one walk, its true length (m) and the steps' vertical excursions.

    ``excursion_m`` (m, one per step) is only needed by the pendulum model.
    """

    steps: StepDetection
    distance_m: float
    excursion_m: FloatArray | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.distance_m) and self.distance_m > 0):
            raise InputError(f"distance {self.distance_m}", where="calibration walk",
                             expected="a positive distance in m")
        if len(self.steps) == 0:
            raise InputError("no steps detected", where="calibration walk",
                             expected="a walk with detected steps")
        if self.excursion_m is not None and np.shape(self.excursion_m) != (len(self.steps),):
            raise InputError(f"{np.shape(self.excursion_m)} excursions for {len(self.steps)} "
                             "steps", where="calibration walk",
                             expected="one vertical excursion per step")


def mean_frequency(steps: StepDetection) -> float:
    """Mean step frequency of eq. 1 (harmonic mean of ``f_k``), Hz."""
    f = steps.frequency_hz
    return float(len(f) / np.sum(1.0 / f))


def fit_weinberg(walks: Sequence[CalibrationWalk]) -> WeinbergModel:
    """Least-squares ``K`` of the Weinberg model."""
    if not walks:
        raise InputError("no walks", where="calibration", expected="at least one walk")
    s = np.array([float(np.sum(np.sqrt(np.sqrt(np.clip(w.steps.acc_max - w.steps.acc_min,
                                                            0.0, None))))) for w in walks])
    d = np.array([w.distance_m for w in walks])
    if np.sum(s * s) <= 0:
        raise InputError("all steps have zero acceleration range", where="calibration",
                         expected="steps with vertical acceleration extremes")
    return WeinbergModel(k=float(np.sum(d * s) / np.sum(s * s)))


def _line(f: FloatArray, sl: FloatArray, base_slope: float,
          min_spread_hz: float) -> tuple[float, float] | None:
    if f.size == 0:
        return None
    if f.size == 1 or np.ptp(f) < min_spread_hz:
        # the frequencies do not determine a slope: keep the base slope, fit the intercept
        return base_slope, float(np.mean(sl - base_slope * f))
    a = np.column_stack([f, np.ones_like(f)])
    (slope, intercept), *_ = np.linalg.lstsq(a, sl, rcond=None)
    return float(slope), float(intercept)


def calibration_points(walks: Sequence[CalibrationWalk]) -> tuple[FloatArray, FloatArray]:
    """Points ``(f_bar_i, SL_bar_i)`` of eq. 1-2, one per walk."""
    f = np.array([mean_frequency(w.steps) for w in walks])
    sl = np.array([w.distance_m / len(w.steps) for w in walks])
    return f, sl


def fit_frequency_law(walks: Sequence[CalibrationWalk], *,
                      base: FrequencyLawModel | None = None,
                      min_spread_hz: float = 0.2) -> FrequencyLawModel:
    """Least-squares walking and running lines of the frequency law (Basso eq. 1-2).

    A segment whose walks span less than ``min_spread_hz`` of mean frequency cannot fix a
    slope (Basso asks for walks at several speeds): it keeps the slope of ``base`` and only
    its intercept is fitted.
    """
    if not walks:
        raise InputError("no walks", where="calibration", expected="at least one walk")
    b = base or FrequencyLawModel()
    f, sl = calibration_points(walks)
    lo = f < b.split_hz
    walk = _line(f[lo], sl[lo], b.walk_slope_m_s, min_spread_hz)
    run = _line(f[~lo], sl[~lo], b.run_slope_m_s, min_spread_hz)
    return FrequencyLawModel(
        walk_slope_m_s=b.walk_slope_m_s if walk is None else walk[0],
        walk_intercept_m=b.walk_intercept_m if walk is None else walk[1],
        run_slope_m_s=b.run_slope_m_s if run is None else run[0],
        run_intercept_m=b.run_intercept_m if run is None else run[1],
        split_hz=b.split_hz, max_length_m=b.max_length_m)


def fit_pendulum(walks: Sequence[CalibrationWalk], *,
                 base: PendulumModel | None = None) -> PendulumModel:
    """Least-squares ``K`` of the pendulum model (walks must carry ``excursion_m``)."""
    if not walks:
        raise InputError("no walks", where="calibration", expected="at least one walk")
    b = base or PendulumModel()
    u = []
    for i, w in enumerate(walks):
        if w.excursion_m is None:
            raise InputError("no vertical excursions", where=f"calibration walk {i}",
                             expected="excursion_m for the pendulum model")
        u.append(float(np.sum(b.unit_lengths(w.excursion_m))))
    uu = np.asarray(u)
    d = np.array([w.distance_m for w in walks])
    if np.sum(uu * uu) <= 0:
        raise InputError("all steps have zero vertical excursion", where="calibration",
                         expected="steps with a vertical pelvis motion")
    return PendulumModel(k=float(np.sum(d * uu) / np.sum(uu * uu)),
                         leg_length_m=b.leg_length_m, max_length_m=b.max_length_m)


def fit_weinberg_running(walks: Sequence[CalibrationWalk], running: Sequence[NDArray[np.bool_]]
                         ) -> tuple[float, float] | None:
    """Weinberg K of walking and of running steps, jointly by least squares over the walks.

    Each calibration walk's length is ``K_walk S_walk + K_run S_run`` with ``S`` the sums of
    ``(a_max - a_min)^(1/4)`` of its steps classified walking / running (``running``: one
    mask per walk). None when fewer than two walks have a substantial share (30 %) of running
    steps, when every walk has, or when the fit is implausible.
    """
    rows, dist = [], []
    n_run = 0
    for w, r in zip(walks, running, strict=True):
        q = np.sqrt(np.sqrt(np.clip(w.steps.acc_max - w.steps.acc_min, 0.0, None)))
        rows.append([float(np.sum(q[~r])), float(np.sum(q[r]))])
        dist.append(w.distance_m)
        n_run += int(np.mean(r) > 0.3)
    if n_run < 2 or n_run == len(walks):
        return None
    sol = np.linalg.lstsq(np.asarray(rows), np.asarray(dist), rcond=None)[0]
    k_walk, k_run = float(sol[0]), float(sol[1])
    if not (k_walk > 0 and 0.5 <= k_run / k_walk <= 2.0):
        return None
    return k_walk, k_run


def walks_between_marks(steps: StepEvents, t_marks: FloatArray, distance_m: FloatArray, *,
                        min_steps: int = 10
                        ) -> tuple[list[CalibrationWalk], list[NDArray[np.bool_]]]:
    """Calibration walks between consecutive marked times, and their running-step masks.

    ``distance_m`` is the distance travelled at each of ``t_marks`` (increasing); a walk holds
    the steps ending in ``(t_k, t_k+1]``. Stretches with fewer than ``min_steps`` steps are
    left out.
    """
    walks: list[CalibrationWalk] = []
    runs: list[NDArray[np.bool_]] = []
    for k, (a, b) in enumerate(pairwise(np.asarray(t_marks, dtype=np.float64).tolist())):
        sel = (steps.t_end > a) & (steps.t_end <= b)
        if np.count_nonzero(sel) < min_steps:
            continue
        det = StepDetection(steps.t_start[sel], steps.t_end[sel], steps.frequency_hz[sel],
                            steps.acc_max[sel], steps.acc_min[sel])
        walks.append(CalibrationWalk(det, float(distance_m[k + 1] - distance_m[k])))
        runs.append(steps.activity[sel] == int(Activity.RUNNING))
    return walks, runs
