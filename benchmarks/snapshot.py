"""Size and time of ``Tracker.snapshot()`` / ``Tracker.restore()`` one hour into a mission.

Usage: ``python benchmarks/snapshot.py [--duration-s 3600] [--presets default ...]
[--chunk-s 1.0] [--repeat 20]``. The session is the hour-long ``office_random_walk`` of
``benchmarks/track_speed.py`` (cameras, BLE beacons, RFID tags, range nodes); it is fed in
chunks of ``chunk-s`` seconds, as the live service receives it, and the tracker is snapshotted
at the end. Prints, per preset, the snapshot size and the best time of ``repeat`` snapshots and
restores (aim: < 100 KB, < 1 ms).
"""

from __future__ import annotations

import argparse
import time
import warnings

from rich.console import Console
from rich.table import Table

from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.chunks import split_session
from hrtls.sim.scenarios import run_scenario


def main() -> None:
    """Print one row per preset."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--chunk-s", type=float, default=1.0)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--presets", nargs="*", default=["default", "colombo2014", "tarrio2011"])
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    console = Console()
    with console.status("simulating"):
        sim = run_scenario("office_random_walk", args.seed, duration_s=args.duration_s)
    s = sim.session
    parts = list(split_session(s, args.chunk_s))
    table = Table(title=f"snapshot after {args.duration_s:.0f} s in {len(parts)} chunks")
    for col in ("preset", "size (KB)", "snapshot (ms)", "restore (ms)", "rows so far"):
        table.add_column(col, justify="right")
    for name in args.presets:
        tracker = Tracker(preset(name))
        tracker.start_session(s)
        with console.status(f"tracking {name}"):
            for part in parts:
                tracker.update(part)
        n_rows = len(tracker.estimates_since())
        best_s = best_r = float("inf")
        data = b""
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            data = tracker.snapshot()
            best_s = min(best_s, time.perf_counter() - t0)
            t0 = time.perf_counter()
            Tracker.restore(data)
            best_r = min(best_r, time.perf_counter() - t0)
        table.add_row(name, f"{len(data) / 1024:.1f}", f"{best_s * 1e3:.2f}",
                      f"{best_r * 1e3:.2f}", str(n_rows))
    console.print(table)


if __name__ == "__main__":
    main()
