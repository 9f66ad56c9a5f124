"""Session I/O speed: write and read a 1 M-row imu.csv (target: loads in a few seconds).

Run: python benchmarks/session_io.py [--rows N]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import read_session, write_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rows", type=int, default=1_000_000)
    args = parser.parse_args()
    n = args.rows
    rng = np.random.default_rng(0)
    t = np.arange(n) / 100.0
    imu = ImuStream(SensorSeries(t, rng.normal([0, 0, 9.81], 1.0, (n, 3)), "acc"),
                    SensorSeries(t, rng.normal(0, 0.5, (n, 3)), "gyro"),
                    SensorSeries(t, rng.normal([20, 0, -40], 2.0, (n, 3)), "mag"))
    session = Session(imu=imu)
    table = Table("operation", "rows", "seconds", "rows/s", title="session I/O")
    with tempfile.TemporaryDirectory() as tmp:
        for target in (Path(tmp) / "s", Path(tmp) / "s.zip"):
            start = time.perf_counter()
            write_session(session, target)
            dt = time.perf_counter() - start
            table.add_row(f"write {target.suffix or 'folder'}", f"{n:,}", f"{dt:.2f}",
                          f"{n / dt:,.0f}")
            start = time.perf_counter()
            back = read_session(target)
            dt = time.perf_counter() - start
            assert len(back.imu.accel) == n
            table.add_row(f"read {target.suffix or 'folder'}", f"{n:,}", f"{dt:.2f}",
                          f"{n / dt:,.0f}")
    Console().print(table)


if __name__ == "__main__":
    main()
