"""Speed of ``hrtls track``: IMU samples per second per preset on an hour-long simulated walk.

Usage: ``python benchmarks/track_speed.py [--duration-s 3600] [--repeat 2]
[--presets default tarrio2011] [--baseline REV | --no-baseline] [--wall-time] [--parts]``.

The session is ``office_random_walk`` (cameras, 8 BLE beacons, RFID tags, range nodes), so every
correction runs. It is written once as a session folder and read back, and each preset tracks
it ``repeat`` times after one warm-up run (numba compilation); the best time is reported,
split into attitude + gait (per-sample stages, best of their own runs) and the rest (events:
corrections, event loop, result assembly). Times are process CPU time unless ``--wall-time``.

Side by side, the same session is tracked by the code of ``--baseline`` (a git revision of this
repository, default: the main branch before issue 12, the causal / restorable tracker), in a
subprocess that imports that revision's ``src``; the ratio is baseline time / our time.

``--parts`` also splits each preset's run into the tracker's parts (:data:`PARTS`, exclusive
times: a part's time without the parts it calls; best of the runs per part).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console
from rich.table import Table

from hrtls.data import Session
from hrtls.io.session import read_session, write_session
from hrtls.pipeline import PRESETS, Tracker, preset
from hrtls.sim.scenarios import run_scenario

BASELINE_REV = "29f96f6"
"""Main before issue 12 (whole-recording hard iron and mounting, one tracker class)."""
TARGET_SAMPLES_S = 2_000_000
TARGET_RATIO = 1.6
PARTS = (("IMU alignment", "hrtls.data.series", "ImuStream", "aligned"),
         ("attitude (without hard iron)", "hrtls.pipeline.imu_stage", "AttitudeStage", "update"),
         ("running hard-iron fit", "hrtls.calibration.hard_iron_running", "RunningHardIron",
          "update"),
         ("gait stage", "hrtls.gait.analyzer", "GaitAnalyzer", "update"),
         ("event loop scheduling", "hrtls.pipeline.engine", "FusionEngine", "drain"),
         ("compiled runs (with their Python)", "hrtls.pipeline.engine", "FusionEngine",
          "_run_kernel"),
         ("fixes, tag groups (Python)", "hrtls.pipeline.engine", "", "apply_observation"),
         ("result (finish)", "hrtls.pipeline.tracker", "Tracker", "finish"))
"""(label, module, class ('' for a module function), function) of the timed parts."""

_BASELINE_RUN = """
import json, sys, time, warnings
warnings.simplefilter("ignore")
from hrtls.io.session import read_session
from hrtls.pipeline import Tracker, preset
s = read_session(sys.argv[1])
out = {}
for name in sys.argv[4:]:
    try:
        cfg = preset(name)
    except Exception:
        continue
    Tracker(cfg).run(s)
    best = float("inf")
    for _ in range(int(sys.argv[3])):
        t0 = CLOCK()
        Tracker(cfg).run(s)
        best = min(best, CLOCK() - t0)
    out[name] = best
print(json.dumps(out))
"""


def baseline_times(rev: str, session_dir: Path, presets: list[str], repeat: int,
                   wall: bool, work: Path) -> dict[str, float] | str:
    """Best time per preset of revision ``rev`` (or the reason it could not run)."""
    repo = Path(__file__).resolve().parents[1]
    src = work / "baseline"
    src.mkdir()
    try:
        archive = subprocess.run(["git", "-C", str(repo), "archive", rev, "src"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    except (OSError, subprocess.CalledProcessError) as exc:
        return f"baseline {rev} not available ({exc})"
    code = _BASELINE_RUN.replace("CLOCK", "time.perf_counter" if wall else "time.process_time")
    env = {**os.environ, "PYTHONPATH": str(src / "src")}
    run = subprocess.run([sys.executable, "-c", code, str(session_dir), rev, str(repeat),
                          *presets], capture_output=True, text=True, env=env)
    if run.returncode != 0:
        return f"baseline {rev} failed: {run.stderr.strip().splitlines()[-1:]}"
    return {k: float(v) for k, v in json.loads(run.stdout.strip().splitlines()[-1]).items()}


def main() -> None:
    """Print one row per preset."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--presets", nargs="*", default=list(PRESETS),
                    help="presets to time (default: all)")
    ap.add_argument("--baseline", default=BASELINE_REV,
                    help=f"git revision to compare with (default {BASELINE_REV})")
    ap.add_argument("--no-baseline", action="store_true", help="time this code only")
    ap.add_argument("--parts", action="store_true", help="also time the tracker's parts")
    ap.add_argument("--wall-time", action="store_true",
                    help="time with the wall clock (default: process CPU time, steadier on a "
                         "shared machine)")
    args = ap.parse_args()
    clock = time.perf_counter if args.wall_time else time.process_time
    warnings.simplefilter("ignore")
    console = Console(width=150)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        with console.status("simulating"):
            sim = run_scenario("office_random_walk", args.seed, duration_s=args.duration_s)
            write_session(sim.session.with_parts(truth=None), work / "session")
            s = read_session(work / "session")
        assert s.imu is not None
        n = len(s.imu.accel)
        console.print(f"office_random_walk {args.duration_s:.0f} s, seed {args.seed}: {n:,} IMU "
                      f"samples, {len(s.rss or [])} RSS, {len(s.ranges or [])} ranges, "
                      f"{len(s.tags or [])} tag reads, {len(s.fixes or [])} fixes")
        base: dict[str, float] | str = "not run (--no-baseline)"
        if not args.no_baseline:
            with console.status(f"timing the baseline {args.baseline}"):
                base = baseline_times(args.baseline, work / "session", args.presets,
                                      args.repeat, args.wall_time, work)
        rows = []
        for name in args.presets:
            rows.append((name, *_time_preset(s, name, args.repeat, clock)))
    table = Table("preset", "seconds", "samples/s", "attitude+gait s", "events s",
                  "trajectory rows", f"baseline {args.baseline} s", "ratio",
                  title="hrtls track speed (one core, best of runs, "
                  f"{'wall' if args.wall_time else 'CPU'} time)")
    for name, total, stage, n_rows in rows:
        b = base.get(name) if isinstance(base, dict) else None
        table.add_row(name, f"{total:.2f}", f"{n / total:,.0f}", f"{stage:.2f}",
                      f"{max(total - stage, 0.0):.2f}", f"{n_rows:,}",
                      "-" if b is None else f"{b:.2f}", "-" if b is None else f"{b / total:.2f}")
    console.print(table)
    if isinstance(base, str):
        console.print(base)
    console.print(f"targets (issue 12, default preset): >= {TARGET_SAMPLES_S:,} samples/s, "
                  f"ratio >= {TARGET_RATIO}")
    if args.parts:
        parts = Table("part", *args.presets, title="exclusive time per part, ms (best of runs)")
        times = [_time_parts(s, name, args.repeat, clock) for name in args.presets]
        for label in [*(p[0] for p in PARTS), "rest", "total"]:
            parts.add_row(label, *(f"{t[label] * 1e3:.1f}" for t in times))
        console.print(parts)


@contextmanager
def _timed_parts(clock: Callable[[], float], acc: dict[str, float]) -> Iterator[None]:
    """Wrap the functions of :data:`PARTS` to add their exclusive times to ``acc``."""
    stack: list[float] = []    # time spent in the callees of each open call
    saved = []
    for label, module, cls, name in PARTS:
        owner = getattr(importlib.import_module(module), cls) if cls else \
            importlib.import_module(module)
        func = getattr(owner, name)
        saved.append((owner, name, func))

        def timed(*a: object, _f: Callable[..., object] = func, _label: str = label,
                  **k: object) -> object:
            stack.append(0.0)
            t0 = clock()
            try:
                return _f(*a, **k)
            finally:
                dt = clock() - t0
                inner = stack.pop()
                acc[_label] = acc.get(_label, 0.0) + dt - inner
                if stack:
                    stack[-1] += dt
        setattr(owner, name, timed)
    try:
        yield
    finally:
        for owner, name, func in saved:
            setattr(owner, name, func)


def _time_parts(s: Session, name: str, repeat: int, clock: Callable[[], float]
                ) -> dict[str, float]:
    """Best exclusive time of each part over ``repeat`` runs (and the rest, the total)."""
    cfg = preset(name)
    best: dict[str, float] = {}
    for _ in range(max(1, repeat)):
        acc: dict[str, float] = {}
        with _timed_parts(clock, acc):
            t0 = clock()
            Tracker(cfg).run(s)
            total = clock() - t0
        acc["rest"] = total - sum(acc.values())
        acc["total"] = total
        for k, v in acc.items():
            best[k] = min(best.get(k, float("inf")), v)
    return {label: best.get(label, 0.0) for label in [*(p[0] for p in PARTS), "rest", "total"]}


def _time_preset(s: Session, name: str, repeat: int, clock: Callable[[], float]
                 ) -> tuple[float, float, int]:
    """Best total and per-sample-stage times of one preset, and its trajectory rows."""
    cfg = preset(name)
    Tracker(cfg).run(s)  # warm-up: numba caches
    assert s.imu is not None
    total = stage = float("inf")
    n_rows = 0
    for _ in range(max(1, repeat)):
        tr = Tracker(cfg)
        tr.start_session(s)
        t_stage = clock()
        t_imu, acc, gyr, mag = s.imu.aligned()
        q = None if tr.attitude is None else tr.attitude.update(
            t_imu, acc, gyr, mag, s.orientation, mounting_q_bd=tr.meta.mounting_q_bd,
            state_t=tr.state.t)
        if tr.gait is not None:
            tr.gait.update(t_imu, acc, q)
        stage = min(stage, clock() - t_stage)
        total_t0 = clock()
        result = Tracker(cfg).run(s)
        total = min(total, clock() - total_t0)
        n_rows = len(result.trajectory)
    return total, stage, n_rows


if __name__ == "__main__":
    main()
