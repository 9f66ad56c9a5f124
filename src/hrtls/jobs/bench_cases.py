"""The cases of ``hrtls bench papers``: scenario, options, paper preset and metrics."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from hrtls.jobs import bench_studies
from hrtls.jobs.bench_metrics import (
    Metric,
    activity_correct,
    basso_ime,
    checkpoint_max,
    checkpoint_mean,
    floors_correct,
    max_error,
    mean_error,
    p90_error,
    p97_axis,
    rss_gain,
    speed_rmse,
)
from hrtls.pipeline import TrackerConfig
from hrtls.pipeline.config import TagsConfig
from hrtls.sim.scenarios import TARRIO_OFFICE_TABLE


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


def thesis_stairs(config: TrackerConfig) -> TrackerConfig:
    """The thesis' multi-floor rescuer: LDA activity (stairs from it), no barometer."""
    return config.model_copy(update={
        "name": f"{config.name} (LDA, no barometer)", "barometer": False,
        "gait": config.gait.model_copy(update={"activity": "lda"})})


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
                            paper_config=fixes_every(tp), default_config=fixes_every(tp),
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
    return out + _two_user_prediction_cases() + _study_cases()


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
             quick=False, study=bench_studies.loose_cooperation),
        Case(f"wsn_tight ({bench_studies.TIGHT_NETWORKS} networks of 50 nodes, no anchors)",
             "wsn", {}, "robot + Algorithm 1", [
                 MetricSpec("networks fully localized [share]", None,
                            "all (Figs. 6.13-6.16: every example network)", (">=", 1.0),
                            higher_is_better=True),
                 MetricSpec("position RMSE after refinement [rho]", None,
                            "- (not reported)")],
             quick=False, study=bench_studies.tight_cooperation)]


def fixes_every(tp: float) -> Callable[[TrackerConfig], TrackerConfig]:
    """A configuration change: camera fixes on, every ``tp`` seconds."""
    def apply(config: TrackerConfig) -> TrackerConfig:
        return config.model_copy(update={"fixes": config.fixes.model_copy(
            update={"period_s": tp, "enabled": True})})

    return apply
