"""The ``hrtls`` command."""

from __future__ import annotations

import typer

app = typer.Typer(no_args_is_help=True, help="Hybrid Rescue Team Localization System.")


@app.callback()
def _root() -> None:
    """Hybrid Rescue Team Localization System."""


def main() -> None:
    """Entry point of the ``hrtls`` console script."""
    app()
