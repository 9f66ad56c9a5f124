"""How the CLI reports problems: one clear line and a non-zero exit, details with --verbose."""

from __future__ import annotations

import functools
import re
import traceback
import warnings
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import typer
from rich.console import Console

from hrtls.errors import DegradedInputWarning, HrtlsError, RepairWarning

P = ParamSpec("P")
R = TypeVar("R")

err_console = Console(stderr=True, highlight=False)

EXIT_INPUT = 2
EXIT_INTERNAL = 3


class Verbosity:
    """Process-wide --verbose flag set by the root callback."""

    verbose = False


_PYTHON_TO_CLI = (
    (re.compile(r" \(repair=True in Python\)"), ""),
    (re.compile(r"\brepair=True\b"), "--repair"),
    (re.compile(r"\bfmt=(?:\.\.\.)?"), "--format"),
    (re.compile(r"\btrial=(?:\.\.\.)?"), "--trial"),
    (re.compile(r"\bbeacons=(?:\.\.\.)?"), "--beacons"),
    (re.compile(r"\boverwrite=True\b"), "--overwrite"),
    (re.compile(r" \(readers: \w+_unit='[^']*'\)"), ""),
    (re.compile(r"; pass include_wifi=True to keep them as RSS readings"), ""),
    (re.compile(r"rename it or pass sensors=\{[^}]*\}"),
     "rename it after its sensor (e.g. accelerometer.txt)"),
    (re.compile(r"pass sensors=\{[^}]*\} if the name does not say it"),
     "name the file after its sensor (e.g. accelerometer.txt)"),
    (re.compile(r", or sensors=\{file: kind\}"), ""),
    (re.compile(r"; pass sensors= to choose"), "; move the others out of the folder"),
    (re.compile(r"pass time_unit='[^)]*'"), "give the times in s, ms or ns"),
    (re.compile(r", or a stated time_unit"), ""),
    (re.compile(r"pass platform='ios' for an iPhone export"),
     "keep the export's Metadata.csv (it names the platform)"),
)
"""Library hints name Python arguments; the CLI names its flags instead."""


def cli_text(message: object) -> str:
    """``message`` with Python argument names replaced by the CLI flags that set them."""
    text = str(message)
    for pattern, flag in _PYTHON_TO_CLI:
        text = pattern.sub(flag, text)
    return text


def _show_warning(message: warnings.WarningMessage) -> None:
    labels: dict[type[Warning], str] = {RepairWarning: "repaired", DegradedInputWarning: "note"}
    kind = labels.get(message.category, "warning")
    err_console.print(f"[yellow]{kind}:[/yellow] {cli_text(message.message)}", markup=True)


def reports_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Wrap a command: hrtls errors become one line + exit 2, warnings are printed once."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                result = func(*args, **kwargs)
            except HrtlsError as exc:
                _flush(caught)
                if Verbosity.verbose:
                    err_console.print(traceback.format_exc(), markup=False)
                err_console.print(f"[red]error:[/red] {cli_text(exc)}", markup=True,
                                  soft_wrap=True)
                raise typer.Exit(EXIT_INPUT) from None
            except (OSError, MemoryError) as exc:
                _flush(caught)
                if Verbosity.verbose:
                    err_console.print(traceback.format_exc(), markup=False)
                err_console.print(f"[red]error:[/red] {exc}", markup=True, soft_wrap=True)
                raise typer.Exit(EXIT_INPUT) from None
            except (typer.Exit, typer.Abort, KeyboardInterrupt):
                _flush(caught)
                raise
            except Exception as exc:
                _flush(caught)
                if Verbosity.verbose:
                    err_console.print(traceback.format_exc(), markup=False)
                err_console.print(
                    f"[red]internal error:[/red] {type(exc).__name__}: {exc} "
                    "(this is a bug in hrtls; run with --verbose and report it)",
                    markup=True, soft_wrap=True)
                raise typer.Exit(EXIT_INTERNAL) from None
        _flush(caught)
        return result

    return wrapper


def _flush(caught: list[warnings.WarningMessage]) -> None:
    seen: set[str] = set()
    for message in caught:
        text = str(message.message)
        if text in seen:
            continue
        seen.add(text)
        _show_warning(message)
