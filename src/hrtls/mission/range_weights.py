"""Correlated ranges in the range-SLAM smoother (:mod:`hrtls.mission.graph`).

Ranges from one agent to one node a short time apart share most of their error (the same walls
on the path, the same multipath): taken as independent they would count many times the same
information. With a correlation window ``w`` each range's sigma is multiplied by
``sqrt(n)``, ``n`` the ranges of the same agent to the same node within ``w / 2`` of it (itself
included): ``n`` ranges inside one window weigh about as one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def neighbours(agent: IntArray, node: IntArray, t_s: FloatArray, window_s: float) -> IntArray:
    """Ranges of the same agent and node within ``window_s / 2`` of each, itself included."""
    if window_s <= 0 or not len(t_s):
        return np.ones(len(t_s), np.int64)
    key = agent.astype(np.int64) * (int(node.max()) + 1) + node.astype(np.int64)
    order = np.lexsort((t_s, key))
    k, t = key[order], t_s[order]
    span = float(t.max() - t.min()) + window_s + 1.0
    v = k.astype(np.float64) * span + (t - t.min())
    lo = np.searchsorted(v, v - 0.5 * window_s, side="left")
    hi = np.searchsorted(v, v + 0.5 * window_s, side="right")
    out = np.empty(len(t), np.int64)
    out[order] = hi - lo
    return out


def correlated_sigma(agent: IntArray, node: IntArray, t_s: FloatArray, sigma_m: FloatArray,
                     *, window_s: float) -> FloatArray:
    """Each range's sigma times ``sqrt(n)`` (module doc), m."""
    return np.asarray(sigma_m * np.sqrt(neighbours(agent, node, t_s, window_s)), np.float64)
