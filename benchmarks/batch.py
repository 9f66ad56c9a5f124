"""Batch speed-up of the engines: many one-hour recordings tracked by 1 process, a local pool
and Ray tasks, side by side in one run; Ray's overhead per task.

Usage::

    python benchmarks/batch.py                        # 100 recordings of 1 h, all engines
    python benchmarks/batch.py --recordings 8 --duration-s 600 --engines local
    python benchmarks/batch.py --overhead-tasks 500   # Ray's per-task overhead only

The recordings are ``office_random_walk`` sessions (cameras, BLE, tags, ranges) written as
session folders; ``--distinct`` of them are simulated (seeds 0, 1, ...) and the batch cycles
through them, since simulating 100 hours would take far longer than tracking them. Every engine
tracks the same task list (read, track, write, score); the summaries must be identical, and the
script checks that before it prints speed-ups.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
import warnings
from pathlib import Path

from rich.console import Console
from rich.table import Table

from hrtls.io.session import write_session
from hrtls.jobs.batch import plan_batch, run_batch
from hrtls.parallel import LocalEngine
from hrtls.runner import make_engine
from hrtls.sim.scenarios import run_scenario


def _noop(x: int) -> int:
    return x


def _make_recordings(root: Path, *, count: int, distinct: int, duration_s: float) -> list[Path]:
    sources = []
    for seed in range(distinct):
        sim = run_scenario("office_random_walk", seed, duration_s=duration_s)
        sources.append(write_session(sim.session, root / "sources" / f"office{seed}"))
    out = []
    for k in range(count):
        link = root / "batch" / f"rec{k:03d}"
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(sources[k % distinct], target_is_directory=True)
        out.append(link)
    return out


def _comparable(rows: tuple[dict, ...]) -> list[tuple]:
    return [(r["status"], r["steps"], r["distance_walked_m"], r["checkpoint_mean_m"],
             r["error_p90_m"]) for r in rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", type=int, default=100)
    ap.add_argument("--distinct", type=int, default=4)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--engines", nargs="*", default=["one-process", "local", "ray"])
    ap.add_argument("--overhead-tasks", type=int, default=200)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    console = Console()
    root = Path(tempfile.mkdtemp(prefix="hrtls-batch-"))
    try:
        with console.status(f"simulating {args.distinct} x {args.duration_s:.0f} s"):
            recs = _make_recordings(root, count=args.recordings, distinct=args.distinct,
                                    duration_s=args.duration_s)
        table = Table("engine", "workers", "recordings", "wall s", "s / recording",
                      "speed-up", "same results",
                      title=f"hrtls track over {args.recordings} recordings of "
                      f"{args.duration_s / 3600:.2g} h ({os.cpu_count()} cores)")
        # warm-up: compile (or load the cached) numba kernels once before any clock runs
        run_batch(plan_batch(recs[:1], root / "warm", preset="default", config_path=None),
                  root / "warm", engine=LocalEngine(workers=1))
        base_s = None
        base_rows = None
        for name in args.engines:
            if name == "one-process":
                engine = LocalEngine(workers=1)
            else:
                engine = make_engine(name, workers=args.workers)
            out = root / f"out-{name}"
            tasks = plan_batch(recs, out, preset="default", config_path=None)
            t0 = time.perf_counter()
            res = run_batch(tasks, out, engine=engine)
            wall = time.perf_counter() - t0
            rows = _comparable(res.rows)
            if base_s is None:
                base_s, base_rows = wall, rows
            table.add_row(name, str(engine.workers), str(len(tasks)), f"{wall:.1f}",
                          f"{wall / len(tasks):.2f}", f"{base_s / wall:.2f}x",
                          "yes" if rows == base_rows else "NO")
            shutil.rmtree(out, ignore_errors=True)
        console.print(table)
        if "ray" in args.engines and args.overhead_tasks > 0:
            engine = make_engine("ray", workers=args.workers)
            engine.map(_noop, list(range(10)))  # warm the workers
            t0 = time.perf_counter()
            engine.map(_noop, list(range(args.overhead_tasks)))
            per = (time.perf_counter() - t0) / args.overhead_tasks
            console.print(f"Ray overhead: {1e3 * per:.2f} ms per task "
                          f"({args.overhead_tasks} no-op tasks, {engine.workers} in flight)")
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
