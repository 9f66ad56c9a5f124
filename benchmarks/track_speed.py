"""Speed of ``hrtls track``: IMU samples per second per preset on an hour-long simulated walk.

Usage: ``python benchmarks/track_speed.py [--duration-s 3600] [--repeat 2]
[--presets default tarrio2011] [--cpu-time]``. The session is
``office_random_walk`` (cameras, 8 BLE beacons, RFID tags, range nodes), so every correction
runs; each preset tracks it ``repeat`` times after one warm-up run (numba compilation) and the
best time is reported, split into attitude + gait (per-sample stages, best of their own runs)
and the rest (events: corrections, event loop, result assembly).
"""

from __future__ import annotations

import argparse
import time
import warnings

from rich.console import Console
from rich.table import Table

from hrtls.pipeline import PRESETS, Tracker, preset
from hrtls.sim.scenarios import run_scenario


def main() -> None:
    """Print one row per preset."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--presets", nargs="*", default=list(PRESETS),
                    help="presets to time (default: all)")
    ap.add_argument("--cpu-time", action="store_true",
                    help="time with the process CPU clock (steadier on a shared machine)")
    args = ap.parse_args()
    clock = time.process_time if args.cpu_time else time.perf_counter
    warnings.simplefilter("ignore")
    console = Console()
    with console.status("simulating"):
        sim = run_scenario("office_random_walk", args.seed, duration_s=args.duration_s)
    s = sim.session
    assert s.imu is not None
    n = len(s.imu.accel)
    console.print(f"office_random_walk {args.duration_s:.0f} s: {n:,} IMU samples, "
                  f"{len(s.rss or [])} RSS, {len(s.ranges or [])} ranges, "
                  f"{len(s.tags or [])} tag reads, {len(s.fixes or [])} fixes")
    table = Table("preset", "seconds", "samples/s", "attitude+gait s", "events s",
                  "trajectory rows", title="hrtls track speed (one core, best of runs, "
                  f"{'CPU' if args.cpu_time else 'wall'} time)")
    for name in args.presets:
        cfg = preset(name)
        Tracker(cfg).run(s)  # warm-up: numba caches
        # best of the runs for the whole track and, separately, for the per-sample stages
        # (IMU alignment, attitude, gait) alone; "events" is the difference
        total = stage = float("inf")
        n_rows = 0
        for _ in range(max(1, args.repeat)):
            tr = Tracker(cfg)
            t_imu = s.imu.accel.t
            tr.start(s.meta, s.landmarks, has_imu=True, has_gyro=s.imu.gyro is not None,
                     has_mag=s.imu.mag is not None, has_orientation=s.orientation is not None,
                     rate_hz=s.imu.accel.rate_hz, t0=s.time_span()[0])
            t_stage = clock()
            _, acc, gyr, mag = s.imu.aligned()
            assert tr.attitude is not None and tr.gait is not None
            q = tr.attitude.update(t_imu, acc, gyr, mag, s.orientation,
                                   mounting_q_bd=tr.meta.mounting_q_bd, state_t=tr.state.t)
            tr.gait.update(t_imu, acc, q)
            stage = min(stage, clock() - t_stage)
            total_t0 = clock()
            result = Tracker(cfg).run(s)
            total = min(total, clock() - total_t0)
            n_rows = len(result.trajectory)
        table.add_row(name, f"{total:.2f}", f"{n / total:,.0f}", f"{stage:.2f}",
                      f"{max(total - stage, 0.0):.2f}", f"{n_rows:,}")
    console.print(table)


if __name__ == "__main__":
    main()
