"""Commands ``hrtls track`` and ``hrtls demo``."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import cli_text, reports_errors
from hrtls.cli.process import imports_done
from hrtls.jobs.warmup import mark_compiled

if TYPE_CHECKING:
    from hrtls.jobs.track import Progress
    from hrtls.pipeline.config import TrackerConfig
    from hrtls.pipeline.tracker import TrackResult

console = Console(highlight=False)


@contextlib.contextmanager
def progress_bars(show: bool | None) -> Iterator[Progress | None]:
    """A rich progress bar with ETA fed by :data:`hrtls.jobs.track.Progress` calls.

    ``show`` None: only when the console is a terminal. Reading has no total (a pulsing bar).
    """
    if not (console.is_terminal if show is None else show):
        yield None
        return
    from rich.progress import (
        BarColumn,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.progress import Progress as Bars

    with Bars(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
              TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), console=console,
              transient=True) as bars:
        task = bars.add_task("starting", total=None)

        def update(what: str, done: float, total: float | None) -> None:
            bars.update(task, description=what, completed=done, total=total)

        yield update


def _fmt(value: float | None, unit: str = " m") -> str:
    return "-" if value is None else f"{value:.2f}{unit}"


def _refuse_engine_options(session: Path, *, engine: str, workers: int | None,
                           ray_address: str | None) -> None:
    """``--engine``, ``--workers`` and ``--ray-address`` are errors for one recording."""
    if engine != "local" or workers is not None or ray_address is not None:
        from hrtls.errors import InputError

        raise InputError("--engine, --workers and --ray-address are for batches",
                         where=str(session),
                         expected="a folder of recordings or a glob (one recording: no engine)")


def _track_one(session: Path, output: Path, *, cfg: TrackerConfig, repair: bool,
               beacons: Path | None, fmt: str | None, trial: str | None, plot: bool,
               overwrite: bool, format_out: str, show_progress: bool | None) -> None:
    """Track one recording, write its results to ``output`` and print a summary."""
    from hrtls.cli.paths import check_writable
    from hrtls.errors import InputError
    from hrtls.jobs.track import (
        check_output_dir,
        evaluate_track,
        reference_steps,
        track_recording,
        write_track_outputs,
    )

    imports_done()
    if format_out not in ("csv", "parquet"):
        raise InputError(f"{format_out!r}", where="--format-out", expected="csv or parquet")
    if not session.exists():
        raise InputError("no such file or folder", where=str(session),
                         expected="a recording (session folder, zip, logfile, ...)")
    check_output_dir(output, overwrite=overwrite)
    check_writable(output, flag="--output", folder=True)
    with progress_bars(show_progress) as progress:
        run = track_recording(session, cfg, repair=repair, beacons=beacons, fmt=fmt,
                              trial=trial, progress=progress)
    result, data, n, seconds = run.result, run.session, run.samples, run.tracker_s
    del run
    evaluation = evaluate_track(result, data)
    reference = reference_steps(result, data)
    if not plot:  # the ground truth is not needed any more: not held while writing
        data = data.with_parts(truth=None)
    if reference is not None:
        result.report["reference_steps"] = reference
    write_track_outputs(result, data, output, overwrite=overwrite, plot=plot,
                        evaluation=evaluation, table_format="parquet"
                        if format_out == "parquet" else "csv")
    _print_summary(result, name=cfg.name, samples=n, tracker_s=seconds, reference=reference,
                   evaluation=evaluation)
    console.print(f"wrote {output}")


def _print_summary(result: TrackResult, *, name: str, samples: int, tracker_s: float,
                   reference: dict[str, Any] | None, evaluation: dict[str, Any] | None) -> None:
    """Steps, distance, speed, reference steps, corrections, notes and the evaluation."""
    from hrtls.cli.sim import report_table

    n, seconds = samples, tracker_s
    summary = result.report["summary"]
    console.print(f"[bold]{name}[/bold]: {summary['steps']} steps, "
                  f"{summary['distance_walked_m']:.1f} m walked, "
                  f"{n:,} IMU samples in {seconds:.2f} s"
                  f"{f' ({n / seconds:,.0f} samples/s)' if n and seconds > 0 else ''}")
    if reference is not None:
        inside = reference.get("ours_in_reference_bouts")
        error = reference["error_fraction"]
        bouts = "" if inside is None else f", {inside} inside the reference walking bouts"
        off = "" if error is None else f", {100 * error:+.1f} %"
        counted = ("none" if reference["reference"] is None
                   else f"{reference['reference']}")
        console.print(f"steps: {reference['ours']} ours{bouts}; reference "
                      f"{counted} ({reference['source']}){off}")
    counts = result.report["corrections"]
    if counts:
        console.print("corrections: " + "; ".join(
            f"{kind} " + ", ".join(f"{v} {k}" for k, v in c.items())
            for kind, c in counts.items()))
    for note in result.report["notes"]:
        console.print(f"note: {cli_text(note)}")
    if evaluation is not None:
        console.print(report_table(evaluation))


@reports_errors
def track(
    session: Annotated[Path, typer.Argument(help="Session folder/zip or any supported recording.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Result folder to write.")],
    config: Annotated[Path | None, typer.Option("--config", "-c",
                                                help="Tracker configuration (TOML).")] = None,
    preset_name: Annotated[str | None, typer.Option(
        "--preset", "-p", help="default | colombo2014 | basso2017 | tarrio2011 | handheld-phone | "
        "inderst-rfid | inderst-range")] = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also write track.png.")] = False,
    repair: Annotated[bool, typer.Option("--repair", help="Repair bad rows (warns).")] = False,
    beacons: Annotated[Path | None, typer.Option(
        "--beacons", help="Beacon positions CSV for IPIN logfiles.")] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace existing results.")] = False,
    engine: Annotated[str, typer.Option(
        "--engine", help="Batch engine for a folder or glob of recordings: local | ray.")]
    = "local",
    workers: Annotated[int | None, typer.Option(
        "--workers", help="Batch: recordings tracked at once (default: all cores).")] = None,
    ray_address: Annotated[str | None, typer.Option(
        "--ray-address", help="Batch with --engine ray: cluster address (default: local Ray).")]
    = None,
    format_out: Annotated[str, typer.Option(
        "--format-out", help="Trajectory and steps tables as csv | parquet.")] = "csv",
    fmt: Annotated[str | None, typer.Option(
        "--format", "-f", help="Input format (default: detected). See `hrtls formats`.")] = None,
    trial: Annotated[str | None, typer.Option(
        "--trial", help="Trial of a multi-trial recording (mobgap: e.g. Test5/Trial1).")] = None,
    show_progress: Annotated[bool | None, typer.Option(
        "--progress/--no-progress", help="Progress bars (default: only on a terminal).")]
    = None,
) -> None:
    """Track a recording: trajectory.csv, steps.csv, trajectory.geojson, report.json.

    A session folder or zip is read in chunks (bounded memory) unless --repair is given.

    SESSION may also be a folder of recordings or a quoted glob ('runs/*.zip'): each recording
    gets a result folder under OUTPUT and OUTPUT/summary.csv lists them all.
    """
    from hrtls.jobs.batch import is_batch

    if is_batch(str(session)):
        from hrtls.cli.batch import track_batch

        track_batch(str(session), output, config=config, preset_name=preset_name, plot=plot,
                    repair=repair, overwrite=overwrite, engine=engine, workers=workers,
                    ray_address=ray_address)
        return
    _refuse_engine_options(session, engine=engine, workers=workers, ray_address=ray_address)
    from hrtls.cli.config import chosen_config

    cfg = chosen_config(config, preset_name, command="hrtls track")
    _track_one(session, output, cfg=cfg, repair=repair, beacons=beacons, fmt=fmt, trial=trial,
               plot=plot, overwrite=overwrite, format_out=format_out,
               show_progress=show_progress)
    mark_compiled()


@reports_errors
def demo(
    output: Annotated[Path, typer.Option("--output", "-o", help="Folder for sessions, results "
                                                                "and plots.")] = Path("hrtls-demo"),
    seed: Annotated[int, typer.Option(help="Simulation seed.")] = 0,
) -> None:
    """Simulate the thesis' rescue missions and track them with and without infrastructure."""
    from hrtls.jobs.demo import MISSIONS, run_demo

    for mission, _, text in MISSIONS:
        console.print(f"[bold]{mission}[/bold]: {text}")
    with console.status("working") as status:
        rows = run_demo(output, seed=seed, overwrite=True,
                        progress=lambda msg: status.update(msg))
    table = Table("mission", "tracking", "steps", "walked m", "checkpoint mean m",
                  "checkpoint max m", "p90 error m", "time s", title="hrtls demo (simulated)")
    for row in rows:
        table.add_row(row.mission, row.method, str(row.steps), _fmt(row.distance_m, ""),
                      _fmt(row.checkpoint_mean_m, ""), _fmt(row.checkpoint_max_m, ""),
                      _fmt(row.error_p90_m, ""), f"{row.seconds:.2f}")
    Console(highlight=False, width=max(console.width, 120)).print(table)
    console.print(f"sessions, results (trajectory.csv, steps.csv, trajectory GeoJSON, "
                  f"report.json) and plots (track.png) are in {output}/")
    mark_compiled()
