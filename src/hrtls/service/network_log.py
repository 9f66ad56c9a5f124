"""The log of ranges between the dropped nodes (``network_range_batches``), packed and read back.

A batch is stored as accepted (its columns in msgpack); :func:`unpack` gives it back as the
mission estimator's :class:`~hrtls.mission.network_ranges.NetworkRanges`.
"""

from __future__ import annotations

from typing import Any

import msgpack
import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session as DbSession

from hrtls.mission.network_ranges import NetworkRanges
from hrtls.service.models import NetworkRangeBatch


def pack(ranges: NetworkRanges) -> bytes:
    """The stored body of a batch."""
    body: bytes = msgpack.packb({"t_s": ranges.t_s.tolist(), "node_a": ranges.node_a.tolist(),
                                 "node_b": ranges.node_b.tolist(),
                                 "range_m": ranges.range_m.tolist()})
    return body


def unpack(body: bytes) -> NetworkRanges:
    """A stored body as ranges."""
    d: dict[str, Any] = msgpack.unpackb(body)
    return NetworkRanges(t_s=np.asarray(d["t_s"], float), node_a=np.asarray(d["node_a"], str),
                         node_b=np.asarray(d["node_b"], str),
                         range_m=np.asarray(d["range_m"], float))


def batches_after(db: DbSession, mission_id: int, after_id: int, *, limit: int
                  ) -> list[tuple[int, NetworkRanges]]:
    """``(id, ranges)`` of the mission's batches stored after ``after_id``, in log order."""
    rows = db.execute(select(NetworkRangeBatch.id, NetworkRangeBatch.body)
                      .where(NetworkRangeBatch.mission_id == mission_id,
                             NetworkRangeBatch.id > after_id)
                      .order_by(NetworkRangeBatch.id).limit(limit)).all()
    return [(int(r.id), unpack(r.body)) for r in rows]


def newest_id(db: DbSession, mission_id: int) -> int:
    """Id of the mission's newest stored batch (0: none)."""
    newest = db.scalars(select(NetworkRangeBatch.id)
                        .where(NetworkRangeBatch.mission_id == mission_id)
                        .order_by(NetworkRangeBatch.id.desc()).limit(1)).first()
    return 0 if newest is None else int(newest)


def all_ranges(db: DbSession, mission_id: int) -> NetworkRanges:
    """Every stored range of the mission, by time (empty without any)."""
    parts = [r for _, r in batches_after(db, mission_id, 0, limit=2**31 - 1)]
    return NetworkRanges.concat(parts) if parts else NetworkRanges.empty()
