"""Ranges measured between two dropped nodes (the same radio as the agents' node ranges).

A dropped node ranges its neighbours within the radio's reach; the readings reach the mission
with their time on the agents' session clock (``network_ranges.csv`` of a mission folder,
:meth:`hrtls.mission.tracker.MissionTracker.feed_network` live). Time windows follow the
mission tracker's windows of the agents' parts: a window ``[t0, t1)`` holds ``t0 <= t < t1``
(:meth:`NetworkRanges.between`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.data.validation import as_float_vector, as_str_vector, check_finite
from hrtls.errors import InputError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class NetworkRanges:
    """Ranges ``range_m`` between nodes ``node_a`` and ``node_b`` at mission time ``t_s``.

    All four arrays have one entry per range; times finite, ranges finite and positive (m),
    the two nodes of a range different ids.
    """

    t_s: FloatArray
    node_a: NDArray[np.str_]
    node_b: NDArray[np.str_]
    range_m: FloatArray

    def __post_init__(self) -> None:
        where = "NetworkRanges"
        t = as_float_vector(self.t_s, where=f"{where} t_s")
        n = len(t)
        a = as_str_vector(self.node_a, where=f"{where} node_a", length=n)
        b = as_str_vector(self.node_b, where=f"{where} node_b", length=n)
        r = as_float_vector(self.range_m, where=f"{where} range_m", length=n)
        check_finite(t, where=f"{where} t_s")
        check_finite(r, where=f"{where} range_m")
        if np.any(r <= 0):
            i = int(np.flatnonzero(r <= 0)[0])
            raise InputError(f"range {r[i]}", where=f"{where} range_m index {i}",
                             expected="a distance > 0 m")
        if np.any(a == b):
            i = int(np.flatnonzero(a == b)[0])
            raise InputError(f"node_a = node_b = {a[i]!r}", where=f"{where} node_b index {i}",
                             expected="two different nodes")
        for name, v in (("t_s", t), ("node_a", a), ("node_b", b), ("range_m", r)):
            object.__setattr__(self, name, v)

    def __len__(self) -> int:
        return len(self.t_s)

    @classmethod
    def empty(cls) -> NetworkRanges:
        """No ranges."""
        return cls(np.zeros(0), np.zeros(0, np.str_), np.zeros(0, np.str_), np.zeros(0))

    @classmethod
    def concat(cls, parts: Sequence[NetworkRanges]) -> NetworkRanges:
        """The ranges of ``parts`` in time order (equal times keep the parts' order)."""
        if not parts:
            return cls.empty()
        t = np.concatenate([p.t_s for p in parts])
        o = np.argsort(t, kind="stable")
        return cls(t[o], np.concatenate([p.node_a for p in parts])[o],
                   np.concatenate([p.node_b for p in parts])[o],
                   np.concatenate([p.range_m for p in parts])[o])

    def select(self, mask: NDArray[np.bool_]) -> NetworkRanges:
        """The ranges where ``mask`` is True."""
        return NetworkRanges(self.t_s[mask], self.node_a[mask], self.node_b[mask],
                             self.range_m[mask])

    def between(self, t0_s: float, t1_s: float) -> NetworkRanges:
        """The ranges with ``t0_s <= t < t1_s`` (a mission window, module doc)."""
        return self.select((self.t_s >= t0_s) & (self.t_s < t1_s))

    def nodes(self) -> list[str]:
        """The node ids ranged, sorted."""
        return sorted(set(self.node_a.tolist()) | set(self.node_b.tolist()))
