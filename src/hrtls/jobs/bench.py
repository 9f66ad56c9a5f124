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

import dataclasses
import math
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from hrtls.calibration.channel import fit_path_loss
from hrtls.data import Activity, ChannelModel, Session, Trajectory
from hrtls.errors import InputError
from hrtls.evaluate.floors import floor_detection
from hrtls.evaluate.metrics import (
    axis_errors,
    checkpoint_errors,
    distance_at,
    integral_mean_error,
    moving_speed_rmse,
    position_errors,
)
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length_fit import CalibrationWalk, fit_frequency_law, fit_weinberg
from hrtls.jobs import bench_studies
from hrtls.parallel import Engine, LocalEngine, values_or_raise
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.config import TagsConfig
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import TARRIO_OFFICE_TABLE, SimulationResult, run_scenario

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
    paper_stats, default_stats: the paper preset / ``default`` over the seeds.
    target: our goal, e.g. ``<= 0.5``; ``-`` when there is none.
    met: whether ``default`` meets the target on its 90th percentile over the seeds (None
        without a target).
    n_seeds: number of seeds.
    note: how the number was read, or the paired bearing comparison.
    higher_is_better: the metric improves upwards (the p90 is then the 10th percentile).
    """

    scenario: str
    metric: str
    paper: str
    paper_preset: str
    paper_stats: SeedStats
    default_stats: SeedStats
    target: str
    met: bool | None
    n_seeds: int
    note: str = ""
    higher_is_better: bool = False

    @property
    def paper_value(self) -> float | None:
        """The paper's figure as a number (its leading number), None when it has none."""
        m = re.match(r"~?\s*([0-9]+(?:\.[0-9]+)?)", self.paper)
        return float(m.group(1)) if m else None

    @property
    def beats_paper(self) -> bool | None:
        """Whether ``default``'s mean over seeds is better than the paper's figure."""
        ref, mean = self.paper_value, self.default_stats.mean
        if ref is None or not math.isfinite(mean):
            return None
        return mean > ref if self.higher_is_better else mean < ref

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> BenchRow:
        """The row of :meth:`to_dict` (None read as NaN)."""
        def num(v: float | None) -> float:
            return math.nan if v is None else float(v)

        def stats(which: str) -> SeedStats:
            return SeedStats(num(d[f"{which}_mean"]), num(d[f"{which}_p90"]),
                             num(d[f"{which}_worst"]))

        return cls(d["scenario"], d["metric"], d["paper"], d["paper_preset"], stats("paper"),
                   stats("default"), d["target"], d["met"], int(d["n_seeds"]), d["note"],
                   bool(d.get("higher_is_better", d["target"].startswith(">="))))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form (NaN as None)."""
        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)

        out: dict[str, Any] = {"scenario": self.scenario, "metric": self.metric,
                               "paper": self.paper, "paper_preset": self.paper_preset}
        for which, st in (("paper", self.paper_stats), ("default", self.default_stats)):
            out.update({f"{which}_mean": num(st.mean), f"{which}_p90": num(st.p90),
                        f"{which}_worst": num(st.worst)})
        out.update({"target": self.target, "met": self.met, "n_seeds": self.n_seeds,
                    "note": self.note, "higher_is_better": self.higher_is_better,
                    "paper_value": self.paper_value, "beats_paper_on_mean": self.beats_paper})
        return out


Metric = Callable[[TrackResult, SimulationResult], float]


@dataclass(frozen=True, slots=True)
class MetricSpec:
    """A metric of a case: label, paper figure, target (``("<=", 0.5)``), worst = max or min.

    ``fn`` scores a tracked walk; None for the metrics of a study case (its ``study`` gives
    the values).
    """

    label: str
    fn: Metric | None
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
    relative_to: str | None = None
    """Label of a case whose ``default`` value (same metric) this one must not exceed."""
    study: Callable[[int], Sequence[float]] | None = None
    """A study instead of a tracked walk (:mod:`hrtls.jobs.bench_studies`): the values of the
    metrics for one seed. hrtls' default for such a job is the paper's method, so both columns
    hold its values."""


# ---------------------------------------------------------------------------------- metrics
def p97_axis(result: TrackResult, sim: SimulationResult) -> float:
    """Colombo: 97th percentile of max(|e_x|, |e_y|) (m)."""
    truth = sim.session.truth
    assert truth is not None
    return float(np.percentile(np.max(axis_errors(result.trajectory, truth), axis=1), 97.0))


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
    return moving_speed_rmse(predicted_track(result), truth, moving_m_s=SPEED_MOVING_M_S)


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


def max_error(result: TrackResult, sim: SimulationResult) -> float:
    """Maximum horizontal error (m)."""
    truth = sim.session.truth
    assert truth is not None
    return float(np.max(position_errors(result.trajectory, truth)[1]))


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


def activity_correct(result: TrackResult, sim: SimulationResult) -> float:
    """Share of the true activity samples the track labels alike (%), Inderst Sec. 6.3.

    Each simulation sample inside the track takes the activity of the last trajectory row at
    or before it.
    """
    tr = result.trajectory
    t, truth = sim.activity_t, sim.activity
    inside = (t >= tr.t[0]) & (t <= tr.t[-1])
    row = np.searchsorted(tr.t, t[inside], side="right") - 1
    return float(100.0 * np.mean(tr.activity[row] == truth[inside]))


def floors_correct(result: TrackResult, sim: SimulationResult) -> float:
    """Share of the time on a floor that the track is on the right floor (ISO/IEC 18305)."""
    scores = floor_detection(result.trajectory, sim.session.truth, None,
                             floor_height_m=sim.session.meta.floor_height_m)
    assert scores is not None
    return float(scores["time_share_correct_on_floors"])


def thesis_stairs(config: TrackerConfig) -> TrackerConfig:
    """The thesis' multi-floor rescuer: LDA activity (stairs from it), no barometer."""
    return config.model_copy(update={
        "name": f"{config.name} (LDA, no barometer)", "barometer": False,
        "gait": config.gait.model_copy(update={"activity": "lda"})})


# ---------------------------------------------------------------------------------- cases
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
                       ("<=", 1.0))], quick=test in (1, 3)))
    out.append(Case("tarrio_circle (9 anchors)", "tarrio_circle", {}, "tarrio2011", [
        MetricSpec("p90 error [m]", p90_error, "2.4 (Sec. IV)", ("<=", 1.8)),
        MetricSpec("RSS alone - ours, mean [m]", rss_gain, "~1.5 (Kalman vs RSS alone)",
                   (">=", 1.5), higher_is_better=True)]))
    for office_user, row in TARRIO_OFFICE_TABLE.items():   # KF: columns 3 and 6
        kf_mean, kf_max = row[2], row[5]
        out.append(Case(f"tarrio_office user {office_user}", "tarrio_office",
                        {"user": office_user},
                        "tarrio2011", [
                            MetricSpec("mean error [m]", mean_error,
                                       f"{kf_mean:.2f} (Table I, KF)", ("<=", kf_mean)),
                            MetricSpec("max error [m]", max_error,
                                       f"{kf_max:.2f} (Table II, KF)", ("<=", kf_max))],
                        quick=office_user == 1))
    out.append(Case("inderst_ring tags=none (PDR only)", "inderst_ring", {"tags": "none"},
                    "inderst-rfid", [MetricSpec(
                        "max checkpoint error [m]", checkpoint_max,
                        "16.13 (Table 6.10, prediction only)", ("<=", 16.13))],
                    paper_config=without_bearing, default_config=without_bearing, quick=False))
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
    out.append(Case("inderst_multifloor (stairs)", "inderst_multifloor", {}, "inderst-rfid", [
        MetricSpec("activity samples right [%]", activity_correct,
                   "83.20 / 82.87 (Sec. 6.3, two multi-floor walks)", (">=", 83.2),
                   higher_is_better=True),
        MetricSpec("time on the right floor", floors_correct,
                   "none (issue 19 target: 0.99 with a barometer)", (">=", 0.99),
                   higher_is_better=True),
        MetricSpec("max checkpoint error [m]", checkpoint_max,
                   "26 (Table 6.8, ~280 m, prediction only)", ("<=", 26.0))],
        paper_config=thesis_stairs, quick=False))
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
    out += _two_user_prediction_cases() + _study_cases()
    return out


def _two_user_prediction_cases() -> list[Case]:
    """Tables 6.11-6.12: the two users' walk with the inertial platform alone (no tags)."""
    figures = {"A": ("6.11", "7.2", "15.6"), "B": ("6.12", "5", "8.9")}
    return [Case(f"inderst_two_users {user} prediction only", "inderst_two_users",
                 {"user": user, "tags": False}, "inderst-rfid", [
                     MetricSpec("mean checkpoint error [m]", checkpoint_mean,
                                f"{mean_fig} (Table {table}, prediction)", ("<=", float(mean_fig))),
                     MetricSpec("max checkpoint error [m]", checkpoint_max,
                                f"{max_fig} (Table {table}, prediction)", ("<=", float(max_fig)))],
                 paper_config=without_bearing, default_config=without_bearing, quick=False)
            for user, (table, mean_fig, max_fig) in figures.items()]


def _lda_study(seed: int) -> list[float]:
    return [bench_studies.activity_cross_validation(seed)]


def _loose_study(seed: int) -> list[float]:
    return list(bench_studies.loose_cooperation(seed))


def _tight_study(seed: int) -> list[float]:
    return list(bench_studies.tight_cooperation(seed))


def _study_cases() -> list[Case]:
    """Inderst Sec. 6.2 (activity recognition) and Sec. 6.4 (range-node network) studies."""
    return [
        Case("inderst_activity_study (10 users, leave one out)", "activity_course", {},
             "LDA eq. 4.8", [MetricSpec(
                 "error rate, Table 6.7 class mix [%]", None, "12.44 (Sec. 6.2, Table 6.7)",
                 ("<=", 12.44), note="per-class errors of the pooled held-out users' windows "
                 "weighted by Table 6.7's class counts")],
             quick=False, study=_lda_study),
        Case(f"wsn_loose ({bench_studies.LOOSE_NETWORKS} networks of 50 nodes, rho 0.2)",
             "wsn", {}, "SELA + planner", [
                 MetricSpec("nodes localized by SELA alone [share]", None,
                            "- (Fig. 6.11a: 5 of 50 in its one network)",
                            higher_is_better=True),
                 MetricSpec("connected networks fully localized with the planner [share]", None,
                            "all (Fig. 6.11c, Sec. 5.4)", (">=", 1.0),
                            higher_is_better=True)],
             quick=False, study=_loose_study),
        Case(f"wsn_tight ({bench_studies.TIGHT_NETWORKS} networks of 50 nodes, no anchors)",
             "wsn", {}, "robot + Algorithm 1", [
                 MetricSpec("networks fully localized [share]", None,
                            "all (Figs. 6.13-6.16: every example network)", (">=", 1.0),
                            higher_is_better=True),
                 MetricSpec("position RMSE after refinement [rho]", None,
                            "- (not reported)")],
             quick=False, study=_tight_study)]


def _fix_period_of(tp: float) -> Callable[[TrackerConfig], TrackerConfig]:
    def apply(config: TrackerConfig) -> TrackerConfig:
        return config.model_copy(update={"fixes": config.fixes.model_copy(
            update={"period_s": tp, "enabled": True})})

    return apply


# ---------------------------------------------------------------------------------- calibration
def calibrate_step_model(config: TrackerConfig, cal: SimulationResult) -> dict[str, Any]:
    """Basso Sec. II-D: fit the preset's step-length model on walks of known length.

    ``cal`` is the calibration course of the same simulated person
    (``run_scenario(name, seed, calibration=True)``): it is cut at its checkpoints (the leg
    ends, where the user marks the time); every leg is one calibration walk of known length.
    Steps are detected by the preset itself, with its uncalibrated step model.
    """
    cps, truth = cal.session.checkpoints, cal.session.truth
    assert cps is not None and truth is not None
    steps = _track(config, cal.session.with_parts(truth=None, checkpoints=None)).steps
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


def survey_channel(cal: SimulationResult) -> ChannelModel | None:
    """Tarrio Sec. IV-V: the path-loss law fitted on the calibration course's readings.

    The course is walked with the surveyed positions known (its truth); each reading is paired
    with the horizontal distance from the receiver to its anchor. None without readings.
    """
    rss, truth = cal.session.rss, cal.session.truth
    if rss is None or truth is None or len(rss.t) < 3:
        return None
    xy = truth.position_at(rss.t)[:, :2]
    anchor_xy = np.array([cal.session.landmarks[a].xyz()[:2] for a in rss.anchor.tolist()])
    return fit_path_loss(distance_m=np.linalg.norm(xy - anchor_xy, axis=1),
                         rss_dbm=rss.rss_dbm)


def calibrated_session(config: TrackerConfig, session: Session, cal: SimulationResult
                       ) -> Session:
    """The session with what its user brings: step model and channel from the calibration."""
    meta = session.meta
    user = meta.user.model_copy(update={"step_model": calibrate_step_model(config, cal)})
    update: dict[str, Any] = {"user": user}
    if session.rss is not None:
        update["channel"] = survey_channel(cal)
    return session.with_parts(meta=meta.model_copy(update=update))


# ---------------------------------------------------------------------------------- running
def _track(config: TrackerConfig, session: Session) -> TrackResult:
    tracker = Tracker(config)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = tracker.run(session)
    # position changes of the accepted fixes, for the prediction's own speed (Fig. 7)
    result.report["fix_jumps"] = [list(j) for j in tracker.fix_jumps]
    return result


DEV_SEEDS: tuple[int, ...] = tuple(range(10))
"""Development seeds: every default and preset was tuned on these only."""
HELD_OUT_SEEDS: tuple[int, ...] = tuple(range(100, 130))
"""Held-out seeds: the published table (never used for tuning)."""
NOISE_SIGMAS = 2.0
"""A bearing row improves on its reference when the paired mean difference is below
``-NOISE_SIGMAS`` standard errors (outside the seed-to-seed noise)."""


@dataclass(frozen=True, slots=True)
class BenchItem:
    """One unit of work: a case (by label) and a seed."""

    case: str
    seed: int


def _case(label: str) -> Case:
    for c in cases():
        if c.label == label:
            return c
    raise InputError(f"case {label!r}", where="bench case", expected="a label of cases()")


def _configs(case: Case) -> dict[str, TrackerConfig]:
    paper_cfg = preset(case.paper_preset)
    default_cfg = preset("default")
    if case.paper_config is not None:
        paper_cfg = case.paper_config(paper_cfg)
    if case.default_config is not None:
        default_cfg = case.default_config(default_cfg)
    return {"paper": paper_cfg, "default": default_cfg}


def run_item(item: BenchItem) -> dict[str, list[float]]:
    """Metric values of one case and seed: ``{"paper": [...], "default": [...]}``.

    The tracker sees the simulated session without its truth, with the step model (and
    channel) its user calibrated on the calibration course of the same person.
    """
    case = _case(item.case)
    if case.study is not None:
        values = [float(v) for v in case.study(item.seed)]
        return {"paper": values, "default": values}
    sim = run_scenario(case.scenario, item.seed, **case.options)
    cal = run_scenario(case.scenario, item.seed, calibration=True, **case.options)
    blind = sim.session.with_parts(truth=None, checkpoints=None)
    out: dict[str, list[float]] = {}
    for which, cfg in _configs(case).items():
        session = calibrated_session(cfg, blind, cal)
        res = _track(cfg, session)
        scored = dataclasses.replace(sim, session=session.with_parts(
            truth=sim.session.truth, checkpoints=sim.session.checkpoints))
        out[which] = [float(_scored_by(m)(res, scored)) for m in case.metrics]
    return out


def _scored_by(metric: MetricSpec) -> Metric:
    if metric.fn is None:
        raise InputError(f"metric {metric.label!r} has no scorer", where="bench case",
                         expected="a tracked case's metric (a study gives its own values)")
    return metric.fn


@dataclass(frozen=True, slots=True)
class SeedStats:
    """Mean, 90th percentile on the bad side and worst value of one metric over the seeds."""

    mean: float
    p90: float
    worst: float

    @classmethod
    def of(cls, values: Sequence[float], higher_is_better: bool) -> SeedStats:
        """Statistics of ``values`` (the bad side is low when ``higher_is_better``)."""
        v = np.asarray(values, dtype=np.float64)
        if v.size == 0 or not np.all(np.isfinite(v)):
            return cls(math.nan, math.nan, math.nan)
        if higher_is_better:
            return cls(float(np.mean(v)), float(np.percentile(v, 10.0)), float(np.min(v)))
        return cls(float(np.mean(v)), float(np.percentile(v, 90.0)), float(np.max(v)))


def _met(value: float, target: tuple[str, float] | None) -> bool | None:
    if target is None or not math.isfinite(value):
        return None
    op, bound = target
    return value <= bound if op == "<=" else value >= bound


def bearing_gain(with_bearing: Sequence[float], without: Sequence[float]
                 ) -> tuple[float, float, float]:
    """Paired difference (with - without) over seeds: mean, standard error and maximum."""
    d = np.asarray(with_bearing, dtype=np.float64) - np.asarray(without, dtype=np.float64)
    if d.size < 2:
        return float(np.mean(d)) if d.size else math.nan, math.nan, \
            float(np.max(d)) if d.size else math.nan
    return float(np.mean(d)), float(np.std(d, ddof=1) / np.sqrt(d.size)), float(np.max(d))


def run_bench(*, seeds: Sequence[int] = HELD_OUT_SEEDS, quick: bool = False,
              progress: Callable[[str], None] | None = None,
              only: Sequence[str] | None = None, engine: Engine | None = None
              ) -> list[BenchRow]:
    """Run every case on ``seeds`` (``quick``: a subset, first seed) and return the rows.

    ``only`` keeps the cases whose label contains one of the strings. Cases and seeds are
    independent items mapped by ``engine`` (one process by default); the rows do not depend
    on the engine. ``met`` judges the 90th percentile over the seeds (the 10th for a
    higher-is-better metric); a bearing row must also improve on its reference row by more
    than :data:`NOISE_SIGMAS` standard errors of the paired difference.
    """
    seed_list = [int(s) for s in seeds][:1] if quick else [int(s) for s in seeds]
    if not seed_list:
        raise InputError("no seeds", where="seeds", expected="at least one seed")
    selected = [c for c in cases() if (c.quick or not quick)
                and (not only or any(s in c.label for s in only))]
    items = [BenchItem(c.label, s) for c in selected for s in seed_list]
    eng = engine or LocalEngine(workers=1)

    def tick(done: int, total: int) -> None:
        if progress is not None:
            progress(f"{done}/{total} case-seeds")

    values = values_or_raise(eng.map(run_item, items, progress=tick), where="bench papers")
    per_case: dict[str, list[dict[str, list[float]]]] = {}
    for it, v in zip(items, values, strict=True):
        per_case.setdefault(it.case, []).append(v)
    rows: list[BenchRow] = []
    done: dict[tuple[str, str], list[float]] = {}
    for case in selected:
        runs = per_case[case.label]
        for k, m in enumerate(case.metrics):
            paper_v = [r["paper"][k] for r in runs]
            default_v = [r["default"][k] for r in runs]
            ps = SeedStats.of(paper_v, m.higher_is_better)
            ds = SeedStats.of(default_v, m.higher_is_better)
            target = "-" if m.target is None else f"{m.target[0]} {m.target[1]:g}"
            met = _met(ds.p90, m.target)
            note = m.note
            ref = done.get((case.relative_to or "", m.label))
            if ref is not None:
                mean_d, se_d, max_d = bearing_gain(default_v, ref)
                better = math.isfinite(se_d) and mean_d + NOISE_SIGMAS * se_d < 0.0
                target = (f"{'' if target == '-' else target + ' and '}below w/o bearing "
                          f"by > {NOISE_SIGMAS:g} s.e.")
                met = better if met is None else (met and better)
                note = (f"with - without bearing: mean {mean_d:+.2f} m, s.e. {se_d:.2f} m, "
                        f"worst seed {max_d:+.2f} m")
            done[(case.label, m.label)] = default_v
            rows.append(BenchRow(case.label, m.label, m.paper, case.paper_preset, ps, ds,
                                 target, met, len(seed_list), note, m.higher_is_better))
    return rows


def parse_seeds(text: str) -> tuple[int, ...]:
    """Seeds from the command line: ``held-out``, ``dev``, ``A-B`` (inclusive) or ``a,b,c``."""
    t = text.strip()
    if t == "held-out":
        return HELD_OUT_SEEDS
    if t == "dev":
        return DEV_SEEDS
    try:
        if "-" in t and "," not in t:
            lo, hi = (int(v) for v in t.split("-", 1))
            if hi < lo:
                raise ValueError
            return tuple(range(lo, hi + 1))
        seeds = tuple(int(v) for v in t.split(",") if v.strip())
    except ValueError:
        raise InputError(f"seeds {text!r}", where="--seeds",
                         expected="held-out, dev, A-B or a comma list of integers") from None
    if not seeds or min(seeds) < 0:
        raise InputError(f"seeds {text!r}", where="--seeds", expected="non-negative integers")
    return seeds


def describe_seeds(seeds: Sequence[int]) -> str:
    """``held-out seeds 100-129`` / ``development seeds 0-9`` / ``seeds 3, 5``."""
    s = tuple(seeds)
    kind = ("held-out " if set(s) <= set(HELD_OUT_SEEDS) else
            "development " if set(s) <= set(DEV_SEEDS) else "")
    if len(s) > 2 and s == tuple(range(s[0], s[-1] + 1)):
        return f"{kind}seeds {s[0]}-{s[-1]} ({len(s)})"
    return f"{kind}seed{'s' if len(s) > 1 else ''} " + ", ".join(str(v) for v in s)


def _fmt(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v:.2f}"


def stats_text(st: SeedStats) -> str:
    """``mean / p90 / worst`` of one preset."""
    return f"{_fmt(st.mean)} / {_fmt(st.p90)} / {_fmt(st.worst)}"


def markdown_table(rows: Sequence[BenchRow]) -> str:
    """The rows as the Markdown table of the README (one line per row, trailing newline)."""
    head = ("| scenario | metric | paper | paper preset: mean / p90 / worst "
            "| default: mean / p90 / worst | default mean beats paper | our goal (on p90) "
            "| met |\n|---|---|---|---|---|---|---|---|\n")
    lines = []
    for r in rows:
        met = "-" if r.met is None else ("yes" if r.met else "no")
        beats = "-" if r.beats_paper is None else ("yes" if r.beats_paper else "no")
        cells = [r.scenario, r.metric, r.paper, f"{r.paper_preset}: {stats_text(r.paper_stats)}",
                 stats_text(r.default_stats), beats, r.target, met]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return head + "\n".join(lines) + "\n"
