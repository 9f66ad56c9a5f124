"""Where input bytes come from: a folder, a zip (read in memory, never extracted) or one file.

A zip's members with absolute paths, drive letters or ``..`` are refused, and the total
uncompressed size is capped (``max_bytes``), so reading a hostile archive cannot write anywhere
or exhaust memory. Session folders (:mod:`hrtls.io.session`) and user formats
(:mod:`hrtls.io.readers`) both read through :func:`open_source`.
"""

from __future__ import annotations

import re
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Literal

import pyarrow as pa

from hrtls.errors import FormatError, InputError

DEFAULT_MAX_BYTES = 2 * 1024**3
"""Largest total uncompressed size of an input (zip members or folder files), bytes."""

# --------------------------------------------------------------------------------------------
# Sources: folder, zip or single file
# --------------------------------------------------------------------------------------------


def _hidden(parts: Sequence[str]) -> bool:
    """Hidden files and macOS zip clutter (``.DS_Store``, ``__MACOSX/``) are not data."""
    return any(p.startswith(".") or p == "__MACOSX" for p in parts)


@dataclass
class Source:
    """Files of one input, read as bytes by their relative (POSIX) name.

    Attributes
    ----------
    path:
        The folder, zip or file the user gave.
    names:
        Relative member names (sorted). A single file has one member: its file name.
    kind:
        ``"folder"``, ``"zip"`` or ``"file"``.
    """

    path: Path
    names: list[str]
    kind: Literal["folder", "zip", "file"]
    _reader: Callable[[str, int], bytes]
    _opener: Callable[[str], IO[bytes]] | None = None
    _sizer: Callable[[str], int] | None = None

    def open(self, name: str) -> IO[bytes]:
        """Member ``name`` as a binary file (read in pieces, for files too large to hold)."""
        if name not in self.names:
            raise InputError(f"no member {name!r}", where=str(self.path),
                             expected=f"one of {', '.join(self.names[:10])}")
        if self._opener is None:
            return (self.path if self.kind == "file" else self.path / name).open("rb")
        return self._opener(name)

    def read(self, name: str) -> bytes:
        """Contents of member ``name``."""
        return self.head(name, -1)

    def buffer(self, name: str) -> pa.Buffer:
        """Contents of member ``name`` as an Arrow buffer; a file is memory-mapped, not copied."""
        if name not in self.names:
            raise InputError(f"no member {name!r}", where=str(self.path),
                             expected=f"one of {', '.join(self.names[:10])}")
        if self.kind == "zip":
            return pa.py_buffer(self.read(name))
        path = self.path if self.kind == "file" else self.path / name
        try:
            with pa.memory_map(str(path)) as mapped:
                return mapped.read_buffer()
        except OSError as exc:
            raise InputError(f"cannot be read ({exc})", where=str(path),
                             expected="a readable file") from None

    def head(self, name: str, n_bytes: int) -> bytes:
        """The first ``n_bytes`` of member ``name`` (all of it for ``-1``)."""
        if name not in self.names:
            raise InputError(f"no member {name!r}", where=str(self.path),
                             expected=f"one of {', '.join(self.names[:10])}")
        return self._reader(name, n_bytes)

    def size(self, name: str) -> int:
        """Bytes of member ``name`` (uncompressed)."""
        if name not in self.names:
            raise InputError(f"no member {name!r}", where=str(self.path),
                             expected=f"one of {', '.join(self.names[:10])}")
        if self._sizer is not None:
            return self._sizer(name)
        return (self.path if self.kind == "file" else self.path / name).stat().st_size

    def label(self, name: str) -> str:
        """How a member is named in messages: ``folder/name``, ``archive.zip:name`` or the file."""
        if self.kind == "file":
            return str(self.path)
        if self.kind == "zip":
            return f"{self.path}:{name}"
        return str(self.path / name)

    def by_basename(self) -> dict[str, list[str]]:
        """Members grouped by their lower-case base name."""
        out: dict[str, list[str]] = {}
        for name in self.names:
            out.setdefault(PurePosixPath(name).name.lower(), []).append(name)
        return out

    def find(self, basename: str) -> str | None:
        """The one member whose base name is ``basename`` (case-insensitive), or None.

        Raises
        ------
        FormatError
            When several members have that name (the input holds several recordings).
        """
        found = self.by_basename().get(basename.lower(), [])
        if len(found) > 1:
            raise FormatError(f"{len(found)} files named {basename} ({', '.join(found)})",
                              where=str(self.path),
                              expected="one recording per folder or zip")
        return found[0] if found else None


def open_source(path: Path | str, *, max_bytes: int = DEFAULT_MAX_BYTES,
                zip_allowed: bool = True) -> Source:
    """Open a folder, a zip or a single file as a :class:`Source`.

    Zip members are read in memory; members with absolute paths, drive letters or ``..`` are
    refused, and so is a total uncompressed size above ``max_bytes``.

    Raises
    ------
    InputError
        When the path does not exist.
    FormatError
        For an unreadable or unsafe zip, or one that is too large.
    """
    path = Path(path)
    if max_bytes <= 0:
        raise InputError(f"max_bytes = {max_bytes}", where="max_bytes",
                         expected="a positive number of bytes")
    if path.is_dir():
        files = sorted(p for p in path.rglob("*")
                       if p.is_file() and not _hidden(p.relative_to(path).parts))
        total = sum(p.stat().st_size for p in files)
        if total > max_bytes:
            raise FormatError(f"{total} bytes in the folder", where=str(path),
                              expected=f"at most {max_bytes} bytes (raise max_bytes if intended)")
        names = [p.relative_to(path).as_posix() for p in files]
        return Source(path, names, "folder", lambda n, k: _read_file(path / n, k))
    if not path.is_file():
        raise InputError("no such file or folder", where=str(path),
                         expected="an existing file, folder or zip")
    if zip_allowed and zipfile.is_zipfile(path):
        return _zip_source(path, max_bytes)
    size = path.stat().st_size
    if size > max_bytes:
        raise FormatError(f"{size} bytes", where=str(path),
                          expected=f"at most {max_bytes} bytes (raise max_bytes if intended)")
    return Source(path, [path.name], "file", lambda n, k: _read_file(path, k))


def _read_file(path: Path, n_bytes: int) -> bytes:
    try:
        with path.open("rb") as fh:
            return fh.read(n_bytes)
    except OSError as exc:
        raise InputError(f"cannot be read ({exc.strerror})", where=str(path),
                         expected="a readable file") from None


def _zip_source(path: Path, max_bytes: int) -> Source:
    try:
        zf = zipfile.ZipFile(path)
        infos = [i for i in zf.infolist() if not i.is_dir()]
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise FormatError(f"not a readable zip ({exc})", where=str(path),
                          expected="an intact zip archive") from None
    members: dict[str, zipfile.ZipInfo] = {}
    for info in infos:
        raw = info.filename
        pure = PurePosixPath(raw)
        if (pure.is_absolute() or ".." in pure.parts or "\\" in raw
                or re.match(r"^[A-Za-z]:", raw)):
            raise FormatError(f"member {raw!r} points outside the archive", where=str(path),
                              expected="relative member names without '..'")
        if _hidden(pure.parts):
            continue
        members[pure.as_posix()] = info
    total = sum(i.file_size for i in members.values())
    if total > max_bytes:
        raise FormatError(f"{total} bytes uncompressed", where=str(path),
                          expected=f"at most {max_bytes} bytes (raise max_bytes if intended)")

    def read(name: str, n_bytes: int) -> bytes:
        info = members[name]
        try:
            with zf.open(info) as fh:
                if n_bytes >= 0:
                    return fh.read(n_bytes)
                data = fh.read(info.file_size + 1)
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, RuntimeError,
                NotImplementedError) as exc:
            raise FormatError(f"member cannot be read ({exc})", where=f"{path}:{name}",
                              expected="an intact, unencrypted zip") from None
        if len(data) != info.file_size:
            raise FormatError("member size differs from its header", where=f"{path}:{name}",
                              expected="an intact zip")
        return data

    return Source(path, sorted(members), "zip", read, lambda name: zf.open(members[name]),
                  lambda name: members[name].file_size)
