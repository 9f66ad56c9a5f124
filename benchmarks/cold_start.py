"""Cold start of the ``hrtls`` command (issue 19, item 7): wall time of fresh processes.

* ``hrtls --help`` (target < 0.3 s): only the root group and the commands' one-line summaries;
* ``hrtls track --help``: imports the track command's module only;
* ``hrtls formats``: imports the format registry (readers, no tracker).
* ``--demo``: ``hrtls demo`` with an empty kernel cache (a fresh install: every numba kernel is
  compiled) and then warm: seconds until the dashboard URL and token are printed, until every
  agent is on the map (its first estimate: a rescuer's check-in pose counts) and until every
  agent is *tracked* (an estimate later than its check-in, i.e. from the data it streamed;
  target: under 25 s cold). The snapshot is polled with the printed token. ``--demo-runs``
  repeats the pair. Every kernel compile is logged (``HRTLS_COMPILE_LOG``): the table adds the
  CPU seconds numba spent compiling in the demo's process and in its background worker, and
  ``--compile-list`` prints each kernel compiled (process, start, CPU seconds with and without
  the kernels it calls). ``--precompile 1`` forces the background worker (``HRTLS_PRECOMPILE``;
  by default it starts only with a core idle).

Each command runs ``--runs`` times in a new process; the table gives the best, median and worst
wall time. The machine may be shared: the best run is the steadiest figure.
Run: ``python benchmarks/cold_start.py [--runs 10] [--demo [--demo-runs 2] [--compile-list]]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import NamedTuple

import numpy as np
from rich.console import Console
from rich.table import Table

COMMANDS = (("hrtls --help", ["--help"], 0.3), ("hrtls track --help", ["track", "--help"], None),
            ("hrtls formats", ["formats"], None))


def _hrtls() -> list[str]:
    exe = Path(sys.executable).with_name("hrtls")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("hrtls")
    return [found] if found else [sys.executable, "-m", "hrtls.cli"]


DEMO_TARGET_S = 25.0
"""Issue 19: the first ``hrtls demo`` after a fresh install, live within this time."""
DEMO_LIMIT_S = 240.0
"""Give up on a demo run after this long."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def demo_run(cache_dir: Path, work: Path, log: Path
             ) -> tuple[float, DemoTimes, float | None, float]:
    """Seconds to the printed token, to each agent on the map and tracked (``hrtls demo``), to
    the end of its background compiles (None when it started none, or they did not end), and
    the Unix time of the start; every compile is logged to ``log``."""
    port = _free_port()
    # JIT kernels only: a module `hrtls warmup` compiled ahead of time would make "cold" warm;
    # the user cache (first-run markers) in the temporary folder too
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "HRTLS_AOT": "0",
           "XDG_CACHE_HOME": str(cache_dir.parent / "user-cache"), "HRTLS_COMPILE_LOG": str(log)}
    t0 = time.time()
    start = time.perf_counter()
    proc = subprocess.Popen([*_hrtls(), "demo", "--speed", "4", "--port", str(port),
                             "--duration-s", str(DEMO_LIMIT_S), "-o", str(work)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    assert proc.stdout is not None
    try:
        token = None
        background = False
        while token is None:
            line = proc.stdout.readline()
            if not line:
                raise RuntimeError("hrtls demo ended before printing its token")
            background = background or "background process" in line
            if found := re.search(r"commander token \(sign in with it\)\s+(\S+)", line):
                token = found.group(1)
        t_token = time.perf_counter() - start
        times = _poll_agents(port, token, start)
        done = _background_done(cache_dir, start) if background else None
        return t_token, times, done, t0
    finally:
        proc.terminate()
        proc.wait(timeout=30)


class DemoTimes(NamedTuple):
    """Seconds from the start of ``hrtls demo`` per agent id: first on the map, first tracked."""

    on_map: dict[str, float]
    tracked: dict[str, float]


def _poll_agents(port: int, token: str, start: float) -> DemoTimes:
    """Poll the mission's snapshot until every agent has an estimate from its own data."""
    times = DemoTimes({}, {})
    while time.perf_counter() - start < DEMO_LIMIT_S:
        req = urllib.request.Request(f"http://127.0.0.1:{port}/api/v1/missions/1/snapshot",
                                     headers={"Authorization": f"Bearer {token}"})
        with urllib.request.urlopen(req, timeout=10) as resp:
            picture = json.load(resp)
        now = time.perf_counter() - start
        checkin = {str(a["id"]): (a["start_pose"] or {}).get("t") for a in picture["agents"]}
        for est in picture["estimates"]:
            agent = str(est["agent"])
            times.on_map.setdefault(agent, now)
            t_in = checkin.get(agent)
            if t_in is None or est["t"] > t_in:   # not the check-in pose: tracked
                times.tracked.setdefault(agent, now)
        if picture["agents"] and len(times.tracked) == len(picture["agents"]):
            break
        time.sleep(0.25)
    return times


def _background_done(cache_dir: Path, start: float) -> float | None:
    """Seconds until the demo's background compiles wrote their marker (waits for it)."""
    markers = cache_dir.parent / "user-cache" / "hrtls"
    while time.perf_counter() - start < DEMO_LIMIT_S:
        if any(markers.glob("demo-compiled-*")):
            return time.perf_counter() - start
        time.sleep(0.25)
    return None


class Compile(NamedTuple):
    """One logged compile (``hrtls.kernels.COMPILE_LOG``): process role, kernel, timing."""

    role: str
    kernel: str
    start_s: float
    cpu_s: float
    self_cpu_s: float


def compiles(log: Path, t0: float) -> list[Compile]:
    """The kernels numba compiled (not loaded from its cache), start relative to ``t0``."""
    if not log.exists():
        return []
    out = []
    for line in log.read_text(encoding="utf-8").splitlines():
        rec = json.loads(line)
        if rec["compiled"]:
            role = "worker" if "precompile" in rec["argv"] else "demo"
            out.append(Compile(role, rec["kernel"], rec["start"] - t0, rec["cpu_s"],
                               rec["self_cpu_s"]))
    return out


def compile_cpu(records: list[Compile], role: str, until_s: float = math.inf) -> float:
    """CPU seconds of the compiles of one process role that started before ``until_s``."""
    return sum(r.self_cpu_s for r in records if r.role == role and r.start_s < until_s)


def demo_table(runs: int = 1, listing: list[Table] | None = None) -> Table:
    """Cold then warm ``hrtls demo``, ``runs`` times (a new empty cache each time).

    ``listing``: gets a table of the kernels compiled by each cold run.
    """
    table = Table("run", "token printed s", "all on the map s", "first tracked s",
                  "all tracked s", "target s", "met", "background compiles s",
                  "compile CPU s demo / worker", "same, until all tracked",
                  title="hrtls demo: empty kernel cache, then warm")
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            cache = Path(tmp) / "numba"
            for label in ("cold (empty cache)", "warm"):
                log = Path(tmp) / f"compiles-{label.split()[0]}.jsonl"
                t_token, times, done, t0 = demo_run(cache, Path(tmp) / label.split()[0], log)
                on_map = max(times.on_map.values(), default=float("nan"))
                tracked = sorted(times.tracked.values()) or [float("nan")]
                cold = label.startswith("cold")
                met = "yes" if tracked[-1] < DEMO_TARGET_S else "no"  # every agent tracked
                recs = compiles(log, t0)
                cpu = [compile_cpu(recs, role, until) for until in (math.inf, tracked[-1])
                       for role in ("demo", "worker")]
                table.add_row(label, f"{t_token:.1f}", f"{on_map:.1f}", f"{tracked[0]:.1f}",
                              f"{tracked[-1]:.1f}", f"{DEMO_TARGET_S:.0f}" if cold else "-",
                              met if cold else "-", "-" if done is None else f"{done:.1f}",
                              f"{cpu[0]:.1f} / {cpu[1]:.1f}", f"{cpu[2]:.1f} / {cpu[3]:.1f}")
                if cold and listing is not None:
                    listing.append(compile_listing(recs))
    return table


def compile_listing(records: list[Compile]) -> Table:
    """The kernels compiled, by start: process, CPU s with the kernels it calls and without."""
    table = Table("start s", "process", "kernel", "CPU s with callees", "CPU s itself",
                  title="kernels compiled in the cold demo")
    for r in sorted(records, key=lambda r: r.start_s):
        table.add_row(f"{r.start_s:.1f}", r.role, r.kernel, f"{r.cpu_s:.2f}",
                      f"{r.self_cpu_s:.2f}")
    for role in ("demo", "worker"):
        table.add_row("", role, "total", "", f"{compile_cpu(records, role):.1f}")
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--demo", action="store_true",
                        help="also time hrtls demo cold and warm (about a minute)")
    parser.add_argument("--demo-runs", type=int, default=1,
                        help="cold and warm demo pairs (each with a new empty cache)")
    parser.add_argument("--compile-list", action="store_true",
                        help="print every kernel compiled by each cold demo")
    parser.add_argument("--precompile", choices=("auto", "0", "1"), default=None,
                        help="HRTLS_PRECOMPILE for the demo (default: as set, else auto)")
    args = parser.parse_args()
    if args.precompile is not None:
        os.environ["HRTLS_PRECOMPILE"] = args.precompile
    table = Table("command", "best s", "median s", "worst s", "target s", "met",
                  title=f"cold start, {args.runs} fresh processes each")
    for label, argv, target in COMMANDS:
        walls = []
        for _ in range(args.runs):
            start = time.perf_counter()
            subprocess.run([*_hrtls(), *argv], check=True, capture_output=True)
            walls.append(time.perf_counter() - start)
        w = np.array(walls)
        met = "-" if target is None else ("yes" if np.median(w) < target else "no")
        table.add_row(label, f"{w.min():.3f}", f"{np.median(w):.3f}", f"{w.max():.3f}",
                      "-" if target is None else f"{target:.1f}", met)
    Console().print(table)
    if args.demo:
        listing: list[Table] = []
        Console().print(demo_table(args.demo_runs, listing if args.compile_list else None))
        for t in listing:
            Console().print(t)


if __name__ == "__main__":
    main()
