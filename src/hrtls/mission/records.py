"""Records of :class:`hrtls.mission.tracker.MissionTracker`: closures, node tracks, progress."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LoopClosure:
    """A contributor starting to use its node.

    ``t``: time of the agent's row the decision used; covariance traces (m^2) of that row and
    the smallest at the agent's readings of the node.
    """

    t: float
    agent: str
    node: str
    trace_now_m2: float
    trace_readings_m2: float


@dataclass(frozen=True, eq=False)
class NodeTrack:
    """A node's estimate over the mission."""

    t: FloatArray
    position_m: FloatArray
    covariance_m2: FloatArray


@dataclass(frozen=True)
class Progress:
    """What :meth:`MissionTracker.advance` did.

    ``windows``: windows processed; ``horizon_s``: end of the last processed window, s;
    ``changed``: the nodes re-localized in them.
    """

    windows: int
    horizon_s: float
    changed: tuple[str, ...]
