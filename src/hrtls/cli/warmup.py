"""Command ``hrtls warmup``."""

from __future__ import annotations

from rich.console import Console

from hrtls.cli.errors import reports_errors

console = Console(highlight=False)


@reports_errors
def warmup() -> None:
    """Compile the numerical kernels now (once per install) so that later runs start at once."""
    from hrtls.jobs.warmup import warm_up

    with console.status("compiling") as status:
        seconds = warm_up(progress=lambda msg: status.update(msg))
    console.print(f"kernels compiled and cached ({seconds:.1f} s)")
