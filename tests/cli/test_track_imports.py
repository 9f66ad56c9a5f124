"""`hrtls track` imports only what it uses (none of the slow scipy subpackages it once pulled in)
and, in its own process only, freezes the imported objects out of the garbage collector."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from hrtls.io.session import write_session
from hrtls.sim.scenarios import run_scenario

UNUSED = ("scipy.stats", "scipy.special", "scipy.signal", "scipy.spatial", "scipy.optimize",
          "scipy.interpolate", "scipy.integrate", "scipy.ndimage", "pyarrow.parquet", "pymap3d",
          "matplotlib", "networkx", "sklearn", "pandas", "fastapi", "sqlalchemy", "ray")
"""Modules the command must not import for a CSV session folder without a georeference."""


def test_track_of_a_csv_session_leaves_unused_modules_alone(tmp_path: Path) -> None:
    session = tmp_path / "walk"
    write_session(run_scenario("colombo_circle", seed=0, laps=1).session, session)
    code = ("import atexit, gc, json, sys\n"
            "atexit.register(lambda: print('FROZEN', gc.get_freeze_count(), 'LOADED', "
            "json.dumps(sorted(sys.modules))))\n"
            "from hrtls.cli.app import main\n"
            f"sys.argv = ['hrtls', 'track', {str(session)!r}, '-o', "
            f"{str(tmp_path / 'out')!r}]\n"
            "main()\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "out" / "trajectory.csv").exists()
    frozen, loaded_text = run.stdout.split("FROZEN", 1)[1].split("LOADED", 1)
    loaded = set(json.loads(loaded_text))
    assert int(frozen) > 10_000  # the modules' objects, out of the collector's passes
    assert "hrtls.gait.features" in loaded and "numba" in loaded  # it did track
    assert not [m for m in UNUSED if m in loaded]


def test_only_the_hrtls_process_freezes_its_objects() -> None:
    code = ("import gc\n"
            "from hrtls.cli import process\n"
            "process.imports_done(); process.exiting(); before = gc.get_freeze_count()\n"
            "process.own(); process.imports_done()\n"
            "print(before, gc.get_freeze_count())\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120)
    before, after = (int(v) for v in run.stdout.split())
    assert before == 0 and after > 0
