"""Cold start of the ``hrtls`` command (issue 19, item 7): wall time of fresh processes.

* ``hrtls --help`` (target < 0.3 s): only the root group and the commands' one-line summaries;
* ``hrtls track --help``: imports the track command's module only;
* ``hrtls formats``: imports the format registry (readers, no tracker).
* ``--demo``: ``hrtls demo`` with an empty kernel cache (a fresh install: every numba kernel is
  compiled) and then warm: seconds until the dashboard URL and token are printed, until every
  agent is on the map (its first estimate: a rescuer's check-in pose counts) and until every
  agent is *tracked* (an estimate later than its check-in, i.e. from the data it streamed;
  target: under 25 s cold). The snapshot is polled with the printed token. ``--demo-runs``
  repeats the pair.

Each command runs ``--runs`` times in a new process; the table gives the best, median and worst
wall time. The machine may be shared: the best run is the steadiest figure.
Run: ``python benchmarks/cold_start.py [--runs 10] [--demo [--demo-runs 2]]``.
"""

from __future__ import annotations

import argparse
import json
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


def demo_run(cache_dir: Path, work: Path) -> tuple[float, DemoTimes, float | None]:
    """Seconds to the printed token, to each agent on the map and tracked (``hrtls demo``), and
    to the end of its background compiles (None when it started none, or they did not end)."""
    port = _free_port()
    # JIT kernels only: a module `hrtls warmup` compiled ahead of time would make "cold" warm;
    # the user cache (first-run markers) in the temporary folder too
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "HRTLS_AOT": "0",
           "XDG_CACHE_HOME": str(cache_dir.parent / "user-cache")}
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
        return t_token, times, done
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


def demo_table(runs: int = 1) -> Table:
    """Cold then warm ``hrtls demo``, ``runs`` times (a new empty cache each time)."""
    table = Table("run", "token printed s", "all on the map s", "first tracked s",
                  "all tracked s", "target s", "met", "background compiles s",
                  title="hrtls demo: empty kernel cache, then warm")
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            cache = Path(tmp) / "numba"
            for label in ("cold (empty cache)", "warm"):
                t_token, times, done = demo_run(cache, Path(tmp) / label.split()[0])
                on_map = max(times.on_map.values(), default=float("nan"))
                tracked = sorted(times.tracked.values()) or [float("nan")]
                cold = label.startswith("cold")
                met = "yes" if tracked[-1] < DEMO_TARGET_S else "no"  # every agent tracked
                table.add_row(label, f"{t_token:.1f}", f"{on_map:.1f}", f"{tracked[0]:.1f}",
                              f"{tracked[-1]:.1f}", f"{DEMO_TARGET_S:.0f}" if cold else "-",
                              met if cold else "-", "-" if done is None else f"{done:.1f}")
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--demo", action="store_true",
                        help="also time hrtls demo cold and warm (about a minute)")
    parser.add_argument("--demo-runs", type=int, default=1,
                        help="cold and warm demo pairs (each with a new empty cache)")
    args = parser.parse_args()
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
        Console().print(demo_table(args.demo_runs))


if __name__ == "__main__":
    main()
