"""Output paths checked before a command does its work: the message names the flag and path."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hrtls.errors import InputError


def _nearest_existing(path: Path) -> Path:
    """``path`` or the closest of its parents that exists."""
    probe = path.absolute()
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def check_writable(path: Path, *, flag: str, folder: bool) -> None:
    """Refuse an output that cannot be written, before any work is done.

    ``path`` is the folder (``folder``) or file to write; it need not exist. Its nearest existing
    parent must be a folder in which a test folder can be made (and removed): a parent that is a
    file, a read-only or virtual file system, or missing permissions raise
    :class:`~hrtls.errors.InputError` naming ``flag`` and ``path``.
    """
    target = path.absolute()
    if target.exists():
        if folder and not target.is_dir():
            raise InputError("is a file", where=f"{flag} {path}",
                             expected="a folder to write into (a new or an empty one)")
        if not folder and target.is_dir():
            raise InputError("is a folder", where=f"{flag} {path}", expected="a file path")
    base = target if target.is_dir() else _nearest_existing(target.parent)
    if not base.is_dir():
        raise InputError(f"{base} is a file, not a folder", where=f"{flag} {path}",
                         expected="a path whose parents are folders")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".hrtls-write-test-", dir=base))
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise InputError(f"cannot write in {base} ({reason})", where=f"{flag} {path}",
                         expected="a folder where hrtls may create files") from None
