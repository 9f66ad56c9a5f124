"""``hrtls track`` and ``hrtls bench papers`` through typer's CliRunner."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from typer.testing import CliRunner

from hrtls.cli import bench as bench_cli
from hrtls.cli import track as track_cli
from hrtls.data.session import GeoreferenceModel
from hrtls.sim.scenarios import SimulationResult, write_result

runner = CliRunner()


def track_app() -> typer.Typer:
    app = typer.Typer()
    app.command("track")(track_cli.track)
    app.command("demo")(track_cli.demo)
    return app


def write_office(office: SimulationResult, folder: Path, *, geo: bool) -> Path:
    meta = office.session.meta
    if geo:
        meta = meta.model_copy(update={"georeference": GeoreferenceModel(lat_deg=41.86,
                                                                          lon_deg=12.47)})
    sim = SimulationResult(**{**{f: getattr(office, f) for f in office.__dataclass_fields__},
                              "session": office.session.with_parts(meta=meta)})
    return write_result(sim, folder / "session")


def test_track_writes_everything(office: SimulationResult, tmp_path: Path) -> None:
    session = write_office(office, tmp_path, geo=True)
    out = tmp_path / "out"
    res = runner.invoke(track_app(), ["track", str(session), "-o", str(out), "--plot"])
    assert res.exit_code == 0, res.output
    for name in ("trajectory.csv", "steps.csv", "trajectory.geojson", "report.json",
                 "track.png"):
        assert (out / name).is_file(), name
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert "lat" in header and "lon" in header
    report = json.loads((out / "report.json").read_text())
    assert report["evaluation"] is not None
    assert "corrections" in report and report["config"]["name"] == "default"
    # the evaluation table is printed when the session has ground truth
    assert "mean" in res.output.lower()


def test_track_without_georeference_has_no_latlon(office: SimulationResult,
                                                  tmp_path: Path) -> None:
    session = write_office(office, tmp_path, geo=False)
    out = tmp_path / "out"
    res = runner.invoke(track_app(), ["track", str(session), "-o", str(out), "-p",
                                      "inderst-range"])
    assert res.exit_code == 0, res.output
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert "lat" not in header


def test_track_bad_input_exit_2(tmp_path: Path) -> None:
    res = runner.invoke(track_app(), ["track", str(tmp_path / "missing"), "-o",
                                      str(tmp_path / "o")])
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1


def test_track_bad_preset_and_config(office: SimulationResult, tmp_path: Path) -> None:
    session = write_office(office, tmp_path, geo=False)
    res = runner.invoke(track_app(), ["track", str(session), "-o", str(tmp_path / "o"),
                                      "-p", "nope"])
    assert res.exit_code == 2 and "unknown preset" in res.output
    bad = tmp_path / "bad.toml"
    bad.write_text("[fixes]\nperiod = 3\n")
    res = runner.invoke(track_app(), ["track", str(session), "-o", str(tmp_path / "o"),
                                      "-c", str(bad)])
    assert res.exit_code == 2 and "fixes.period" in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_bench_runs_rows() -> None:
    from hrtls.jobs.bench import run_bench

    rows = run_bench(seeds=[100], only=["colombo_circle Tp=16"])
    assert rows and rows[0].paper_preset == "colombo2014"
    assert rows[0].paper.startswith("0.50")
    d = rows[0].to_dict()
    assert set(d) >= {"scenario", "metric", "paper", "default_mean", "default_p90",
                      "default_worst", "met", "n_seeds"}


def test_bench_cli_help() -> None:
    res = runner.invoke(bench_cli.app, ["papers", "--help"])
    assert res.exit_code == 0 and "--seeds" in res.output and "--quick" in res.output
