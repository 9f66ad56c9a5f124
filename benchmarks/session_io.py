"""Session I/O speed and memory, side by side with their targets (issue 20).

* read a 1 M-row ``imu.csv`` into a validated session vs ``pandas.read_csv`` of the same file
  (target <= 1.5x), and the same session as Parquet (target <= 0.2x of ``pandas.read_csv``; the
  ratio to the CSV session read is shown too);
* ``hrtls track`` end to end on a two-hour simulated recording vs the tracker's own time
  (target <= 2x), in a child process: its CPU time (all threads) over the CPU time of the
  tracker's calls (``Tracker.update`` and ``finish``, their thread alone: the IMU is read on
  another meanwhile), timed in the child with the other phases (imports, reading, evaluation,
  writing), one row each; the wall ratio (end to end over the tracker's calls) is shown too,
  but under load both grow with the other jobs on the machine, CPU times do not; the CPU of
  the child's main thread (the tracker's calls among it) is a floor of its wall time even on
  idle cores;
  ``--baseline-src PATH`` runs the same children on another checkout's ``src`` (e.g. the
  main branch), interleaved round by round with this one, and ``--jit-row`` this code with
  the JIT kernels only (``HRTLS_AOT=0``: not the ones ``hrtls warmup`` compiled ahead of time);
* the same on the recording converted to Parquet (``hrtls convert --to parquet``), a second
  row without a target;
* peak memory (the child's own ``VmHWM``) of ``hrtls track`` on an eight-hour
  simulated recording (target < 1 GB).

The children of ``hrtls track`` run ``--track-repeat`` times each; the table shows the round
of least CPU time and the spread of the per-round ratio. The hrtls sources are byte-compiled
first (``compileall``), as ``pip install`` does: where ``PYTHONDONTWRITEBYTECODE`` is set
every child would otherwise compile them again. ``--no-bytecode`` measures that case (it
deletes the bytecode of hrtls and the children do not write it).

The readers run interleaved, ``--repeat`` rounds, so each round compares them under the same
load; the table shows the best round (CPU seconds of all threads, and wall seconds) and the
spread of the per-round ratio (min / median / max). Run: ``python benchmarks/session_io.py
[--rows N] [--repeat 5] [--track-repeat 3] [--hours-track 2] [--hours-memory 8] [--skip-track]
[--skip-read] [--no-bytecode] [--baseline-src PATH] [--jit-row]``; simulated sessions are
cached under ``--work``.
"""

from __future__ import annotations

import argparse
import compileall
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import hrtls
from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import read_session, write_session

HRTLS = [sys.executable, "-c", "from hrtls.cli.app import main; main()"]
"""The ``hrtls`` command in a child process of this interpreter."""
SOURCES = str(Path(hrtls.__file__).resolve().parents[1])
"""Where this interpreter's hrtls is: the child runs the same code."""
PEAK = ("import atexit, re; atexit.register(lambda: print('VmHWM', re.search("
        "r'VmHWM:\\s*(\\d+)', open('/proc/self/status').read()).group(1)))\n")
"""Prints the process's own peak RSS (kB) at exit: ``ru_maxrss`` of a child also counts the
parent's memory at the fork, which ``execve`` keeps."""


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(CPU s of all threads, wall s) of one call."""
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def simulated(work: Path, hours: float) -> Path:
    path = work / f"walk_{hours:g}h"
    if not (path / "session.json").exists():
        subprocess.run([*HRTLS, "simulate", "office_random_walk",
                        "-o", str(path), "-O", f"duration_s={hours * 3600:g}", "--overwrite"],
                       check=True, capture_output=True)
    return path


CHILD_ENV: dict[str, str] = {"COLUMNS": "200", "MPLBACKEND": "Agg", "PYTHONPATH": SOURCES}
"""Environment of the children, over this process's own."""


def _child(args: list[str], src: str | None = None,
           env: dict[str, str] | None = None) -> tuple[str, float, float, float]:
    """(output, wall s, CPU s, peak MB) of one ``python -c`` child process.

    CPU: the child's own rusage (``wait4``); peak memory: its ``VmHWM`` (:data:`PEAK`).
    ``src``: the hrtls sources the child imports (default :data:`SOURCES`).
    """
    args = [*args[:2], PEAK + args[2], *args[3:]]
    with tempfile.TemporaryFile("w+") as log:
        w0 = time.perf_counter()
        proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, text=True,
                                env={**os.environ, **CHILD_ENV, **(
                                    {"PYTHONPATH": src} if src else {}), **(env or {})})
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - w0
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        text = log.read()
    if proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, args, text)
    found = re.search(r"VmHWM (\d+)", text)
    peak_mb = float(found.group(1)) / 1e3 if found else float("nan")
    return text, wall, usage.ru_utime + usage.ru_stime, peak_mb


def track_child(session: Path, out: Path) -> tuple[float, float, float, float]:
    """(wall s, CPU s, tracker s, peak MB) of ``hrtls track`` in a child process."""
    text, wall, cpu, peak_mb = _child([*HRTLS, "track", str(session), "-o", str(out),
                                       "--overwrite"])
    found = re.search(r"IMU samples in ([0-9.]+) s", text)
    tracker_s = float(found.group(1)) if found else float("nan")
    return wall, cpu, tracker_s, peak_mb


BREAKDOWN = """
import collections, contextlib, io, sys, time
T0 = time.process_time()
from hrtls.cli.app import main
import hrtls.jobs.track as J, hrtls.io.stream as S, hrtls.pipeline.tracker as TR
import hrtls.recordings
spent = collections.defaultdict(float)
spent["imports"] = time.process_time() - T0
def timed_method(owner, name, label, clock=time.process_time):
    fn = getattr(owner, name, None)
    if fn is None:  # an older or newer checkout (--baseline-src) without it
        return
    def wrapper(*a, **k):
        c0 = clock()
        try:
            return fn(*a, **k)
        finally:
            spent[label] += clock() - c0
    setattr(owner, name, wrapper)
for owner, name, label in [
        (J, "track_recording", "track_recording"), (S.SessionStream, "start_imu", "read IMU whole"),
        (J, "evaluate_track", "evaluation"), (J, "write_track_outputs", "write outputs")]:
    timed_method(owner, name, label)
# the CPU of their own thread alone: the readers run on others meanwhile
for owner, name, label in [(TR.Tracker, "update", "tracker"), (TR.Tracker, "finish", "tracker"),
                           (S.SessionStream, "truth", "read truth")]:
    timed_method(owner, name, label, time.thread_time)
# within the phases above, not added to them: numba's kernels on their first call (the
# compiled code loaded from the cache, numba's target set up on the first), by thread CPU;
# with the ahead-of-time build, its loading (numba is then imported only for a kernel it lacks)
within = collections.defaultdict(float)
def timed_within(owner, name, label, count=None):
    fn = getattr(owner, name)
    def wrapper(*a, **k):
        c0 = time.thread_time()
        out = fn(*a, **k)
        within[label] += time.thread_time() - c0
        if count:
            within[count(out)] += 1
        return out
    setattr(owner, name, wrapper)
def numba_timers():
    import numba.core.caching as NC, numba.core.dispatcher as ND
    timed_within(NC.Cache, "load_overload", "numba cache loads",
                 lambda out: "numba cache misses" if out is None else "numba cache hits")
    timed_within(ND.Dispatcher, "compile", "numba first calls")
try:
    import hrtls.kernels as HK
except ImportError:  # an older checkout (--baseline-src): numba imported with the modules
    numba_timers()
else:
    timed_within(HK, "_load", "ahead-of-time kernels loaded")
    first_numba = HK._numba
    def numba_then_timers():
        if HK._STATE["numba"] is None:
            c0 = time.thread_time()
            first_numba()
            within["numba imported for the JIT"] += time.thread_time() - c0
            numba_timers()
        return first_numba()
    HK._numba = numba_then_timers
sys.argv = ["hrtls", "track", *sys.argv[1:]]
shown = io.StringIO()
with contextlib.redirect_stdout(shown):
    try:
        main()
    except SystemExit:
        pass
print(shown.getvalue())
spent["total"] = time.process_time() - T0
# the main thread's own CPU: what the wall time cannot fall below even on idle cores
within["main thread"] = time.thread_time()
spent["read the rest (open, chunks, other tables)"] = spent.pop("track_recording") - sum(
    spent[k] for k in ("read IMU whole", "read truth", "tracker"))
for k in [k for k, v in spent.items() if v == 0.0]:
    del spent[k]
spent["other (options, report on screen)"] = spent["total"] - sum(
    v for k, v in spent.items() if k != "total")
for k, v in spent.items():
    print(f"PHASE {k}={v:.3f}")
for k, v in within.items():
    print(f"WITHIN {k}={v:.3f}")
"""
"""One ``hrtls track`` in a child, CPU seconds per phase: its functions are wrapped by timers
only ("imports" is what the command imports before any work, a cost that does not grow with
the recording)."""


Round = tuple[dict[str, float], float, float, float, float]
"""(CPU s by phase, wall s, CPU s, tracker wall s, peak MB) of one child."""


def phases_child(session: Path, out: Path, src: str | None = None,
                 env: dict[str, str] | None = None) -> Round:
    """One ``hrtls track`` in a child whose phases are timed (:data:`BREAKDOWN`)."""
    text, wall, cpu, peak_mb = _child([sys.executable, "-c", BREAKDOWN, str(session), "-o",
                                       str(out), "--overwrite"], src, env)
    phases = {k: float(v) for k, v in re.findall(r"PHASE (.+)=([0-9.]+)", text)}
    phases |= {f"within {k}": float(v) for k, v in re.findall(r"WITHIN (.+)=([0-9.]+)", text)}
    found = re.search(r"IMU samples in ([0-9.]+) s", text)
    return phases, wall, cpu, float(found.group(1)) if found else float("nan"), peak_mb


def _spread(ratios: list[float]) -> str:
    return f"{min(ratios):.2f} / {statistics.median(ratios):.2f} / {max(ratios):.2f}"


def reading(n: int, repeat: int, table: Table) -> None:
    import pandas as pd  # the bench extra; only this comparison needs it

    rng = np.random.default_rng(0)
    t = np.arange(n) / 100.0
    imu = ImuStream(SensorSeries(t, rng.normal([0, 0, 9.81], 1.0, (n, 3)), "acc"),
                    SensorSeries(t, rng.normal(0, 0.5, (n, 3)), "gyro"),
                    SensorSeries(t, rng.normal([20, 0, -40], 2.0, (n, 3)), "mag"))
    with tempfile.TemporaryDirectory() as tmp:
        csv_dir, pq_dir = Path(tmp) / "csv", Path(tmp) / "pq"
        write_session(Session(imu=imu), csv_dir)
        write_session(Session(imu=imu), pq_dir, table_format="parquet")
        del imu
        readers: dict[str, Callable[[], object]] = {
            "pandas.read_csv imu.csv": lambda: pd.read_csv(csv_dir / "imu.csv"),
            "read_session csv": lambda: read_session(csv_dir),
            "read_session parquet": lambda: read_session(pq_dir),
        }
        for fn in readers.values():
            fn()  # warm the page cache and imports
        runs: dict[str, list[tuple[float, float]]] = {k: [] for k in readers}
        for _ in range(repeat):
            for label, fn in readers.items():
                runs[label].append(timed(fn))
    pandas_runs = runs["pandas.read_csv imu.csv"]
    best = {k: (min(r[0] for r in v), min(r[1] for r in v)) for k, v in runs.items()}
    pandas_cpu, pandas_wall = best["pandas.read_csv imu.csv"]
    for label, (cpu, wall) in best.items():
        ratio = target = spread = ok = ""
        if label == "read_session csv":
            r = cpu / pandas_cpu
            ratio = f"{r:.2f}x pandas ({wall / pandas_wall:.2f}x wall)"
            target, ok = "<= 1.5x pandas", "yes" if r <= 1.5 else "NO"
            spread = _spread([a[0] / b[0] for a, b in zip(runs[label], pandas_runs, strict=True)])
        elif label == "read_session parquet":
            r = cpu / pandas_cpu
            ratio = (f"{r:.2f}x pandas ({wall / pandas_wall:.2f}x wall), "
                     f"{cpu / best['read_session csv'][0]:.2f}x csv")
            target, ok = "<= 0.2x pandas", "yes" if r <= 0.2 else "NO"
            spread = _spread([a[0] / b[0] for a, b in zip(runs[label], pandas_runs, strict=True)])
        table.add_row(f"{label} ({n:,} rows)", f"{cpu:.2f}", f"{wall:.2f}", ratio, spread,
                      target, ok)


def parquet_copy(session: Path) -> Path:
    path = session.with_name(session.name + "_parquet")
    if not (path / "session.json").exists():
        subprocess.run([*HRTLS, "convert", str(session), "-o", str(path), "--to", "parquet",
                        "--overwrite"], check=True, capture_output=True)
    return path


def track_rows(label: str, session: Path, out: Path, repeat: int, table: Table,
               target: bool, baseline: str | None = None, jit: bool = False) -> None:
    """``hrtls track`` of ``session`` ``repeat`` times: the round of least CPU, by phase.

    With ``baseline`` (another checkout's sources) its rounds alternate with this code's; with
    ``jit`` also this code with the JIT kernels only (``HRTLS_AOT=0``).
    """
    runs: dict[str, list[Round]] = {label: []}
    jit_label = f"{label}, JIT kernels only (HRTLS_AOT=0)"
    if jit:
        runs[jit_label] = []
    if baseline:
        runs[f"{label}, baseline {baseline}"] = []
    for _ in range(repeat):
        runs[label].append(phases_child(session, out))
        if jit:
            runs[jit_label].append(phases_child(session, out, env={"HRTLS_AOT": "0"}))
        if baseline:
            runs[f"{label}, baseline {baseline}"].append(phases_child(session, out, baseline))
    for name, rounds in runs.items():
        _track_row(name, rounds, table, target and name == label)


def _track_row(label: str, rounds: list[Round], table: Table, target: bool) -> None:
    ratios = [r[2] / r[0]["tracker"] for r in rounds]
    wall_ratios = [r[1] / r[3] for r in rounds]
    phases, wall, cpu, tracker_wall, peak_mb = min(rounds, key=lambda r: r[2])
    tracker = phases["tracker"]
    table.add_row(f"{label} (tracker {tracker:.2f} s CPU, {tracker_wall:.2f} s wall)",
                  f"{cpu:.2f}", f"{wall:.2f}",
                  f"{cpu / tracker:.2f}x tracker (CPU / CPU), {wall / tracker_wall:.2f}x (wall "
                  f"/ wall; per round {_spread(wall_ratios)}); {peak_mb:,.0f} MB",
                  _spread(ratios), "<= 2x" if target else "",
                  ("yes" if cpu / tracker <= 2 else "NO") if target else "")
    phases["interpreter start and exit"] = cpu - phases.pop("total")
    within = {k.removeprefix("within "): phases.pop(k) for k in list(phases)
              if k.startswith("within ")}
    for name, value in phases.items():
        table.add_row(f"  {name}", f"{value:.2f}", "",
                      f"{value / tracker:.2f}x tracker, {value / cpu:.0%}", "", "", "")
    if "main thread" in within:  # the other rows' CPU on the main thread, with the tracker
        main = within["main thread"]
        table.add_row("  within those: on the main thread (a floor of the wall time)",
                      f"{main:.2f}", "", f"{main / tracker:.2f}x tracker", "", "", "")
    for name in ("ahead-of-time kernels loaded", "numba imported for the JIT"):
        if name in within:  # part of the tracker's and the readers' rows
            table.add_row(f"  within those: {name}", f"{within[name]:.2f}", "",
                          f"{within[name] / tracker:.2f}x tracker", "", "", "")
    if "numba first calls" in within:  # part of the tracker's and the readers' rows
        first = within["numba first calls"]
        table.add_row(
            f"  within those: numba first calls ({within.get('numba cache hits', 0):.0f} "
            f"loaded from the cache, {within.get('numba cache misses', 0):.0f} misses)",
            f"{first:.2f}", "", f"{first / tracker:.2f}x tracker, {first / cpu:.0%}; loading "
            f"{within.get('numba cache loads', 0.0):.2f} s", "", "", "")


def tracking(args: argparse.Namespace, table: Table) -> None:
    args.work.mkdir(parents=True, exist_ok=True)
    s2, s8 = simulated(args.work, args.hours_track), simulated(args.work, args.hours_memory)
    phases_child(s2, args.work / "out_track")  # the page cache and the kernel cache warm
    track_rows(f"hrtls track {args.hours_track:g} h", s2, args.work / "out_track",
               args.track_repeat, table, target=True, baseline=args.baseline_src,
               jit=args.jit_row)
    if not args.skip_parquet:
        track_rows(f"hrtls track {args.hours_track:g} h, Parquet", parquet_copy(s2),
                   args.work / "out_track_parquet", args.track_repeat, table, target=False)
    wall, cpu, tracker_s, peak_mb = track_child(s8, args.work / "out_memory")
    table.add_row(f"hrtls track {args.hours_memory:g} h peak memory (tracker {tracker_s:.2f} s)",
                  f"{cpu:.2f}", f"{wall:.2f}", f"{peak_mb:,.0f} MB", "", "< 1000 MB",
                  "yes" if peak_mb < 1000 else "NO")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--hours-track", type=float, default=2.0)
    parser.add_argument("--hours-memory", type=float, default=8.0)
    parser.add_argument("--skip-track", action="store_true")
    parser.add_argument("--skip-read", action="store_true")
    parser.add_argument("--skip-parquet", action="store_true")
    parser.add_argument("--track-repeat", type=int, default=3)
    parser.add_argument("--no-bytecode", action="store_true")
    parser.add_argument("--baseline-src", default=None,
                        help="another checkout's src folder, tracked in alternate rounds")
    parser.add_argument("--jit-row", action="store_true",
                        help="also this code with the JIT kernels only, in alternate rounds")
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "hrtls-io")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    if args.no_bytecode:  # the compiled kernels beside the bytecode stay
        for pyc in (Path(SOURCES) / "hrtls").rglob("__pycache__/*.pyc"):
            pyc.unlink()
        CHILD_ENV["PYTHONDONTWRITEBYTECODE"] = "1"
    else:
        for src in (SOURCES, args.baseline_src):
            if src:
                compileall.compile_dir(Path(src) / "hrtls", quiet=1)
    table = Table("measure", "CPU s", "wall s", "ratio (best round)",
                  "CPU ratio min / median / max", "target", "ok", title="session I/O")
    if not args.skip_read:
        reading(args.rows, args.repeat, table)
    if not args.skip_track:
        tracking(args, table)
    Console(width=200).print(table)


if __name__ == "__main__":
    main()
