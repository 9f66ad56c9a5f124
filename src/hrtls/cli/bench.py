"""``hrtls bench papers``: the papers' scenarios with their own presets and with ``default``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from hrtls.cli.errors import reports_errors
from hrtls.errors import InputError

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Benchmarks against the papers' published figures.")
console = Console(highlight=False)


@app.callback()
def _bench() -> None:
    """Benchmarks against the papers' published figures."""


@app.command("papers")
@reports_errors
def papers(
    seeds: Annotated[str, typer.Option(
        "--seeds", "-n", help="held-out (100-129, published), dev (0-9, for tuning), A-B or "
                              "a,b,c.")] = "held-out",
    quick: Annotated[bool, typer.Option("--quick", help="A subset of the cases, one seed.")
                     ] = False,
    only: Annotated[list[str] | None, typer.Option(
        "--only", help="Keep the cases whose label contains this text (repeatable), "
                       "e.g. --only colombo.")] = None,
    engine_name: Annotated[str, typer.Option(
        "--engine", help="Where the case-seeds run: local | ray (same numbers either way).")]
    = "local",
    workers: Annotated[int | None, typer.Option(
        help="Case-seeds run at once (default: all cores).")] = None,
    ray_address: Annotated[str | None, typer.Option(
        help="With --engine ray: cluster address (default: a local Ray).")] = None,
    json_out: Annotated[Path | None, typer.Option(
        "--json", help="Write the rows as JSON to this file.")] = None,
    markdown_out: Annotated[Path | None, typer.Option(
        "--markdown", help="Write the README's Markdown table to this file.")] = None,
    from_json: Annotated[Path | None, typer.Option(
        "--from-json", help="Do not run: print (and --markdown) the rows of an earlier --json "
                            "file.")] = None,
) -> None:
    """Run each paper's scenario with its preset and with default; print one table."""
    from hrtls.jobs.bench import (
        DEFINITIONS,
        BenchRow,
        describe_seeds,
        markdown_table,
        parse_seeds,
        run_bench,
        stats_text,
    )
    from hrtls.runner import make_engine

    if from_json is not None:
        try:
            data = json.loads(from_json.read_text())
            rows = [BenchRow.from_dict(d) for d in data["rows"]]
            used = tuple(int(v) for v in data["seeds"])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"{type(exc).__name__}: {exc}", where=str(from_json),
                             expected="a file written by hrtls bench papers --json") from None
    else:
        seed_list = parse_seeds(seeds)
        engine = make_engine(engine_name, workers=workers, ray_address=ray_address)
        with console.status("running") as status:
            rows = run_bench(seeds=seed_list, quick=quick, only=only or None, engine=engine,
                             progress=lambda msg: status.update(msg))
        used = seed_list[:1] if quick else seed_list
    table = Table("scenario", "metric", "paper figure", "paper preset (ours)",
                  "default preset", "mean beats paper", "our goal (on p90)", "met?",
                  title=f"hrtls bench papers (simulated, {describe_seeds(used)}: "
                        "mean / p90 / worst over seeds)")
    for r in rows:
        met = "-" if r.met is None else ("[green]yes[/green]" if r.met else "[red]no[/red]")
        table.add_row(r.scenario, r.metric, r.paper,
                      f"{r.paper_preset}: {stats_text(r.paper_stats)}",
                      stats_text(r.default_stats),
                      "-" if r.beats_paper is None else ("yes" if r.beats_paper else "no"),
                      r.target, met)
    Console(highlight=False, width=max(console.width, 160)).print(table)
    for r in rows:
        if r.note.startswith("with - without"):
            console.print(f"[dim]{r.scenario}: {r.note}[/dim]")
    for key, text in DEFINITIONS.items():
        console.print(f"[dim]{key}: {text}[/dim]")
    if json_out is not None and from_json is None:
        json_out.write_text(json.dumps({"seeds": list(used), "rows": [r.to_dict() for r in rows]},
                                       indent=2) + "\n")
    if markdown_out is not None:
        markdown_out.write_text(markdown_table(rows))
