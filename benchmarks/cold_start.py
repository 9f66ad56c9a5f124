"""Cold start of the ``hrtls`` command (issue 19, item 7): wall time of fresh processes.

* ``hrtls --help`` (target < 0.3 s): only the root group and the commands' one-line summaries;
* ``hrtls track --help``: imports the track command's module only;
* ``hrtls formats``: imports the format registry (readers, no tracker).

Each command runs ``--runs`` times in a new process; the table gives the best, median and worst
wall time. The machine may be shared: the best run is the steadiest figure.
Run: ``python benchmarks/cold_start.py [--runs 10]``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
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


if __name__ == "__main__":
    main()
