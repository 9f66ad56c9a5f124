"""Time the simulator: an hour of 100 Hz IMU with cameras, beacons, RFID tags and range nodes.

Run: ``python benchmarks/sim.py [--duration-s 3600] [--write DIR]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from hrtls.sim.scenarios import SCENARIOS, run_scenario, write_result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration-s", type=float, default=3600.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--write", type=Path, default=None,
                        help="also write the session (default: a temporary folder)")
    parser.add_argument("--all", action="store_true", help="also time every scenario")
    args = parser.parse_args()

    run_scenario("colombo_square", 0)  # compile the numba kernel outside the timing
    t0 = time.perf_counter()
    result = run_scenario("office_random_walk", args.seed, duration_s=args.duration_s)
    t_sim = time.perf_counter() - t0
    s = result.session
    with tempfile.TemporaryDirectory() as tmp:
        out = args.write or Path(tmp) / "hour"
        t0 = time.perf_counter()
        write_result(result, out, overwrite=True)
        t_write = time.perf_counter() - t0

    table = Table("what", "value", title="hrtls.sim benchmark")
    table.add_row("simulated time", f"{result.activity_t[-1]:.0f} s")
    table.add_row("IMU samples (100 Hz)", f"{len(s.imu.accel.t)}")
    table.add_row("magnetometer samples (50 Hz)", f"{len(s.imu.mag.t) if s.imu.mag else 0}")
    table.add_row("fixes / RSS / tags / ranges",
                  f"{len(s.fixes) if s.fixes else 0} / {len(s.rss) if s.rss else 0} / "
                  f"{len(s.tags) if s.tags else 0} / {len(s.ranges) if s.ranges else 0}")
    table.add_row("distance walked", f"{result.motion.distance_m:.0f} m")
    table.add_row("true steps", f"{len(result.true_steps)}")
    table.add_row("simulation wall time", f"{t_sim:.2f} s")
    table.add_row("writing the session", f"{t_write:.2f} s")
    Console().print(table)

    if args.all:
        t2 = Table("scenario", "simulated s", "wall s", title="all scenarios (seed 0)")
        for name in SCENARIOS:
            t0 = time.perf_counter()
            r = run_scenario(name, 0)
            t2.add_row(name, f"{r.activity_t[-1]:.0f}", f"{time.perf_counter() - t0:.2f}")
        Console().print(t2)


if __name__ == "__main__":
    main()
