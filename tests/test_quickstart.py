"""docs/quickstart.md runs: every `hrtls` line of its bash blocks, in order, in a fresh folder."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "quickstart.md"


def commands() -> list[list[str]]:
    blocks = re.findall(r"```bash\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)
    return [shlex.split(line) for block in blocks for line in block.splitlines()
            if line.startswith("hrtls ")]


def test_quickstart_walkthrough(shared_data: Path, tmp_path: Path) -> None:
    steps = commands()
    assert [c[1] for c in steps] == ["info", "track", "evaluate", "export", "export"]
    for argv in steps:
        args = [a.replace("DATA/", f"{shared_data}/") for a in argv[1:]]
        done = subprocess.run([sys.executable, "-c", "from hrtls.cli.app import main; main()",
                               *args], cwd=tmp_path, capture_output=True, text=True,
                              check=False)
        assert done.returncode == 0, (argv, done.stdout, done.stderr)
    out = tmp_path / "t04"
    for name in ("trajectory.csv", "steps.csv", "trajectory.geojson", "report.json",
                 "track.png", "evaluation.json", "trajectory.gpx"):
        assert (out / name).is_file(), name
    assert (tmp_path / "t04-table.csv").is_file()
    report = json.loads((out / "report.json").read_text())
    assert report["floors"]["source"] == "barometer"
    assert report["floors"]["floor_changes"] == 0
    assert report["input"]["format"] == "ipin"
    evaluation = json.loads((out / "evaluation.json").read_text())
    assert evaluation["floors"]["checkpoints_correct"] == 1.0
    mf = subprocess.run([sys.executable, "-c", "from hrtls.cli.app import main; main()",
                         "export", str(out), "--to", "mf-json"], capture_output=True,
                        text=True, check=False)
    assert mf.returncode == 2 and "no Unix time origin" in mf.stderr
