"""``hrtls bench papers``: each paper's scenario tracked with its own preset and with ``default``.

For every target of the issue "rescuer filter end to end" the simulated scenario of the paper is
run for several seeds, tracked with the paper's preset and with our ``default`` preset, and
scored the way the paper scored. Each :class:`BenchRow` holds the paper's published figure, the
mean and worst value over the seeds for both presets, the target and whether ``default`` meets
it. The CLI prints the rows as one table; this module never prints.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hrtls.calibration.channel import survey_path_loss
from hrtls.data import ChannelModel, Session
from hrtls.errors import InputError
from hrtls.evaluate.metrics import distance_at
from hrtls.gait.step_length_fit import (
    fit_frequency_law,
    fit_weinberg,
    fit_weinberg_running,
    walks_between_marks,
)
from hrtls.jobs.bench_cases import Case, MetricSpec, cases
from hrtls.jobs.bench_metrics import (
    DEFINITIONS,
    activity_correct,
    p97_axis,
    predicted_track,
    speed_rmse,
)
from hrtls.parallel import Engine, LocalEngine, values_or_raise
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult, run_scenario

__all__ = ["DEFINITIONS", "DEV_SEEDS", "HELD_OUT_SEEDS", "BenchItem", "BenchRow", "SeedStats",
           "activity_correct", "bearing_gain", "calibrate_step_model", "calibrated_session",
           "cases", "describe_seeds", "fit_weinberg_running", "markdown_table", "p97_axis",
           "parse_seeds", "predicted_track", "run_bench", "run_item", "speed_rmse",
           "stats_text", "survey_channel"]


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
    walks, runs = walks_between_marks(steps, t_cut, distance_at(truth, t_cut))
    if config.gait.step_length == "frequency":
        return fit_frequency_law(walks).to_dict()
    model = fit_weinberg(walks).to_dict()
    if config.gait.step_length == "weinberg":
        k_run = fit_weinberg_running(walks, runs)
        if k_run is not None:
            model = {"kind": "weinberg", "k": k_run[0], "k_running": k_run[1]}
    return model


def survey_channel(cal: SimulationResult) -> ChannelModel | None:
    """Tarrio Sec. IV-V: the path-loss law fitted on the calibration course's readings.

    The course is walked with the surveyed positions known (its truth); each reading is paired
    with the horizontal distance from the receiver to its anchor. None without readings.
    """
    rss, truth = cal.session.rss, cal.session.truth
    if rss is None or truth is None or len(rss.t) < 3:
        return None
    return survey_path_loss(receiver_xy=truth.position_at(rss.t)[:, :2],
                            anchors=rss.anchor.tolist(), rss_dbm=rss.rss_dbm,
                            landmarks=cal.session.landmarks)


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
