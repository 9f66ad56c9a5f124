"""``hrtls bench papers``: each paper's scenario tracked with its own preset and with ``default``.

For every target of the issue "rescuer filter end to end" the simulated scenario of the paper is
run for several seeds, tracked with the paper's preset and with our ``default`` preset, and
scored the way the paper scored. Each :class:`BenchRow` holds the paper's published figure, the
mean and worst value over the seeds for both presets, the target and whether ``default`` meets
it. The CLI prints the rows as one table; this module never prints.

Error definitions (our readings of the papers, see :data:`DEFINITIONS`):

* Colombo Sec. V: "position errors along both X_w and Y_w smaller than +-50 cm with 97 %
  probability" -- per truth sample the larger of the two per-axis absolute errors,
  ``max(|e_x|, |e_y|)``, and its 97th percentile over the walk. Velocity RMSE (Fig. 7): the RMS
  difference of the filter's and the true walking *speed* on a 10 Hz grid, both smoothed over
  1 s, while the user walks (Fig. 7 is plotted against the distance travelled). Fig. 7 scores
  the automaton speed ``v_xu`` that drives the prediction (eq. 16), not the derivative of the
  corrected track: we differentiate the estimated track with the position jumps of the
  accepted fixes removed (:func:`predicted_track`); the paper differentiated camera
  positions, we use the exact truth.
* Basso Table I "mean position error": the error at the path's way-points (turns and end),
  integrated over the distance walked (trapezoids, start error 0), divided by the path length
  (mean error along the path, m) and normalized by the path length (fraction of distance).
* Tarrio Sec. IV: the 90th percentile of the horizontal error against the continuous truth;
  "Kalman better than RSS alone": mean error of RSS alone (each 2 s WLS position held, no
  IMU) minus mean error of the preset.
* Inderst Table 6.13: maximum Euclidean error at the checkpoints (eq. 6.1) over the mission;
  Tables 6.14-6.15: mean and maximum checkpoint error of users A and B with position-only and
  with position + heading (bearing) correction.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from hrtls.data import Activity, Session, Trajectory
from hrtls.evaluate.metrics import (
    checkpoint_errors,
    distance_at,
    integral_mean_error,
    position_errors,
)
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length_fit import CalibrationWalk, fit_frequency_law, fit_weinberg
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.config import TagsConfig
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult, run_scenario

DEFINITIONS = {
    "p97_axis": "97th percentile of max(|e_x|, |e_y|) over the walk (Colombo Sec. V)",
    "speed_rmse": "RMSE of the prediction's walking speed (fix jumps removed) vs the true speed "
                  "while walking, 10 Hz grid, 1 s smoothing (Colombo Fig. 7)",
    "ime": "Basso integral mean error at the way-points / path length (Table I)",
    "p90": "90th percentile of the horizontal error vs continuous truth (Tarrio Fig. 1)",
    "rss_gain": "mean error of RSS alone minus mean error of the preset (Tarrio Sec. IV)",
    "cp_max": "maximum checkpoint error, eq. 6.1 (Inderst Table 6.13)",
    "cp_mean": "mean checkpoint error, eq. 6.1 (Inderst Tables 6.14-6.15)",
}


@dataclass(frozen=True, slots=True)
class BenchRow:
    """One line of the benchmark table.

    Attributes
    ----------
    scenario: scenario name and options, e.g. ``colombo_circle Tp=16 s``.
    metric: what is measured (unit included).
    paper: the paper's published figure (text, may be ``-``).
    paper_preset: name of the paper's preset.
    paper_mean, paper_worst: the paper preset over the seeds (mean, worst).
    default_mean, default_worst: the ``default`` preset over the seeds (mean, worst).
    target: our goal, e.g. ``<= 0.50``; ``-`` when there is none.
    met: whether the ``default`` mean meets the target (None without a target).
    note: why we fall short, or how the number was read.
    """

    scenario: str
    metric: str
    paper: str
    paper_preset: str
    paper_mean: float
    paper_worst: float
    default_mean: float
    default_worst: float
    target: str
    met: bool | None
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (NaN as None)."""
        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)

        return {"scenario": self.scenario, "metric": self.metric, "paper": self.paper,
                "paper_preset": self.paper_preset, "paper_mean": num(self.paper_mean),
                "paper_worst": num(self.paper_worst), "default_mean": num(self.default_mean),
                "default_worst": num(self.default_worst), "target": self.target,
                "met": self.met, "note": self.note}


Metric = Callable[[TrackResult, SimulationResult], float]


@dataclass(frozen=True, slots=True)
class MetricSpec:
    """A metric of a case: label, paper figure, target (``("<=", 0.5)``), worst = max or min."""

    label: str
    fn: Metric
    paper: str
    target: tuple[str, float] | None = None
    higher_is_better: bool = False
    note: str = ""


@dataclass(frozen=True, slots=True)
class Case:
    """A scenario with options, the paper preset and the metrics to score."""

    label: str
    scenario: str
    options: dict[str, Any]
    paper_preset: str
    metrics: list[MetricSpec]
    paper_config: Callable[[TrackerConfig], TrackerConfig] | None = None
    default_config: Callable[[TrackerConfig], TrackerConfig] | None = None
    quick: bool = True
    calibrate: bool = False
    """Fit the step-length model on another walk of the same user first (Basso II-D)."""
    relative_to: str | None = None
    """Label of a case whose ``default`` value (same metric) this one must not exceed."""


# ---------------------------------------------------------------------------------- metrics
def p97_axis(result: TrackResult, sim: SimulationResult) -> float:
    """Colombo: 97th percentile of max(|e_x|, |e_y|) (m)."""
    truth = sim.session.truth
    assert truth is not None
    tr = result.trajectory
    keep = (truth.t >= tr.t[0]) & (truth.t <= tr.t[-1])
    d = tr.position_at(truth.t[keep])[:, :2] - truth.xyz[keep, :2]
    return float(np.percentile(np.max(np.abs(d), axis=1), 97.0))


def predicted_track(result: TrackResult) -> Trajectory:
    """The estimated track without the position jumps of the accepted fixes.

    Its time derivative is the velocity the filter's prediction integrated (eq. 16: the
    automaton speed along the yaw; or the steps), which is what Colombo's Fig. 7 scores. The
    jumps come from ``report["fix_jumps"]`` (rows ``[t, dx, dy]``, added by :func:`_track`).
    """
    tr = result.trajectory
    jumps = np.asarray(result.report.get("fix_jumps", []), dtype=np.float64).reshape(-1, 3)
    if len(jumps) == 0:
        return tr
    # the row at a fix time holds the corrected state: remove every jump at or before it
    cum = np.vstack([np.zeros((1, 2)), np.cumsum(jumps[:, 1:], axis=0)])
    k = np.searchsorted(jumps[:, 0], tr.t, side="right")
    xyz = tr.xyz.copy()
    xyz[:, :2] -= cum[k]
    return Trajectory.build(t=tr.t, xyz=xyz)


SPEED_MOVING_M_S = 0.2
"""Fig. 7 is plotted against the distance travelled: only samples where the (smoothed) true
speed exceeds this count, m/s."""


def speed_rmse(result: TrackResult, sim: SimulationResult) -> float:
    """Colombo Fig. 7: RMSE of the filter's walking speed against the true speed (m/s).

    The filter's speed is that of its prediction (:func:`predicted_track`: fix jumps are
    corrections, not motion); both tracks are sampled on the same 10 Hz grid, smoothed over
    1 s and differentiated the same way; samples where the true speed is below
    :data:`SPEED_MOVING_M_S` (standing before and after the walk) are left out.
    """
    truth = sim.session.truth
    assert truth is not None
    est = predicted_track(result)
    t0, t1 = max(est.t[0], truth.t[0]), min(est.t[-1], truth.t[-1])
    t = np.arange(t0, t1, 0.1)
    kernel = np.ones(10) / 10.0
    if len(t) < len(kernel) + 2:
        return math.nan
    tm = np.convolve(t, kernel, mode="valid")

    def speed(xy: np.ndarray) -> np.ndarray:
        sm = np.column_stack([np.convolve(c, kernel, mode="valid") for c in xy.T])
        return np.asarray(np.linalg.norm(np.gradient(sm, tm, axis=0), axis=1))

    v_est = speed(est.position_at(t)[:, :2])
    v_true = speed(truth.position_at(t)[:, :2])
    moving = v_true > SPEED_MOVING_M_S
    if not np.any(moving):
        return math.nan
    return float(np.sqrt(np.mean((v_est[moving] - v_true[moving]) ** 2)))


def basso_ime(result: TrackResult, sim: SimulationResult) -> float:
    """Basso Table I mean position error: integral mean error / length (%)."""
    cps, truth = sim.session.checkpoints, sim.session.truth
    assert cps is not None and truth is not None
    t, e, _ = checkpoint_errors(result.trajectory, cps)
    s = distance_at(truth, t)
    length = float(sim.reference.get("length_m", s[-1] if len(s) else 1.0))
    _, frac = integral_mean_error(np.concatenate([[0.0], s]), np.concatenate([[0.0], e]),
                                  length)
    return 100.0 * frac


def p90_error(result: TrackResult, sim: SimulationResult) -> float:
    """90th percentile of the horizontal error (m)."""
    truth = sim.session.truth
    assert truth is not None
    return float(np.percentile(position_errors(result.trajectory, truth)[1], 90.0))


def mean_error(result: TrackResult, sim: SimulationResult) -> float:
    """Mean horizontal error (m)."""
    truth = sim.session.truth
    assert truth is not None
    return float(np.mean(position_errors(result.trajectory, truth)[1]))


def checkpoint_max(result: TrackResult, sim: SimulationResult) -> float:
    """Inderst eq. 6.1: maximum checkpoint error (m)."""
    cps = sim.session.checkpoints
    assert cps is not None
    return float(np.max(checkpoint_errors(result.trajectory, cps)[1]))


def checkpoint_mean(result: TrackResult, sim: SimulationResult) -> float:
    """Inderst eq. 6.1: mean checkpoint error (m)."""
    cps = sim.session.checkpoints
    assert cps is not None
    return float(np.mean(checkpoint_errors(result.trajectory, cps)[1]))


def rss_alone_session(session: Session) -> Session:
    """The session without its IMU: Tarrio's "RSS alone" input."""
    return session.with_parts(imu=None, orientation=None, pressure=None)


def rss_alone_config(config: TrackerConfig) -> TrackerConfig:
    """RSS alone: WLS positions held between scans (no inertial prediction)."""
    return config.model_copy(update={"name": "rss-alone",
                                      "rss": config.rss.model_copy(update={"mode": "wls"})})


def rss_gain(result: TrackResult, sim: SimulationResult) -> float:
    """Mean error of RSS alone minus the preset's mean error (m)."""
    base = Tracker(rss_alone_config(preset("tarrio2011"))).run(rss_alone_session(sim.session))
    return mean_error(base, sim) - mean_error(result, sim)


def without_bearing(config: TrackerConfig) -> TrackerConfig:
    """The same configuration with the tag-bearing heading correction off."""
    return config.model_copy(update={
        "name": f"{config.name} (no bearing)",
        "tags": TagsConfig(**{**config.tags.model_dump(), "bearing_correction": False})})


def with_bearing(config: TrackerConfig) -> TrackerConfig:
    """The same configuration with the tag-bearing heading correction on."""
    return config.model_copy(update={
        "name": f"{config.name} (bearing)",
        "tags": TagsConfig(**{**config.tags.model_dump(), "bearing_correction": True})})


# ---------------------------------------------------------------------------------- cases
RELATIVE_TOLERANCE_M = 0.05
"""A row "not worse than without bearings" may exceed the reference by this much (m)."""
_BASSO = {1: 1.0, 2: 2.1, 3: 0.9, 4: 1.6, 5: 1.6, 6: 1.4}
_RING = {"all": ("2.62", 2.0), "corners": ("4.28", 3.0), "corridor": ("13.34", 5.0),
         "no_tag5": ("2.62", 2.0)}


def cases() -> list[Case]:
    """All benchmark cases, in table order."""
    out: list[Case] = []
    for shape in ("circle", "square"):
        for tp in (10.0, 16.0):
            metrics = [MetricSpec(
                "P97 max(|ex|,|ey|) [m]", p97_axis, "0.50 (97 % within +-50 cm, Tp 1-16 s)",
                ("<=", 0.5), note="per-axis error, 97th percentile")]
            if tp == 10.0:
                metrics.append(MetricSpec("speed RMSE [m/s]", speed_rmse, "~0.25 (Fig. 7)",
                                          ("<=", 0.15)))
            out.append(Case(f"colombo_{shape} Tp={tp:.0f} s", f"colombo_{shape}",
                            {"tp_s": tp}, "colombo2014", metrics,
                            paper_config=_fix_period_of(tp), default_config=_fix_period_of(tp),
                            quick=tp == 16.0))
    for test, basso_fig in _BASSO.items():
        out.append(Case(f"basso_test{test}", f"basso_test{test}", {}, "basso2017", [
            MetricSpec("mean pos. error (IME/L) [%]", basso_ime, f"{basso_fig:.1f} % (Table I)",
                       ("<=", 1.0))], quick=test in (1, 3), calibrate=True))
    out.append(Case("tarrio_circle (9 anchors)", "tarrio_circle", {}, "tarrio2011", [
        MetricSpec("p90 error [m]", p90_error, "2.4 (Sec. IV)", ("<=", 1.8)),
        MetricSpec("RSS alone - ours, mean [m]", rss_gain, "~1.5 (Kalman vs RSS alone)",
                   (">=", 1.5), higher_is_better=True)]))
    for tags, (fig, goal) in _RING.items():
        out.append(Case(f"inderst_ring tags={tags}", "inderst_ring", {"tags": tags},
                        "inderst-rfid", [MetricSpec(
                            "max checkpoint error [m]", checkpoint_max,
                            f"{fig} (Table 6.13, no heading corr.)", ("<=", goal))],
                        paper_config=without_bearing, default_config=without_bearing,
                        quick=tags in ("all", "corners")))
        out.append(Case(f"inderst_ring tags={tags} +bearing", "inderst_ring", {"tags": tags},
                        "inderst-rfid", [MetricSpec(
                            "max checkpoint error [m]", checkpoint_max,
                            "lower than without (Tables 6.14-6.15)", ("<=", goal))],
                        paper_config=with_bearing, default_config=with_bearing,
                        quick=tags in ("all", "corners"),
                        relative_to=f"inderst_ring tags={tags}"))
    users = {"A": ("6.14", "1.6", "3.97", "1.07", "3.14"),
             "B": ("6.15", "1.1", "2.62", "0.84", "2.64")}
    for user, (table, pos_mean, pos_max, head_mean, head_max) in users.items():
        for label, mean_fig, max_fig, cfg in (
                ("position corr.", pos_mean, pos_max, without_bearing),
                ("position+heading corr.", head_mean, head_max, with_bearing)):
            out.append(Case(f"inderst_two_users {user} {label}", "inderst_two_users",
                            {"user": user}, "inderst-rfid", [
                                MetricSpec("mean checkpoint error [m]", checkpoint_mean,
                                           f"{mean_fig} (Table {table})"),
                                MetricSpec("max checkpoint error [m]", checkpoint_max,
                                           f"{max_fig} (Table {table})")],
                            paper_config=cfg, default_config=cfg, quick=False,
                            relative_to=None if cfg is without_bearing
                            else f"inderst_two_users {user} position corr."))
    return out


def _fix_period_of(tp: float) -> Callable[[TrackerConfig], TrackerConfig]:
    def apply(config: TrackerConfig) -> TrackerConfig:
        return config.model_copy(update={"fixes": config.fixes.model_copy(
            update={"period_s": tp, "enabled": True})})

    return apply


# ---------------------------------------------------------------------------------- calibration
CALIBRATION_SEED = 1000
"""Calibration walks are the same scenario (same user) with seed ``CALIBRATION_SEED + seed``."""


def calibrate_step_model(config: TrackerConfig, cal: SimulationResult) -> dict[str, Any]:
    """Basso Sec. II-D: fit the preset's step-length model on a walk of known legs.

    The calibration walk is cut at its way-points; every leg (at its own pace) is one
    calibration walk of known length (the true distance along the leg).
    """
    cps, truth = cal.session.checkpoints, cal.session.truth
    assert cps is not None and truth is not None
    steps = _track(config, cal.session).steps
    t_cut = np.concatenate([[truth.t[0]], cps.t])
    walks = []
    runs = []
    for a, b in pairwise(t_cut.tolist()):
        sel = (steps.t_end > a) & (steps.t_end <= b)
        if np.count_nonzero(sel) < 10:
            continue
        det = StepDetection(steps.t_start[sel], steps.t_end[sel], steps.frequency_hz[sel],
                            steps.acc_max[sel], steps.acc_min[sel])
        dist = float(distance_at(truth, np.array([b]))[0] - distance_at(truth, np.array([a]))[0])
        walks.append(CalibrationWalk(det, dist))
        runs.append(steps.activity[sel] == int(Activity.RUNNING))
    if config.gait.step_length == "frequency":
        return fit_frequency_law(walks).to_dict()
    model = fit_weinberg(walks).to_dict()
    if config.gait.step_length == "weinberg":
        k_run = fit_weinberg_running(walks, runs)
        if k_run is not None:
            model = {"kind": "weinberg", "k": k_run[0], "k_running": k_run[1]}
    return model


def fit_weinberg_running(walks: Sequence[CalibrationWalk], running: Sequence[np.ndarray]
                         ) -> tuple[float, float] | None:
    """Weinberg K of walking and of running steps, jointly by least squares over the walks.

    Each calibration walk's length is ``K_walk S_walk + K_run S_run`` with ``S`` the sums of
    ``(a_max - a_min)^(1/4)`` of its steps classified walking / running. None when fewer than
    two walks have a substantial share (30 %) of running steps or the fit is implausible.
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


def with_step_model(session: Session, step_model: dict[str, Any]) -> Session:
    """The session with the user's step-length model replaced."""
    meta = session.meta
    user = meta.user.model_copy(update={"step_model": step_model})
    return session.with_parts(meta=meta.model_copy(update={"user": user}))


# ---------------------------------------------------------------------------------- running
def _track(config: TrackerConfig, session: Session) -> TrackResult:
    tracker = Tracker(config)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = tracker.run(session)
    # position changes of the accepted fixes, for the prediction's own speed (Fig. 7)
    result.report["fix_jumps"] = [list(j) for j in tracker.fix_jumps]
    return result


def _summary(values: list[float], higher_is_better: bool) -> tuple[float, float]:
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        return math.nan, math.nan
    return float(np.mean(v)), float(np.min(v) if higher_is_better else np.max(v))


def _met(value: float, target: tuple[str, float] | None) -> bool | None:
    if target is None or not math.isfinite(value):
        return None
    op, bound = target
    return value <= bound if op == "<=" else value >= bound


def run_bench(*, seeds: int = 3, quick: bool = False,
              progress: Callable[[str], None] | None = None,
              only: Sequence[str] | None = None) -> list[BenchRow]:
    """Run every case (``quick``: a subset, one seed) and return the table rows.

    ``only`` keeps the cases whose label contains one of the strings.
    """
    n_seeds = 1 if quick else max(1, int(seeds))
    rows: list[BenchRow] = []
    done: dict[tuple[str, str], float] = {}
    for case in cases():
        if quick and not case.quick:
            continue
        if only and not any(s in case.label for s in only):
            continue
        paper_cfg = preset(case.paper_preset)
        default_cfg = preset("default")
        if case.paper_config is not None:
            paper_cfg = case.paper_config(paper_cfg)
        if case.default_config is not None:
            default_cfg = case.default_config(default_cfg)
        values: dict[tuple[str, int], list[float]] = {}
        for seed in range(n_seeds):
            if progress:
                progress(f"{case.label}: seed {seed}")
            sim = run_scenario(case.scenario, seed, **case.options)
            for which, cfg in (("paper", paper_cfg), ("default", default_cfg)):
                session = sim.session
                if case.calibrate:
                    cal = run_scenario(case.scenario, CALIBRATION_SEED + seed, **case.options)
                    session = with_step_model(session, calibrate_step_model(cfg, cal))
                res = _track(cfg, session)
                for k, m in enumerate(case.metrics):
                    values.setdefault((which, k), []).append(m.fn(res, sim))
        for k, m in enumerate(case.metrics):
            pm, pw = _summary(values[("paper", k)], m.higher_is_better)
            dm, dw = _summary(values[("default", k)], m.higher_is_better)
            target = "-" if m.target is None else f"{m.target[0]} {m.target[1]:g}"
            met = _met(dm, m.target)
            ref = done.get((case.relative_to or "", m.label))
            if ref is not None:
                # the heading correction must not make it worse (Tables 6.14-6.15)
                target = (f"{'' if target == '-' else target + ' and '}<= w/o bearing "
                          f"({ref:.2f})")
                ok = dm <= ref + RELATIVE_TOLERANCE_M
                met = ok if met is None else (met and ok)
            done[(case.label, m.label)] = dm
            rows.append(BenchRow(case.label, m.label, m.paper, case.paper_preset, pm, pw, dm, dw,
                                 target, met, m.note))
    return rows
