"""``--config`` and ``--preset`` exclude each other in every command that takes both."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app


@pytest.mark.parametrize("command", [["config", "show"], ["track", "REC", "-o", "OUT"],
                                     ["mission", "track", "MISSION", "-o", "OUT"]])
def test_both_options_refused_naming_the_command(tmp_path: Path, command: list[str]) -> None:
    toml = tmp_path / "c.toml"
    toml.write_text('name = "mine"\n')
    args = [str(tmp_path / a) if a in ("REC", "OUT", "MISSION") else a for a in command]
    r = CliRunner().invoke(app, [*args, "--config", str(toml), "--preset", "default"])
    assert r.exit_code == 2, r.output
    assert "both --config and --preset" in r.output
    assert f"hrtls {' '.join(command[:2]) if command[0] != 'track' else 'track'}" in r.output
