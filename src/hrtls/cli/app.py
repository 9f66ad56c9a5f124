"""The ``hrtls`` command: thin commands that call the library and print with rich."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from hrtls.cli.errors import Verbosity, reports_errors
from hrtls.data import Session
from hrtls.errors import InputError, UnitError

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Hybrid Rescue Team Localization System.")
console = Console(highlight=False)
wide = Console(highlight=False, width=max(console.width, 120))


@app.callback()
def _root(
    verbose: Annotated[bool, typer.Option("--verbose", "-v",
                                          help="Show tracebacks and details.")] = False,
) -> None:
    """Hybrid Rescue Team Localization System: indoor tracking of people and robots."""
    Verbosity.verbose = verbose


FormatOption = Annotated[str | None, typer.Option(
    "--format", "-f", help="Input format (default: detected). See `hrtls formats`.")]
RepairOption = Annotated[bool, typer.Option(
    "--repair", help="Sort backward times, merge duplicates, drop NaN rows (with warnings).")]
BeaconsOption = Annotated[Path | None, typer.Option(
    "--beacons", help="CSV of beacon positions for IPIN logfiles (id/lat/lon/floor).")]
TrialOption = Annotated[str | None, typer.Option(
    "--trial", help="Trial of a multi-trial recording (mobgap: e.g. Test5/Trial1).")]


def _load(path: Path, fmt: str | None, *, repair: bool, check_units: bool,
          beacons: Path | None, trial: str | None = None) -> Session:
    from hrtls.recordings import read_any, reader_options

    if not path.exists():
        raise InputError("no such file or folder", where=str(path),
                         expected="a recording (session folder, zip, logfile, ...)")
    return read_any(path, fmt=fmt, repair=repair, check_units=check_units, beacons=beacons,
                    **reader_options(fmt, trial=trial))


@app.command()
@reports_errors
def formats() -> None:
    """List the input formats hrtls reads."""
    from hrtls.recordings import FORMATS

    table = Table("format", "what")
    for name, reader in FORMATS.items():
        doc = (reader.__doc__ or "").strip().splitlines()
        table.add_row(name, doc[0] if doc else "")
    console.print(table)


@app.command()
@reports_errors
def info(
    path: Annotated[Path, typer.Argument(help="Recording: session folder/zip or a user format.")],
    fmt: FormatOption = None,
    beacons: BeaconsOption = None,
    trial: TrialOption = None,
) -> None:
    """Describe a recording: format, duration, rates, gaps, sensors, suspected unit problems."""
    from hrtls.io.inspect import summarize
    from hrtls.recordings import detect_format

    detected = fmt or detect_format(path)
    with warnings.catch_warnings(record=True) as repairs:
        warnings.simplefilter("always")
        session = _load(path, detected, repair=True, check_units=False, beacons=beacons,
                        trial=trial)
    summary = summarize(session)
    console.print(f"[bold]{path}[/bold]  format [cyan]{detected}[/cyan]  "
                  f"duration {summary.duration_s:.1f} s  "
                  f"({summary.start_s:.3f} .. {summary.end_s:.3f} s)")
    console.print(f"sensors: {', '.join(summary.sensors) or 'none'}; "
                  f"ground truth: {'trajectory' if summary.has_truth else 'no'}"
                  f"{f', {summary.checkpoints} checkpoints' if summary.checkpoints else ''}; "
                  f"georeference: {'yes' if summary.georeferenced else 'no'}")
    table = Table("stream", "samples", "rate Hz", "start s", "end s", "gaps", "longest gap s",
                  "detail")
    for s in summary.streams:
        table.add_row(s.name, str(s.samples), f"{s.rate_hz:.2f}", f"{s.start_s:.3f}",
                      f"{s.end_s:.3f}", str(s.gaps), f"{s.longest_gap_s:.3f}", s.detail)
    wide.print(table)
    if summary.landmarks:
        console.print("landmarks: " + ", ".join(f"{n} {k}" for k, n in summary.landmarks.items()))
    for label, ids in summary.unknown_ids.items():
        console.print(f"[yellow]unknown ids in {label}:[/yellow] {', '.join(ids[:10])}"
                      f"{' ...' if len(ids) > 10 else ''}")
    for problem in summary.unit_problems:
        console.print(f"[red]unit problem:[/red] {problem}")
    for message in {str(w.message) for w in repairs}:
        console.print(f"[yellow]needs repair:[/yellow] {message}")
    for note in summary.notes:
        console.print(f"note: {note}")


@app.command()
@reports_errors
def convert(
    path: Annotated[Path, typer.Argument(help="Recording in any supported format.")],
    output: Annotated[Path, typer.Option("--output", "-o",
                                         help="Session folder (or .zip) to write.")],
    fmt: FormatOption = None,
    repair: RepairOption = False,
    beacons: BeaconsOption = None,
    trial: TrialOption = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing session.")] = False,
) -> None:
    """Convert a recording into a session folder (SI units, ENU, checked)."""
    from hrtls.io.session import write_session
    from hrtls.recordings import detect_format

    columns = (SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task("detecting format", total=3)
        detected = fmt or detect_format(path)
        progress.update(task, advance=1, description=f"reading {detected}")
        try:
            session = _load(path, detected, repair=repair, check_units=True, beacons=beacons,
                            trial=trial)
        except UnitError as exc:
            raise UnitError(exc.problem, where=exc.where, expected=exc.expected,
                            hint="see `hrtls info` and the reader's unit options") from None
        progress.update(task, advance=1, description=f"writing {output}")
        write_session(session, output, overwrite=overwrite)
        progress.update(task, advance=1)
    console.print(f"wrote {output}")


def _register() -> None:
    """Attach the commands that live in their own modules."""
    from hrtls.cli import attitude as attitude_cli
    from hrtls.cli import bench as bench_cli
    from hrtls.cli import config as config_cli
    from hrtls.cli import gait as gait_cli
    from hrtls.cli import ipin as ipin_cli
    from hrtls.cli import sim as sim_cli
    from hrtls.cli import track as track_cli
    from hrtls.cli import wsn as wsn_cli

    app.command("track")(track_cli.track)
    app.command("demo")(track_cli.demo)
    app.command("ipin")(ipin_cli.ipin)
    app.command("simulate")(sim_cli.simulate)
    app.command("evaluate")(sim_cli.evaluate)
    app.command("attitude")(attitude_cli.attitude)
    attitude_cli.calibrate_app.command("steps")(gait_cli.calibrate_steps)
    app.add_typer(attitude_cli.calibrate_app, name="calibrate")
    app.add_typer(gait_cli.activity_app, name="activity")
    app.add_typer(wsn_cli.app, name="wsn")
    app.add_typer(bench_cli.app, name="bench")
    app.add_typer(config_cli.app, name="config")


_register()


def main() -> None:
    """Entry point of the ``hrtls`` console script."""
    app()
