"""Any recording in one call: format sniffing over the user formats and the public datasets.

This module sits above :mod:`hrtls.io` (readers of the formats users have) and
:mod:`hrtls.datasets` (the public recordings, whose loaders may use the io readers), so that
neither of them imports the other's registry. :func:`detect_format` looks at names and the first
bytes of the files (never at whole files); :func:`read_any` detects the format when it is not
given and calls the reader registered in :data:`FORMATS`.

Signatures looked for, in this order:

* ``hrtls-session``: a folder or zip with session files (``imu.csv``, ``session.json``, ...);
* the public datasets of :mod:`hrtls.datasets.formats` (``mobgap``, ``oxford-step``,
  ``broad``, ``ble-rssi``), recognized by their file names and first bytes;
* ``sensorlogger``: ``Metadata.csv`` or known sensor files whose header starts
  ``time,seconds_elapsed``;
* ``phyphox``: a CSV whose header starts with ``"Time (s)"``;
* ``ipin``: lines ``ACCE;``, ``POSI;`` ... or the GetSensorData header;
* ``android``: files named after a sensor whose first data line is ``TIMESTAMP X Y Z``.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any

from hrtls.data import Session
from hrtls.data.clocks import check_session_clocks
from hrtls.datasets import formats as dataset_formats
from hrtls.errors import FormatError, InputError
from hrtls.io.readers.android import read_android, sensor_from_name
from hrtls.io.readers.ipin import looks_like_ipin, read_ipin
from hrtls.io.readers.phyphox import looks_like_phyphox, read_phyphox
from hrtls.io.readers.sensorlogger import SENSOR_LOGGER_FILES, read_sensorlogger
from hrtls.io.source import DEFAULT_MAX_BYTES, Source, open_source

__all__ = ["FORMATS", "detect_format", "read_any", "reader_options"]

_HEAD_BYTES = 4096
_MAX_SNIFFED = 200


def _read_hrtls_session(path: Path | str, *, repair: bool = False, check_units: bool = True,
                        max_bytes: int = DEFAULT_MAX_BYTES) -> Session:
    """Read an hrtls session folder or zip (the canonical interchange format)."""
    from hrtls.io.session import read_session

    return read_session(path, repair=repair, check_units=check_units, max_bytes=max_bytes)


FORMATS: dict[str, Callable[..., Session]] = {
    "hrtls-session": _read_hrtls_session,
    "sensorlogger": read_sensorlogger,
    "phyphox": read_phyphox,
    "ipin": read_ipin,
    "android": read_android,
    "mobgap": dataset_formats.read_mobgap,
    "oxford-step": dataset_formats.read_oxford,
    "broad": dataset_formats.read_broad,
    "ble-rssi": dataset_formats.read_ble_rssi,
}
"""Format name -> reader ``(path, *, repair=False, **options) -> Session``."""

_SL_NAMES = {n.lower() for n in SENSOR_LOGGER_FILES}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_ANDROID_LINE = re.compile(rf"^\s*{_NUMBER}(?:\s*[\s,;]\s*{_NUMBER}){{3}}\s*$")


def _is_session(path: Path) -> bool:
    from hrtls.io.session import is_session

    try:
        return bool(is_session(path))
    except (InputError, OSError, ValueError):
        return False


def _android_like(name: str, head: bytes) -> bool:
    try:
        if sensor_from_name(name) is None:
            return False
    except FormatError:
        return False
    lines = [ln for ln in head.decode("utf-8", errors="replace").splitlines()[:5]
             if ln.strip() and not ln.lstrip().startswith(("#", "%"))]
    return any(_ANDROID_LINE.match(ln) for ln in lines[:2])


def _sniff(src: Source) -> set[str]:
    found: set[str] = set()
    for name in src.names[:_MAX_SNIFFED]:
        head = src.head(name, _HEAD_BYTES)
        base = PurePosixPath(name).name.lower()
        first = head.decode("utf-8", errors="replace").lstrip("\ufeff").split("\n", 1)[0]
        first = first.strip().lower().replace('"', "")
        if base in _SL_NAMES and (first.startswith("time,seconds_elapsed")
                                  or (base == "metadata.csv" and "platform" in first)):
            found.add("sensorlogger")
        elif base.endswith((".csv", ".txt")) and looks_like_phyphox(head):
            found.add("phyphox")
        elif looks_like_ipin(head):
            found.add("ipin")
        elif _android_like(name, head):
            found.add("android")
    return found


def detect_format(path: Path | str, *, max_bytes: int = DEFAULT_MAX_BYTES) -> str:
    """The name of the format of ``path`` (a key of :data:`FORMATS`).

    Raises
    ------
    InputError
        When the path does not exist.
    FormatError
        When no format, or more than one, fits.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file or folder", where=str(path),
                         expected="a recording file, folder or zip")
    if path.is_file() and path.stat().st_size <= _HEAD_BYTES and not path.read_bytes().strip():
        raise FormatError("file is empty", where=str(path), expected="a recording")
    if (path.is_dir() or path.suffix.lower() == ".zip") and _is_session(path):
        return "hrtls-session"
    for name, looks_like in (("mobgap", dataset_formats.looks_like_mobgap),
                             ("oxford-step", dataset_formats.looks_like_oxford),
                             ("broad", dataset_formats.looks_like_broad),
                             ("ble-rssi", dataset_formats.looks_like_ble_rssi)):
        if looks_like(path):
            return name
    src = open_source(path, max_bytes=max_bytes)
    found = _sniff(src)
    if len(found) == 1:
        return found.pop()
    if not found:
        raise FormatError("format not recognized", where=str(path),
                          expected="an hrtls session, a Sensor Logger or phyphox export, an "
                          "IPIN logfile or Android TIMESTAMP X Y Z files",
                          hint=f"pass fmt= (one of {', '.join(FORMATS)})")
    raise FormatError(f"looks like several formats ({', '.join(sorted(found))})",
                      where=str(path), expected="one recording in one format",
                      hint="pass fmt= to choose")


def reader_options(fmt: str | None, *, trial: str | None = None) -> dict[str, Any]:
    """Reader options from CLI flags: only those given, refused for formats without them."""
    options: dict[str, Any] = {}
    if trial is not None:
        reader = FORMATS.get(fmt or "")
        if reader is not None and "trial" not in inspect.signature(reader).parameters:
            raise InputError(f"--trial given for a {fmt} recording", where="--trial",
                             expected="a format with trials ("
                             + ", ".join(n for n, r in FORMATS.items()
                                         if "trial" in inspect.signature(r).parameters) + ")")
        options["trial"] = trial
    return options


def read_any(path: Path | str, *, fmt: str | None = None, repair: bool = False,
             beacons: Path | str | None = None, **options: Any) -> Session:
    """Read any supported recording into a session.

    Parameters
    ----------
    path:
        A file, folder or zip.
    fmt:
        The format (a key of :data:`FORMATS`); detected when None.
    repair:
        Let the reader repair duplicates, backward times and non-finite rows, and remove clock
        jumps of single streams (:func:`hrtls.data.clocks.check_session_clocks`), all with
        warnings. Without it such problems raise; gaps of every stream are kept (warned).
    beacons:
        Beacon landmark CSV (IPIN logfiles only).
    **options:
        Keyword options of the chosen reader (e.g. ``time_unit="ms"`` for android).

    Raises
    ------
    InputError, FormatError
        Unknown format or option, or whatever the reader reports.
    """
    name = fmt if fmt is not None else detect_format(path)
    reader = FORMATS.get(name)
    if reader is None:
        raise InputError(f"unknown format {name!r}", where="fmt",
                         expected=f"one of {', '.join(FORMATS)}")
    if beacons is not None:
        if name != "ipin":
            raise InputError(f"beacons= given for a {name} recording", where="beacons",
                             expected="beacon positions only with IPIN logfiles",
                             hint="add landmarks to the session instead")
        options["beacons"] = beacons
    accepted = [p for p in inspect.signature(reader).parameters if p not in ("path", "repair")]
    unknown = sorted(set(options) - set(accepted))
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)} for format {name}",
                         where="read_any", expected=f"options among {', '.join(accepted)}")
    session = reader(path, repair=repair, **options)
    session, _ = check_session_clocks(session, repair=repair)
    return session
