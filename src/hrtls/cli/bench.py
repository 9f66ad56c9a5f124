"""``hrtls bench papers``: the papers' scenarios with their own presets and with ``default``."""

from __future__ import annotations

import math
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import reports_errors

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Benchmarks against the papers' published figures.")
console = Console(highlight=False)


@app.callback()
def _bench() -> None:
    """Benchmarks against the papers' published figures."""


def _num(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.2f}"


@app.command("papers")
@reports_errors
def papers(
    seeds: Annotated[int, typer.Option("--seeds", "-n", min=1,
                                       help="Simulation seeds per scenario.")] = 10,
    quick: Annotated[bool, typer.Option("--quick", help="A subset of the cases, one seed.")
                     ] = False,
    only: Annotated[list[str] | None, typer.Option(
        "--only", help="Keep the cases whose label contains this text (repeatable), "
                       "e.g. --only colombo.")] = None,
) -> None:
    """Run each paper's scenario with its preset and with default; print one table."""
    from hrtls.jobs.bench import DEFINITIONS, run_bench

    with console.status("running") as status:
        rows = run_bench(seeds=seeds, quick=quick, progress=lambda msg: status.update(msg),
                         only=only or None)
    n = 1 if quick else seeds
    table = Table("scenario", "metric", "paper figure", "paper preset (ours)",
                  "default preset", "target", "met?",
                  title=f"hrtls bench papers (simulated, {n} seed{'s' if n > 1 else ''}: "
                        "mean (worst))")
    for r in rows:
        met = "-" if r.met is None else ("[green]yes[/green]" if r.met else "[red]no[/red]")
        table.add_row(r.scenario, r.metric, r.paper,
                      f"{r.paper_preset}: {_num(r.paper_mean)} ({_num(r.paper_worst)})",
                      f"{_num(r.default_mean)} ({_num(r.default_worst)})", r.target, met)
    Console(highlight=False, width=max(console.width, 160)).print(table)
    for key, text in DEFINITIONS.items():
        console.print(f"[dim]{key}: {text}[/dim]")
