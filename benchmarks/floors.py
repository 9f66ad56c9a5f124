"""Floor detection (issue 19, item 1) on the simulated two-floor mission and the flat IPIN logs.

* ``inderst_multifloor`` (barometer with noise, weather drift and door steps): the share of time
  on the right floor while the truth is on a floor (ISO/IEC 18305 reading) and over all times,
  with the barometer and without it (stairs from the step model alone: with the preset's
  activity, ``motion`` with the climb detector of ``hrtls.gait.stairs_climb`` for a trunk
  placement, without that detector (no stair steps then), and with the LDA's; with the
  barometer also without the detector), per preset; mean,
  10th percentile, worst and the share of seeds meeting the target (>= 99 % with, >= 95 %
  without). Seeds 0-9 are the
  development seeds the barometric stage was designed on; seeds 100-119 were then looked at to
  understand two failures (so they are no longer held out); ``--seeds`` held-out seeds start at
  ``--first-seed`` (200).
* IPIN 2023 logs (flat, real phone barometer): floor changes and landmarks on the right floor,
  with and without their start pose (``trim_to_start``). Needs ``../shared/data``.

Run: ``python benchmarks/floors.py [--seeds 20] [--presets default,inderst-rfid]
[--engine local|ray] [--workers N]`` (seeds and logs run through ``--engine``,
``benchmarks/_engine.py``).
"""

from __future__ import annotations

import argparse
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from _engine import Batch, add_engine_options
from hrtls.evaluate.floors import floor_detection
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.barometric import with_baro_floors
from hrtls.recordings import read_any
from hrtls.sim.scenarios import run_scenario

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "ipin2023"


@dataclass(frozen=True)
class SeedItem:
    """One simulated seed and the presets to track it with."""

    seed: int
    presets: tuple[str, ...]


def simulated_seed(item: SeedItem) -> dict[tuple[str, str], tuple[float, float]]:
    """Shares on floors and over all times, per (preset, heights from), of one seed."""
    warnings.simplefilter("ignore")
    session = run_scenario("inderst_multifloor", item.seed).session
    out: dict[tuple[str, str], tuple[float, float]] = {}
    for name in item.presets:
        cfg = preset(name)
        # the tracker runs the barometric stage itself; off: stairs from the step model (the
        # preset's activity with and without the climb detector, and the LDA's stairs as the
        # thesis' rescuer has them)
        plain = cfg.model_copy(update={"barometer": False})
        lda = plain.model_copy(update={"gait": cfg.gait.model_copy(update={"activity": "lda"})})
        off = cfg.gait.model_copy(update={"climb_stairs": False})
        plain_off = plain.model_copy(update={"gait": off})
        baro_off = cfg.model_copy(update={"gait": off})
        for label, c in (("step model", plain), ("step model, no climb", plain_off),
                         ("step model, LDA", lda), ("barometer", cfg),
                         ("barometer, no climb", baro_off)):
            result = Tracker(c).run(session)
            f = floor_detection(result.trajectory, session.truth, session.checkpoints,
                                floor_height_m=session.meta.floor_height_m)
            assert f is not None
            out[(name, label)] = (f["time_share_correct_on_floors"], f["time_share_correct"])
    return out


def simulated(batch: Batch, seeds: list[int], presets: list[str]) -> Table:
    table = Table("preset", "heights from", "seeds", "on floors mean", "on floors p10",
                  "on floors worst", "all times mean", "seeds >= target", "target",
                  title=f"inderst_multifloor, seeds {seeds[0]}..{seeds[-1]}")
    rows: dict[tuple[str, str], list[tuple[float, float]]] = {}
    items = [SeedItem(seed, tuple(presets)) for seed in seeds]
    for per_seed in batch.values(simulated_seed, items, label=lambda it: f"seed {it.seed}"):
        for key, value in per_seed.items():
            rows.setdefault(key, []).append(value)
    for (name, label), values in rows.items():
        on = np.array([v[0] for v in values])
        every = np.array([v[1] for v in values])
        target = 0.99 if label.startswith("barometer") else 0.95
        table.add_row(name, label, str(len(on)), f"{on.mean():.4f}",
                      f"{np.percentile(on, 10):.4f}", f"{on.min():.4f}",
                      f"{every.mean():.4f}", f"{np.mean(on >= target):.0%}", f"{target:.2f}")
    return table


@dataclass(frozen=True)
class LogItem:
    """One IPIN log and the presets to track it with."""

    log: Path
    presets: tuple[str, ...]


def ipin_log(item: LogItem) -> list[tuple[str, str, str, str, str, str]]:
    """Table rows of one IPIN log: whole and cut to its start pose, per preset."""
    warnings.simplefilter("ignore")
    rows = []
    for trim in (False, True):
        session = read_any(item.log, trim_to_start=trim)
        for name in item.presets:
            cfg = preset(name)
            result = with_baro_floors(Tracker(cfg).run(session), session, cfg)
            f = floor_detection(result.trajectory, None, session.checkpoints,
                                floor_height_m=session.meta.floor_height_m)
            assert f is not None
            rows.append((item.log.name[10:27], "cut to it" if trim else "whole log", name,
                         str(result.report["floors"].get("floor_changes", "-")),
                         f"{f['checkpoints_correct']:.0%} of {f['checkpoints']}",
                         f"{np.ptp(result.trajectory.xyz[:, 2]):.2f}"))
    return rows


def ipin(batch: Batch, presets: list[str]) -> Table | None:
    logs = sorted(DATA.glob("IPIN2023_*.txt"))
    if not logs:
        return None
    table = Table("log", "start pose", "preset", "floor changes", "landmarks on right floor",
                  "z range m", title="IPIN 2023 logs (flat), real phone barometer")
    items = [LogItem(log, tuple(presets)) for log in logs]
    for rows in batch.values(ipin_log, items, label=lambda it: it.log.name):
        for r in rows:
            table.add_row(*r)
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="held-out seeds")
    parser.add_argument("--first-seed", type=int, default=200,
                        help="first held-out seed (100-119 were looked at while developing)")
    parser.add_argument("--dev", action="store_true", help="the development seeds 0-9 instead")
    parser.add_argument("--presets", default="default,inderst-rfid")
    add_engine_options(parser)
    args = parser.parse_args()
    batch = Batch.of(args)
    presets = args.presets.split(",")
    seeds = list(range(10)) if args.dev else list(range(args.first_seed,
                                                         args.first_seed + args.seeds))
    console = Console(width=150)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        console.print(simulated(batch, seeds, presets))
        real = ipin(batch, sorted({*presets, "handheld-phone"}))
    if real is not None:
        console.print(real)
    batch.finish()


if __name__ == "__main__":
    main()
