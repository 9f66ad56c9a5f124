"""Command ``hrtls warmup``."""

from __future__ import annotations

from rich.console import Console

from hrtls.cli.errors import reports_errors

console = Console(highlight=False)


@reports_errors
def warmup() -> None:
    """Compile the numerical kernels now (once per install) so that later runs start at once.

    Then also ahead of time into an extension module (needs a C compiler; without one the
    JIT kernels are used), which ``hrtls track`` loads without importing numba.
    """
    from hrtls.jobs.warmup import build_ahead, warm_up

    with console.status("compiling") as status:
        seconds = warm_up(progress=lambda msg: status.update(msg))
    console.print(f"kernels compiled and cached ({seconds:.1f} s)")
    with console.status("compiling the kernels ahead of time (needs a C compiler)"):
        console.print(build_ahead())
