"""``hrtls config show``: the complete effective tracker configuration as TOML."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from hrtls.cli.errors import reports_errors

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Tracker configurations.")


@app.callback()
def _config() -> None:
    """Tracker configurations."""


@app.command("show")
@reports_errors
def show(
    preset_name: Annotated[str | None, typer.Option(
        "--preset", "-p", help="A named preset (default when neither option is given).")] = None,
    config: Annotated[Path | None, typer.Option(
        "--config", "-c", help="A TOML file (its unset keys take their defaults).")] = None,
) -> None:
    """Print every key with its effective value; edit it and pass it back with --config."""
    from hrtls.errors import InputError
    from hrtls.pipeline.config import load_config, preset, to_toml

    if config is not None and preset_name is not None:
        raise InputError("both --config and --preset", where="hrtls config show",
                         expected="at most one of them")
    cfg = load_config(config) if config is not None else preset(preset_name or "default")
    typer.echo(to_toml(cfg), nl=False)
