"""Per-agent sequence numbers: which batches are stored, what is missing, what to ack."""

from __future__ import annotations

from dataclasses import dataclass, field

ASSIGNED_SEQ_BASE = 2**30
"""Client seqs are below this; the service numbers batches of apps without seqs from here
(OsmAnd, OwnTracks), so both can feed one agent. Seqs stay below 2**31 (a 32-bit column)."""


@dataclass
class SeqBook:
    """Accepted sequence numbers: every ``seq <= through`` plus the set ``above``."""

    through: int = -1
    above: set[int] = field(default_factory=set)

    def __contains__(self, seq: int) -> bool:
        return seq <= self.through or seq in self.above

    def add(self, seq: int) -> bool:
        """Record ``seq``; False when it was there already."""
        if seq in self:
            return False
        self.above.add(seq)
        while self.through + 1 in self.above:
            self.through += 1
            self.above.discard(self.through)
        return True

    @property
    def highest(self) -> int:
        """The highest accepted seq (-1 before any)."""
        return max(self.above) if self.above else self.through

    def missing(self, limit: int = 20) -> list[list[int]]:
        """Gaps ``[first, last]`` below the highest accepted seq (at most ``limit``)."""
        gaps: list[list[int]] = []
        prev = self.through
        for s in sorted(self.above):
            if s > prev + 1:
                gaps.append([prev + 1, s - 1])
                if len(gaps) >= limit:
                    break
            prev = s
        return gaps

    @property
    def gap_open(self) -> bool:
        """Whether any seq below the highest is missing."""
        return bool(self.above)
