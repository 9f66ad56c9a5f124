"""Causal default against the offline two-pass option on the papers' scenarios.

Usage: ``python benchmarks/causal.py [--seeds 100-104] [--only ring ...] [--engine local|ray]``
(the case-seeds run through ``--engine``, ``benchmarks/_engine.py``). For each case of
``hrtls bench papers`` (default: its quick subset) and seed, the ``default`` preset tracks the
calibrated session as the bench does, once causally (the default: running hard-iron fit,
leading-window mounting) and once with ``[offline] two_pass = true`` (hard iron and mounting
fitted on the whole recording first). Prints mean / p90 / worst over the seeds of each metric
and the mean paired difference (causal - two-pass). Seeds 100-129 are the held-out seeds.
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from _engine import Batch, add_engine_options
from hrtls.jobs import bench
from hrtls.jobs.bench import BenchItem, SeedStats, calibrated_session
from hrtls.pipeline import TrackerConfig
from hrtls.sim.scenarios import run_scenario


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(v) for v in text.split(",")]


def _two_pass(cfg: TrackerConfig) -> TrackerConfig:
    return cfg.model_copy(update={"offline": cfg.offline.model_copy(update={"two_pass": True})})


def run_item(item: BenchItem) -> dict[str, list[float]]:
    """Metric values of one case and seed, causal and two-pass."""
    warnings.simplefilter("ignore")
    case = bench._case(item.case)
    sim = run_scenario(case.scenario, item.seed, **case.options)
    cal = run_scenario(case.scenario, item.seed, calibration=True, **case.options)
    blind = sim.session.with_parts(truth=None, checkpoints=None)
    cfg = bench._configs(case)["default"]
    out: dict[str, list[float]] = {}
    for which, c in (("causal", cfg), ("two_pass", _two_pass(cfg))):
        session = calibrated_session(c, blind, cal)
        res = bench._track(c, session)
        scored = dataclasses.replace(sim, session=session.with_parts(
            truth=sim.session.truth, checkpoints=sim.session.checkpoints))
        out[which] = [float(m.fn(res, scored)) for m in case.metrics]
    return out


def main() -> None:
    """Print one row per case and metric."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", default="100-104")
    ap.add_argument("--only", nargs="*", default=None,
                    help="case labels containing any of these (default: the quick subset)")
    add_engine_options(ap)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    batch = Batch.of(args)
    seeds = _seeds(args.seeds)
    cases = [c for c in bench.cases()
             if (c.quick if args.only is None else any(o in c.label for o in args.only))]
    table = Table("case", "metric", "causal mean / p90 / worst", "two-pass mean / p90 / worst",
                  "causal - two-pass (mean)",
                  title=escape(f"default preset, causal vs [offline] two_pass, seeds {args.seeds}"))
    console = Console(width=150)
    items = [BenchItem(c.label, seed) for c in cases for seed in seeds]
    done = batch.map(run_item, items, label=lambda it: f"{it.case} seed {it.seed}")
    for case in cases:
        vals = {which: [v[which] for it, v in done if it.case == case.label]
                for which in ("causal", "two_pass")}
        for k, m in enumerate(case.metrics):
            a = [v[k] for v in vals["causal"]]
            b = [v[k] for v in vals["two_pass"]]
            sa, sb = SeedStats.of(a, m.higher_is_better), SeedStats.of(b, m.higher_is_better)
            table.add_row(case.label, m.label, f"{sa.mean:.2f} / {sa.p90:.2f} / {sa.worst:.2f}",
                          f"{sb.mean:.2f} / {sb.p90:.2f} / {sb.worst:.2f}",
                          f"{float(np.mean(np.subtract(a, b))):+.3f}")
    console.print(table)
    batch.finish()


if __name__ == "__main__":
    main()
