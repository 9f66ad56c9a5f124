"""``hrtls track DIR_OR_GLOB -o OUT``: many recordings on one engine, with a progress bar."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from hrtls.errors import InputError

console = Console(highlight=False)


def track_batch(spec: str, output: Path, *, config: Path | None, preset_name: str | None,
                plot: bool, repair: bool, overwrite: bool, engine: str, workers: int | None,
                ray_address: str | None) -> None:
    """Track every recording of ``spec`` into ``output``; print the summary table."""
    from hrtls.cli.config import chosen_config
    from hrtls.cli.paths import check_writable
    from hrtls.jobs.batch import find_recordings, plan_batch, run_batch
    from hrtls.runner import make_engine

    chosen_config(config, preset_name, command="hrtls track")  # a bad one fails before any work
    if output.exists() and not output.is_dir():
        raise InputError("exists and is not a folder", where=f"--output {output}",
                         expected="a folder for the batch results")
    check_writable(output, flag="--output", folder=True)
    recordings = find_recordings(spec)
    tasks = plan_batch(recordings, output, preset=preset_name, config_path=config,
                       repair=repair, overwrite=overwrite, plot=plot)
    runner = make_engine(engine, workers=workers, ray_address=ray_address)
    with Progress(TextColumn("tracking"), BarColumn(), MofNCompleteColumn(),
                  TimeRemainingColumn(), console=console, transient=True,
                  disable=not console.is_terminal) as bar:
        job = bar.add_task("batch", total=len(tasks))
        result = run_batch(tasks, output, engine=runner,
                           progress=lambda done, total: bar.update(job, completed=done))
    table = Table("recording", "status", "steps", "walked m", "checkpoint mean m", "p90 m",
                  "error", title=f"hrtls track: {len(tasks)} recordings on {runner.name} "
                  f"({runner.workers} workers)")
    for r in result.rows:
        table.add_row(Path(r["recording"]).name, r["status"], _cell(r["steps"], "{:d}"),
                      _cell(r["distance_walked_m"]), _cell(r["checkpoint_mean_m"]),
                      _cell(r["error_p90_m"]), r["error"] or "")
    Console(highlight=False, width=max(console.width, 120)).print(table)
    console.print(f"wrote {result.summary_csv}")
    if result.failed:
        raise InputError(f"{result.failed} of {len(tasks)} recordings failed",
                         where=str(result.summary_csv), expected="every recording tracked")


def _cell(value: object, fmt: str = "{:.2f}") -> str:
    return "-" if value is None else fmt.format(value)
