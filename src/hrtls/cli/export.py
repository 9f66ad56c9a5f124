"""Command ``hrtls export``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from hrtls.cli.errors import reports_errors

console = Console(highlight=False)


@reports_errors
def export(
    result_dir: Annotated[Path, typer.Argument(help="Result folder of `hrtls track`.")],
    to: Annotated[str, typer.Option("--to", help="gpx | mf-json | geojson | csv")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="File to write (default: in RESULT_DIR).")] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace an existing file.")] = False,
) -> None:
    """Export a result as GPX, OGC Moving Features JSON, GeoJSON or CSV.

    GPX needs a georeferenced recording, Moving Features one with absolute times; without a
    georeference GeoJSON is written as local metres (trajectory.local.json, a type that map
    tools refuse rather than misplace).
    """
    from hrtls.cli.paths import check_writable
    from hrtls.jobs.export import export_result

    if output is not None:
        check_writable(output, flag="--output", folder=False)
    written = export_result(result_dir, to=to, output=output, overwrite=overwrite)
    console.print(f"wrote {written}")
