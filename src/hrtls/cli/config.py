"""``hrtls config show``: the complete effective tracker configuration as TOML."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from hrtls.cli.errors import reports_errors

if TYPE_CHECKING:
    from hrtls.pipeline.config import TrackerConfig

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Tracker configurations.")


def chosen_config(config: Path | None, preset_name: str | None, *, command: str
                  ) -> TrackerConfig:
    """The configuration of ``--config FILE`` or ``--preset NAME`` (``default`` when neither).

    Raises
    ------
    InputError
        Both options given, an unknown preset, or a bad TOML file.
    """
    from hrtls.errors import InputError
    from hrtls.pipeline.config import load_config, preset

    if config is not None and preset_name is not None:
        raise InputError("both --config and --preset", where=command,
                         expected="at most one of them")
    return load_config(config) if config is not None else preset(preset_name or "default")


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
    from hrtls.pipeline.config import to_toml

    typer.echo(to_toml(chosen_config(config, preset_name, command="hrtls config show")),
               nl=False)
