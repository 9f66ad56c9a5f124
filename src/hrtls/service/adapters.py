"""Phone apps as agents: Sensor Logger's HTTP push (IMU); GNSS apps: :mod:`.positions`.

Sensor Logger: each push message is written as the app's own CSV export (one file per sensor)
and read by :func:`hrtls.io.readers.sensorlogger.read_sensorlogger`, so sensor names, frames,
signs and units are mapped exactly as for an offline export. ``messageId`` is the batch
``seq``. The raw log keeps the message as received; its content type carries the mission's
``t0_unix`` so the stored body alone decodes to the same batch.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any

from hrtls.errors import HrtlsError
from hrtls.io.readers.sensorlogger import SENSOR_LOGGER_FILES, read_sensorlogger
from hrtls.pipeline.chunks import aligned_imu
from hrtls.service.batches import Batch, BatchError, from_chunk, parse_batch

_FILES = {Path(f).stem.lower(): f for f in SENSOR_LOGGER_FILES}
_COLUMNS = {"Barometer.csv": ("pressure",), "Orientation.csv": ("qw", "qx", "qy", "qz")}


def sensorlogger_batch(message: dict[str, Any], *, t0_unix: float) -> Batch:
    """The batch of one Sensor Logger push message (times to mission time)."""
    payload = message.get("payload")
    seq = message.get("messageId")
    if not isinstance(payload, list) or not isinstance(seq, int):
        raise BatchError(422, "Sensor Logger push needs 'messageId' (int) and 'payload' (list)")
    rows: dict[str, list[str]] = {}
    first_ns: int | None = None
    for i, item in enumerate(payload):
        if not isinstance(item, dict) or not isinstance(item.get("values"), dict):
            raise BatchError(422, f"payload[{i}]: needs name, time and values")
        file = _FILES.get(str(item.get("name", "")).lower())
        if file is None or file == "Metadata.csv":
            continue   # sensors the offline reader does not use either
        cols = _COLUMNS.get(file, ("x", "y", "z"))
        try:
            values = [float(item["values"][c]) for c in cols]
            t_ns = int(item["time"])
        except (KeyError, TypeError, ValueError):
            raise BatchError(422, f"payload[{i}] ({item.get('name')}): needs time (ns) and "
                                  f"values {', '.join(cols)}") from None
        rows.setdefault(file, []).append(",".join([str(t_ns), *map(repr, values)]))
        first_ns = t_ns if first_ns is None else min(first_ns, t_ns)
    if not rows:
        raise BatchError(422, "Sensor Logger push without any sensor hrtls reads "
                              f"({', '.join(sorted(_FILES))})")
    with tempfile.TemporaryDirectory() as tmp:
        for file, lines in rows.items():
            cols = _COLUMNS.get(file, ("x", "y", "z"))
            Path(tmp, file).write_text("time," + ",".join(cols) + "\n" + "\n".join(lines)
                                       + "\n")
        try:
            session = read_sensorlogger(tmp, repair=True)
        except HrtlsError as exc:
            raise BatchError(422, f"Sensor Logger push: {exc}") from None
    if session.imu is not None:
        session = session.with_parts(imu=aligned_imu(session.imu))
    # the reader's t = 0 is the message's first time; offset in integer ns (Unix seconds as
    # floats carry only ~0.2 us)
    assert first_ns is not None
    offset_s = (first_ns - round(t0_unix * 1e9)) * 1e-9
    batch = from_chunk(session, seq=seq, t_offset_s=offset_s)
    return parse_batch(batch)


def decode_sensorlogger(body: bytes, content_type: str) -> Batch:
    """Raw-log decoder of stored Sensor Logger messages."""
    params = dict(p.strip().split("=", 1) for p in content_type.split(";")[1:] if "=" in p)
    return sensorlogger_batch(json.loads(body), t0_unix=float(params["t0_unix"]))
