"""Byte form of a tracker's state: versioned header + zlib-compressed msgpack of plain values.

Only data are stored (numbers, strings, numeric arrays as raw little-endian bytes, and the
fields of a fixed list of state dataclasses, rebuilt by their constructors); no code is
pickled, so a snapshot from an untrusted source cannot run anything. :func:`pack` /
:func:`unpack` are the codec; :meth:`hrtls.pipeline.Tracker.snapshot` decides what goes in.
"""

from __future__ import annotations

import dataclasses
import zlib
from collections import deque
from typing import Any

import msgpack
import numpy as np

from hrtls.attitude.base import AttitudeState
from hrtls.calibration.hard_iron_running import RunningHardIronState
from hrtls.data import StepEvents
from hrtls.errors import FormatError
from hrtls.fusion.baro_floors import BaroFloorState
from hrtls.fusion.channel import ChannelState
from hrtls.fusion.fixes import FixSchedule, StretchMemory
from hrtls.fusion.rss_scans import RssScan
from hrtls.fusion.state import FilterState
from hrtls.fusion.tags import TagMemory

MAGIC = b"HRTLSNAP"
"""First bytes of every snapshot."""
VERSION = 2
"""Layout version (the byte after the magic); restore refuses others."""

_CLASSES: dict[str, type] = {c.__name__: c for c in (
    FilterState, ChannelState, StretchMemory, TagMemory, FixSchedule, RssScan, StepEvents,
    AttitudeState, RunningHardIronState, BaroFloorState)}
"""The dataclasses a snapshot may hold (rebuilt field by field)."""


def _encode(obj: Any) -> Any:
    if obj is None or isinstance(obj, bool | int | float | str | bytes):
        return obj
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fiub":
            arr = np.ascontiguousarray(obj)
            return {"~nd": arr.dtype.newbyteorder("<").str, "s": list(arr.shape),
                    "d": arr.astype(arr.dtype.newbyteorder("<"), copy=False).tobytes()}
        return {"~nl": [_encode(v) for v in obj.reshape(-1).tolist()], "s": list(obj.shape),
                "k": obj.dtype.kind}
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, tuple):
        return {"~t": [_encode(v) for v in obj]}
    if isinstance(obj, deque):
        return {"~q": [_encode(v) for v in obj], "m": obj.maxlen}
    if isinstance(obj, list):
        return [_encode(v) for v in obj]
    if isinstance(obj, dict):
        return {"~d": [[_encode(k), _encode(v)] for k, v in obj.items()]}
    if dataclasses.is_dataclass(obj) and type(obj).__name__ in _CLASSES:
        return {"~c": type(obj).__name__,
                "f": {f.name: _encode(getattr(obj, f.name)) for f in dataclasses.fields(obj)}}
    raise TypeError(f"cannot snapshot a {type(obj).__name__}")


def _decode(obj: Any) -> Any:
    if isinstance(obj, list):
        return [_decode(v) for v in obj]
    if not isinstance(obj, dict):
        return obj
    if "~nd" in obj:
        return np.frombuffer(obj["d"], dtype=np.dtype(obj["~nd"])).reshape(obj["s"]).copy()
    if "~nl" in obj:
        dtype = object if obj["k"] == "O" else str
        return np.array([_decode(v) for v in obj["~nl"]], dtype=dtype).reshape(obj["s"])
    if "~t" in obj:
        return tuple(_decode(v) for v in obj["~t"])
    if "~q" in obj:
        return deque((_decode(v) for v in obj["~q"]), maxlen=obj["m"])
    if "~d" in obj:
        return {_decode(k): _decode(v) for k, v in obj["~d"]}
    if "~c" in obj:
        cls = _CLASSES.get(obj["~c"])
        if cls is None:
            raise FormatError(f"unknown state class {obj['~c']!r}", where="snapshot",
                              expected=", ".join(_CLASSES))
        return cls(**{k: _decode(v) for k, v in obj["f"].items()})
    raise FormatError(f"unknown entry {sorted(obj)}", where="snapshot",
                      expected="a snapshot written by Tracker.snapshot()")


def pack(state: dict[str, Any]) -> bytes:
    """Header + zlib(msgpack(state)) with arrays as raw bytes."""
    body = msgpack.packb(_encode(state), use_bin_type=True)
    return MAGIC + bytes([VERSION]) + zlib.compress(body, 1)


def unpack(data: bytes) -> dict[str, Any]:
    """Inverse of :func:`pack`; a clear :class:`FormatError` for anything else."""
    if not isinstance(data, bytes | bytearray | memoryview):
        raise FormatError(f"a {type(data).__name__}", where="snapshot", expected="bytes")
    raw = bytes(data)
    if not raw.startswith(MAGIC) or len(raw) < len(MAGIC) + 1:
        raise FormatError("no hrtls snapshot header", where="snapshot",
                          expected="bytes from Tracker.snapshot()")
    version = raw[len(MAGIC)]
    if version != VERSION:
        raise FormatError(f"snapshot version {version}", where="snapshot",
                          expected=f"version {VERSION}")
    try:
        body = msgpack.unpackb(zlib.decompress(raw[len(MAGIC) + 1:]), raw=False,
                               strict_map_key=False)
    except (zlib.error, ValueError, msgpack.UnpackException) as exc:
        raise FormatError(f"corrupt snapshot ({exc})", where="snapshot",
                          expected="bytes from Tracker.snapshot()") from None
    out = _decode(body)
    if not isinstance(out, dict):
        raise FormatError("not a state mapping", where="snapshot", expected="a tracker state")
    return out
