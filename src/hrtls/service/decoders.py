"""Stored raw batches as session parts: what the mission estimator is fed.

A raw-log row (``source``, content type, body) is decoded as the host decodes it for its
re-runs (:data:`hrtls.service.host.DECODERS`) and turned into the chunk a tracker consumes
(:func:`hrtls.service.batches.to_chunk`) with the agent's header.
"""

from __future__ import annotations

from hrtls.data import Session
from hrtls.mission.tracker import AgentHeader
from hrtls.service.batches import to_chunk
from hrtls.service.host import DECODERS


def raw_part(source: str, content_type: str, body: bytes, header: AgentHeader) -> Session | None:
    """The session part of one stored batch (None when it carries no samples)."""
    batch = DECODERS[source](body, content_type)
    return to_chunk(batch, header.meta, header.landmarks)
