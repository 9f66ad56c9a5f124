"""Node readings bookkeeping of :class:`hrtls.mission.tracker.MissionTracker`.

A reading is a range from an agent to a node the agent does not use, stored with the agent's
estimate (position and covariance) at the reading's time. The agent's estimate rows come out of
its causal tracker with a lag (a step row is written once the step is detected), so a range near
the end of a window can be later than the agent's latest row: such a range is held as *pending*
for that agent until a later window's rows cover its time, or until the mission's end
(``MissionTracker.advance(final=True)``), where the agent's latest row gives the estimate of the
ranges later than it. No range is dropped for lack of a row.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.data.observations import RangeMeasurements
from hrtls.mission.nodes import NodeRanges

FloatArray = NDArray[np.float64]
Rows = tuple[FloatArray, FloatArray, FloatArray]
"""An agent's estimate rows: time (s), xy (m), xy covariance (m^2)."""


@dataclass
class NodeReadings:
    """Readings of one node: agent index, time, agent xy and covariance, range, sigma, floor.

    ``floor``: the agent's floor at each reading (:mod:`hrtls.mission.floors`).
    """

    agent: list[int] = field(default_factory=list)
    t: list[float] = field(default_factory=list)
    xy: list[FloatArray] = field(default_factory=list)
    cov: list[FloatArray] = field(default_factory=list)
    r: list[float] = field(default_factory=list)
    s: list[float] = field(default_factory=list)
    floor: list[int] = field(default_factory=list)

    def add(self, *, agent: int, t_s: FloatArray, rows: Rows, range_m: FloatArray,
            sigma_m: FloatArray, floor: NDArray[np.int64] | None = None) -> float:
        """Append readings at times ``t_s`` with the agent's ``rows`` there.

        Position linearly interpolated between rows (held at the ends); covariance of the first
        row at or after the time (the last row beyond it); ``floor``: the agent's floor at each
        (0 when None). Returns the smallest covariance trace among them, m^2.
        """
        t, xy, cov = rows
        ax = np.interp(t_s, t, xy[:, 0])
        ay = np.interp(t_s, t, xy[:, 1])
        j = np.clip(np.searchsorted(t, t_s), 0, len(t) - 1)
        self.agent.extend([agent] * len(t_s))
        self.t.extend(t_s.tolist())
        self.xy.extend(np.column_stack([ax, ay]))
        self.cov.extend(cov[j])
        self.r.extend(range_m.tolist())
        self.s.extend(sigma_m.tolist())
        self.floor.extend([0] * len(t_s) if floor is None else np.asarray(floor).tolist())
        return float(np.min(np.trace(cov[j], axis1=1, axis2=2)))

    def ranges(self, pass_gap_s: float, *, floor: int | None = None) -> NodeRanges:
        """The readings for :class:`~hrtls.mission.nodes.NodeEstimator`, grouped in passes.

        ``floor``: only the readings taken on that floor (None: all).
        """
        m = (np.ones(len(self.t), dtype=bool) if floor is None
             else np.asarray(self.floor, dtype=np.int64) == floor)
        chain = np.asarray(self.agent, dtype=np.int64)[m]
        t_s = np.asarray(self.t, dtype=np.float64)[m]
        order = np.lexsort((t_s, chain))    # passes: runs of one agent in time order
        a, t = chain[order], t_s[order]
        new_pass = np.ones(len(t), dtype=bool)
        new_pass[1:] = (a[1:] != a[:-1]) | (np.diff(t) > pass_gap_s)
        group = np.empty(len(t), dtype=np.int64)
        group[order] = np.cumsum(new_pass) - 1
        return NodeRanges.build(
            agent_xy_m=np.asarray(self.xy).reshape(-1, 2)[m],
            agent_cov_m2=np.asarray(self.cov).reshape(-1, 2, 2)[m],
            range_m=np.asarray(self.r)[m], range_sigma_m=np.asarray(self.s)[m], group=group,
            chain=chain, t_s=t_s)


def join_ranges(a: RangeMeasurements | None, b: RangeMeasurements | None
                ) -> RangeMeasurements | None:
    """``a`` then ``b`` (either may be None)."""
    if a is None or not len(a.t):
        return b
    if b is None or not len(b.t):
        return a
    return RangeMeasurements(np.concatenate([a.t, b.t]), np.concatenate([a.node, b.node]),
                             np.concatenate([a.range_m, b.range_m]),
                             np.concatenate([a.sigma_m, b.sigma_m]))


def split_at(ranges: RangeMeasurements, t_s: float
             ) -> tuple[RangeMeasurements | None, RangeMeasurements | None]:
    """The ranges at or before ``t_s`` and those after it (None when empty)."""
    m = ranges.t <= t_s

    def part(k: NDArray[np.bool_]) -> RangeMeasurements | None:
        if not k.any():
            return None
        return RangeMeasurements(ranges.t[k], ranges.node[k], ranges.range_m[k],
                                 ranges.sigma_m[k])

    return part(m), part(~m)


def merge_rows(rows: list[Rows], new: Rows | None) -> Rows | None:
    """The agent's rows with ``new`` appended, the newest version of a repeated time kept."""
    parts = [*rows, new] if new is not None and len(new[0]) else list(rows)
    if not parts:
        return None
    if len(parts) == 1:
        return parts[0]
    t = np.concatenate([r[0] for r in parts])
    xy = np.concatenate([r[1] for r in parts])
    cov = np.concatenate([r[2] for r in parts])
    t, idx = np.unique(t[::-1], return_index=True)      # the newest version of a row
    return t, xy[::-1][idx], cov[::-1][idx]


def trim_rows(rows: Rows, t_end: float, *, keep_s: float = 0.0) -> Rows:
    """Drop the rows no later reading can need: all before the last one at or before t_end.

    ``keep_s``: rows of the last ``keep_s`` seconds before ``t_end`` are kept too (a peer's
    velocity, :mod:`hrtls.mission.peers`).
    """
    t, xy, cov = rows
    i = max(int(np.searchsorted(t, t_end - keep_s, side="right")) - 2, 0)
    return (t[i:], xy[i:], cov[i:]) if i > 0 else rows
