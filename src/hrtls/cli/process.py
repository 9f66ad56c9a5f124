"""The ``hrtls`` process: the garbage collector leaves alone what lives until it exits.

The modules a command imports (classes, functions, compiled-kernel dispatchers: most of the
objects the collector tracks) live until the process exits, yet every full collection, and
those of the interpreter's exit, walk them again. A command calls :func:`imports_done` once
its imports are done, and :func:`hrtls.cli.app.main` calls :func:`exiting` when the command
returns: both move the tracked objects to the collector's permanent generation
(:func:`gc.freeze`), which it does not walk; nothing is freed early or late because of it,
the files are written and closed by then. Only in the ``hrtls`` process (:func:`own`): a
command run inside another program (tests, ``CliRunner``) leaves its collector alone.
"""

from __future__ import annotations

import gc

_OWNED: list[bool] = [False]


def own() -> None:
    """This process is the ``hrtls`` command's own (called by its entry point)."""
    _OWNED[0] = True


def imports_done() -> None:
    """Freeze the objects made so far (the imports) out of the collector's passes."""
    if _OWNED[0]:
        gc.freeze()


def exiting() -> None:
    """The command is done: freeze what is alive, so that the exit does not walk it again."""
    if _OWNED[0]:
        gc.freeze()
