"""The CLI names its flags, checks the output before working, and takes --format/--trial."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.cli.errors import cli_text
from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.io.session import write_session

runner = CliRunner()


def _session(tmp_path: Path) -> Path:
    t = np.arange(600) * 0.01
    acc = np.tile([0.0, 0.0, 9.81], (len(t), 1))
    path = tmp_path / "s"
    write_session(Session(imu=ImuStream(SensorSeries(t, acc, "acc"))), path)
    return path


def test_python_hints_become_flags() -> None:
    assert cli_text("bad (pass repair=True to sort)") == "bad (pass --repair to sort)"
    assert cli_text("x (pass --repair (repair=True in Python) to drop)") == \
        "x (pass --repair to drop)"
    assert cli_text("pass fmt= (one of a, b)") == "pass --format (one of a, b)"
    assert cli_text("others: T2 (choose with trial=...)") == "others: T2 (choose with --trial)"


def test_output_that_is_a_file_is_refused_before_work(tmp_path: Path) -> None:
    session = _session(tmp_path)
    target = tmp_path / "taken"
    target.write_text("x")
    result = runner.invoke(app, ["track", str(session), "-o", str(target)])
    assert result.exit_code == 2
    assert "is a file" in result.output and "Errno" not in result.output


def test_output_with_results_is_refused_before_work(tmp_path: Path) -> None:
    session = _session(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text("{}")
    result = runner.invoke(app, ["track", str(session), "-o", str(out)])
    assert result.exit_code == 2 and "--overwrite" in result.output
    assert (out / "report.json").read_text() == "{}"


def test_track_takes_format_and_refuses_trial_for_formats_without(tmp_path: Path) -> None:
    session = _session(tmp_path)
    ok = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o1"),
                             "--format", "hrtls-session"])
    assert ok.exit_code == 0, ok.output
    bad = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o2"),
                              "--trial", "Test5/Trial1"])
    assert bad.exit_code == 2 and "--trial given for a hrtls-session" in bad.output


def test_repair_error_of_a_session_names_the_flag(tmp_path: Path) -> None:
    session = _session(tmp_path)
    imu = session / "imu.csv"
    lines = imu.read_text().splitlines(keepends=True)
    imu.write_text("".join([*lines[:300], lines[299], *lines[300:]]))
    result = runner.invoke(app, ["track", str(session), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "--repair" in result.output and "repair=True" not in result.output


def test_root_help_lists_every_command_without_importing_it() -> None:
    import subprocess
    import sys

    code = ("import sys; from typer.testing import CliRunner; from hrtls.cli.app import app; "
            "r = CliRunner().invoke(app, ['--help']); print(r.output); "
            "print(sorted(m for m in sys.modules if m.startswith(('hrtls.', 'numpy', 'scipy', "
            "'numba'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    from hrtls.cli.app import _COMMANDS

    for name in _COMMANDS:
        assert f"  {name} " in out
    loaded = out.strip().splitlines()[-1]
    assert "numpy" not in loaded and "hrtls.pipeline" not in loaded and "hrtls.cli.track" \
        not in loaded


def test_summaries_are_the_commands_own_first_lines() -> None:
    from hrtls.cli.app import _COMMANDS, SUMMARIES, load_command

    for name in _COMMANDS:
        command = load_command(name)
        assert SUMMARIES[name] == (command.help or "").strip().splitlines()[0], name


def test_export_refuses_what_the_result_cannot_give_and_writes_the_rest(tmp_path: Path) -> None:
    import json

    from hrtls.io.geojson import LOCAL_TYPE, read_geojson

    session = _session(tmp_path)
    out = tmp_path / "out"
    assert runner.invoke(app, ["track", str(session), "-o", str(out)]).exit_code == 0
    assert not (out / "trajectory.geojson").exists()
    local = out / "trajectory.local.json"
    assert json.loads(local.read_text())["type"] == LOCAL_TYPE
    assert read_geojson(local).is_wgs84 is False
    gpx = runner.invoke(app, ["export", str(out), "--to", "gpx"])
    assert gpx.exit_code == 2 and "no georeference" in gpx.output
    mf = runner.invoke(app, ["export", str(out), "--to", "mf-json"])
    assert mf.exit_code == 2 and "no Unix time origin" in mf.output
    again = runner.invoke(app, ["export", str(out), "--to", "geojson"])
    assert again.exit_code == 2 and "--overwrite" in again.output
    csv = runner.invoke(app, ["export", str(out), "--to", "csv", "-o", str(tmp_path / "t.csv")])
    assert csv.exit_code == 0, csv.output
    assert (tmp_path / "t.csv").read_text() == (out / "trajectory.csv").read_text()
    bad = runner.invoke(app, ["export", str(out), "--to", "kml"])
    assert bad.exit_code == 2 and "gpx | mf-json | geojson | csv" in bad.output


def test_convert_checks_its_output_before_reading(tmp_path: Path) -> None:
    session = _session(tmp_path)
    target = tmp_path / "taken"
    target.write_text("x")
    res = runner.invoke(app, ["convert", str(session), "-o", str(target)])
    assert res.exit_code == 2 and "exists and is not a folder" in res.output
    ok = runner.invoke(app, ["convert", str(session), "-o", str(tmp_path / "copy")])
    assert ok.exit_code == 0, ok.output
    again = runner.invoke(app, ["convert", str(session), "-o", str(tmp_path / "copy")])
    assert again.exit_code == 2 and "--overwrite" in again.output
