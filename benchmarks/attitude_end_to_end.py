"""The attitude filters end to end: the tracker with each filter, on real recordings first.

Which filter should the tracker's ``auto`` attitude be? Attitude accuracy alone
(``benchmarks/attitude.py``) does not say: the tracker needs gravity removal for steps, the
walking heading and a covariance. This script runs the tracker with each filter and prints:

1. IPIN 2023 track 3 (real, hand-held phone, ``../shared/data/ipin2023``): landmark errors of
   PDR and of PDR + BLE RSS, the step constant calibrated on the other file
   (:func:`hrtls.jobs.ipin_eval.run_cross_validated`).
2. The papers' simulated scenarios on the *development* seeds (default 0-4; ``--seeds``): the
   bench's metric per case with the ``default`` configuration and only the attitude changed,
   mean / p90 / worst over seeds. Held-out seeds are for the published table only.

    python benchmarks/attitude_end_to_end.py                 # both parts
    python benchmarks/attitude_end_to_end.py --skip-sim      # IPIN only
    python benchmarks/attitude_end_to_end.py --seeds 0-9 --only colombo,basso

The IPIN cases and the case-seeds run through ``--engine`` (``benchmarks/_engine.py``).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from _engine import Batch, add_engine_options
from hrtls.data import Session
from hrtls.datasets.ipin2023 import list_logfiles, load_logfile
from hrtls.jobs import bench
from hrtls.jobs.bench import BenchItem
from hrtls.jobs.ipin_eval import IpinCase, make_config, run_cross_validated
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.scenarios import run_scenario

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data" / "ipin2023"
METHODS = ("quat-ekf", "inertial-lp", "complementary", "euler-ekf")


def _short(name: str) -> str:
    return name.removesuffix(".txt").replace("IPIN2023_T3_TrainingTrial", "T").replace(
        "_repetition", "r")


def with_attitude(config: TrackerConfig, method: str) -> TrackerConfig:
    return config.model_copy(update={"attitude": config.attitude.model_copy(
        update={"method": method})})


@functools.cache
def ipin_sessions(data: Path) -> dict[str, Session]:
    """The IPIN logs cut to their start pose (loaded once per process)."""
    return {n: load_logfile(data, n, trim_to_start=True) for n in list_logfiles(data)}


@dataclass(frozen=True)
class IpinItem:
    """One attitude filter and RSS mode on the IPIN logs."""

    method: str
    rss: str
    data: Path


def ipin_case(item: IpinItem) -> tuple[list[float], float, float]:
    """Landmark p75 per file, pooled p75 and pooled max of one filter and RSS mode."""
    warnings.simplefilter("ignore")
    sessions = ipin_sessions(item.data)
    case = IpinCase(f"{item.method} {item.rss}", make_config(
        attitude=item.method, rss=item.rss, name=f"e2e-{item.method}-{item.rss}"))
    results = run_cross_validated(sessions, case)
    per = [np.inf if r.errors is None else float(r.errors.stats.p75) for r in results]
    pooled = np.concatenate([r.errors.horizontal_m if r.errors is not None
                             else np.full(len(sessions[r.file].checkpoints or ()), np.inf)
                             for r in results])
    return per, float(np.percentile(pooled, 75)), float(pooled.max())


def ipin_part(batch: Batch, methods: tuple[str, ...], data: Path) -> None:
    if not data.is_dir():
        print(f"IPIN: no data at {data}, skipped")
        return
    names = list_logfiles(data)
    print("\nIPIN 2023 track 3 (real): landmark error p75 per file and pooled, m")
    print("| attitude | RSS | " + " | ".join(_short(n) for n in names) + " | pooled p75 | "
          "pooled max |")
    print("|---|---|" + "---|" * (len(names) + 2))
    items = [IpinItem(method, rss, data) for method in methods for rss in ("off", "tight")]
    for it, (per, p75, worst) in batch.map(ipin_case, items,
                                           label=lambda it: f"IPIN {it.method} {it.rss}"):
        print(f"| {it.method} | {it.rss} | " + " | ".join(f"{v:.2f}" for v in per)
              + f" | {p75:.2f} | {worst:.2f} |", flush=True)


@dataclass(frozen=True)
class SimItem:
    """One case and seed, tracked with each attitude filter."""

    case: BenchItem
    methods: tuple[str, ...]


def sim_case_seed(item: SimItem) -> dict[str, list[float]]:
    """The case's metric values per attitude filter on one seed."""
    warnings.simplefilter("ignore")
    case = bench._case(item.case.case)
    seed = item.case.seed
    default_cfg = bench._configs(case)["default"]
    sim = run_scenario(case.scenario, seed, **case.options)
    cal = run_scenario(case.scenario, seed, calibration=True, **case.options)
    blind = sim.session.with_parts(truth=None, checkpoints=None)
    out: dict[str, list[float]] = {}
    for m in item.methods:
        cfg = with_attitude(default_cfg, m)
        session = bench.calibrated_session(cfg, blind, cal)
        res = bench._track(cfg, session)
        scored = dataclasses.replace(sim, session=session.with_parts(
            truth=sim.session.truth, checkpoints=sim.session.checkpoints))
        out[m] = [float(spec.fn(res, scored)) for spec in case.metrics]
    return out


def sim_part(batch: Batch, methods: tuple[str, ...], seeds: tuple[int, ...],
             only: list[str]) -> None:
    print(f"\nsimulated scenarios, {bench.describe_seeds(seeds)}, "
          "configuration 'default' with only the attitude changed: mean / p90 / worst")
    print("| case | metric | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    cases = [c for c in bench.cases()
             if c.quick and not (only and not any(o in c.label for o in only))]
    items = [SimItem(BenchItem(c.label, seed), methods) for c in cases for seed in seeds]
    done = batch.map(sim_case_seed, items,
                     label=lambda it: f"{it.case.case} seed {it.case.seed}")
    for case in cases:
        runs = [v for it, v in done if it.case.case == case.label]
        for k, spec in enumerate(case.metrics):
            cells = []
            for m in methods:
                v = np.array([r[m][k] for r in runs])
                cells.append(f"{v.mean():.2f} / {np.percentile(v, 90):.2f} / {v.max():.2f}")
            print(f"| {case.label} | {spec.label} | " + " | ".join(cells) + " |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--seeds", default="0-4", help="development seeds (A-B or a,b,c)")
    ap.add_argument("--only", default="", help="comma-separated case label parts")
    ap.add_argument("--skip-ipin", action="store_true")
    ap.add_argument("--skip-sim", action="store_true")
    ap.add_argument("--data", type=Path, default=DATA)
    add_engine_options(ap)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    batch = Batch.of(args)
    methods = tuple(m for m in args.methods.split(",") if m)
    seeds = bench.parse_seeds(args.seeds)
    if set(seeds) & set(bench.HELD_OUT_SEEDS):
        ap.error("--seeds: use development seeds; held-out seeds are for the published table")
    if not args.skip_ipin:
        ipin_part(batch, methods, args.data)
    if not args.skip_sim:
        sim_part(batch, methods, seeds, [o for o in args.only.split(",") if o])
    batch.finish()


if __name__ == "__main__":
    main()
