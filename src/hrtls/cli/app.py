"""The ``hrtls`` command: thin commands that call the library and print with rich."""

from __future__ import annotations

import importlib
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from typer.core import TyperCommand, TyperGroup

from hrtls.cli.errors import Verbosity, cli_text, err_console, reports_errors
from hrtls.errors import InputError, UnitError

if TYPE_CHECKING:
    from hrtls.data import Session

_COMMANDS: dict[str, tuple[str, str, str]] = {
    "track": ("hrtls.cli.track", "track", "command"),
    "demo": ("hrtls.cli.demo", "demo", "command"),
    "ipin": ("hrtls.cli.ipin", "ipin", "command"),
    "simulate": ("hrtls.cli.sim", "simulate", "command"),
    "evaluate": ("hrtls.cli.sim", "evaluate", "command"),
    "export": ("hrtls.cli.export", "export", "command"),
    "warmup": ("hrtls.cli.warmup", "warmup", "command"),
    "attitude": ("hrtls.cli.attitude", "attitude", "command"),
    "calibrate": ("hrtls.cli.attitude", "calibrate_app", "group"),
    "activity": ("hrtls.cli.gait", "activity_app", "group"),
    "wsn": ("hrtls.cli.wsn", "app", "group"),
    "bench": ("hrtls.cli.bench", "app", "group"),
    "config": ("hrtls.cli.config", "app", "group"),
    "serve": ("hrtls.cli.serve", "serve", "command"),
    "agent": ("hrtls.cli.service_cli", "agent_app", "group"),
    "mission": ("hrtls.cli.service_cli", "mission_app", "group"),
}
"""Commands in their own modules: name -> (module, attribute, command or group of commands).

They are imported only when run (or when their own help is asked for), so that ``hrtls
--help`` and the commands that need little start fast; :data:`SUMMARIES` lists them.
"""

SUMMARIES: dict[str, str] = {
    "track": "Track a recording: trajectory.csv, steps.csv, trajectory.geojson, report.json.",
    "demo": "Live supervisor and dashboard with a simulated team; --no-serve: the batch "
            "comparison.",
    "ipin": "Track from the first POSI (start, heading unknown); errors "
            "at the later POSI landmarks.",
    "simulate": "Simulate a paper scenario into a session folder with ground truth.",
    "evaluate": "Score a result folder against ground truth; write evaluation.json and plots "
                "beside it.",
    "export": "Export a result as GPX, OGC Moving Features JSON, GeoJSON or CSV.",
    "warmup": "Compile the numerical kernels now (once per install) so that later runs start "
              "at once.",
    "attitude": "Estimate the orientation (ENU) and write t,qw,qx,qy,qz,roll,pitch,yaw.",
    "calibrate": "Sensor calibration files.",
    "activity": "Activity recognition models.",
    "wsn": "Sensor-network self-localization with mobile agents (Inderst Ch. 5-6).",
    "bench": "Benchmarks against the papers' published figures.",
    "config": "Tracker configurations.",
    "serve": "Run the supervisor: live tracking of the team, REST + WebSocket API and "
             "dashboard.",
    "agent": "Live agents: stream a recording to a running service.",
    "mission": "Missions: track a folder offline; on a service: simulate, floor images, export.",
}
"""One line per lazily loaded command, shown by ``hrtls --help`` without importing it."""


_COMPILING = frozenset({"track", "demo", "ipin", "attitude", "bench", "wsn", "activity",
                        "calibrate"})
"""Commands that run numerical kernels (compiled on first use)."""


def load_command(name: str) -> Any:
    """The click command ``name`` of :data:`_COMMANDS`, imported now."""
    from hrtls.jobs.warmup import NOTICE, configure_cache, first_run

    configure_cache()
    if name in _COMPILING and "--help" not in sys.argv and first_run():
        err_console.print(f"[yellow]note:[/yellow] {NOTICE}")
    module_name, attribute, kind = _COMMANDS[name]
    module = importlib.import_module(module_name)
    target = getattr(module, attribute)
    if name == "calibrate":
        from hrtls.cli import gait as gait_cli

        if not any(c.name == "steps" for c in target.registered_commands):
            target.command("steps")(gait_cli.calibrate_steps)
    if kind == "group":
        command = typer.main.get_command(target)
    else:
        single = typer.Typer(add_completion=False)
        single.command(name)(target)
        command = typer.main.get_command(single)
    command.name = name
    return command


class _LazyGroup(TyperGroup):
    """The root group: lists :data:`SUMMARIES` for help, imports a command when it runs."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        self._listing = False
        for name in _COMMANDS:
            self.commands.setdefault(name, TyperCommand(name, short_help=SUMMARIES[name],
                                                        help=SUMMARIES[name]))

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        command = self.commands.get(cmd_name)
        if cmd_name in _COMMANDS and not self._listing and command is not None \
                and command.callback is None:
            command = self.commands[cmd_name] = load_command(cmd_name)
        return command

    def format_help(self, ctx: Any, formatter: Any) -> None:
        self._listing = True
        try:
            super().format_help(ctx, formatter)
        finally:
            self._listing = False


app = typer.Typer(cls=_LazyGroup, no_args_is_help=True, add_completion=False, rich_markup_mode=None,
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
    from rich.table import Table

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
    from rich.table import Table

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
        console.print(f"[red]unit problem:[/red] {cli_text(problem)}")
    for message in {str(w.message) for w in repairs}:
        console.print(f"[yellow]needs repair:[/yellow] {cli_text(message)}")
    for note in summary.notes:
        console.print(f"note: {cli_text(note)}")


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
    to: Annotated[str, typer.Option(
        "--to", help="Tables as csv | parquet (typed, compressed, units in the schema).")]
    = "csv",
) -> None:
    """Convert a recording into a session folder (SI units, ENU, checked)."""
    from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from hrtls.cli.paths import check_writable
    from hrtls.io.session import SESSION_FILES, write_session
    from hrtls.recordings import detect_format

    if to not in ("csv", "parquet"):
        raise InputError(f"{to!r}", where="--to", expected="csv or parquet")
    if output.suffix.lower() == ".zip":
        if output.exists() and not overwrite:
            raise InputError("already exists", where=str(output), expected="a new path (or "
                             "--overwrite)")
    elif output.exists() and not output.is_dir():
        raise InputError("exists and is not a folder", where=str(output),
                         expected="a folder path or a .zip")
    elif output.is_dir() and not overwrite and any((output / n).exists() for n in SESSION_FILES):
        raise InputError("already holds a session", where=str(output),
                         expected="a new or empty folder (or --overwrite)")
    check_writable(output, flag="--output", folder=output.suffix.lower() != ".zip")
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
                            hint="see `hrtls info`") from None
        progress.update(task, advance=1, description=f"writing {output}")
        write_session(session, output, overwrite=overwrite,
                      table_format="parquet" if to == "parquet" else "csv")
        progress.update(task, advance=1)
    console.print(f"wrote {output}")


def main() -> None:
    """Entry point of the ``hrtls`` console script (see :mod:`hrtls.cli.process`)."""
    from hrtls.cli import process

    process.own()
    try:
        app()
    finally:
        process.exiting()
