"""Simulated ranges between the dropped nodes (the same radio as the agents' node ranges).

Every pair of alive nodes on the same floor within ``max_range_m`` ranges each other at
``rate_hz`` (attempts on a regular grid with a random phase per pair) over the mission's span,
drawn by :func:`hrtls.sim.infrastructure.draw_ranges` (Gaussian noise, NLOS bias through the
walls, dropouts): the radio is modelled once. Failed nodes do not range.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np

from hrtls.mission.network_ranges import NetworkRanges
from hrtls.sim.infrastructure import RangeModel, draw_ranges


def node_network_ranges(nodes: Mapping[str, Sequence[float]], model: RangeModel, *,
                        rate_hz: float, t0_s: float, t1_s: float, floor_height_m: float,
                        rng: np.random.Generator) -> NetworkRanges:
    """Ranges between the ``nodes`` (id -> x, y, z) from ``t0_s`` to ``t1_s`` (module doc)."""
    ids = sorted(nodes)
    if len(ids) < 2 or not t1_s > t0_s:
        return NetworkRanges.empty()
    pos = np.asarray([nodes[k] for k in ids], dtype=np.float64)
    ia, ib = np.triu_indices(len(ids), k=1)
    d = np.linalg.norm(pos[ia] - pos[ib], axis=1)
    same = np.abs(pos[ia, 2] - pos[ib, 2]) < floor_height_m / 2
    keep = same & (d <= model.max_range_m)
    ia, ib, d = ia[keep], ib[keep], d[keep]
    if not len(ia):
        return NetworkRanges.empty()
    grid = np.arange(t0_s, t1_s, 1.0 / rate_hz)
    phase = rng.uniform(0.0, 1.0 / rate_hz, len(ia))
    t = (grid[None, :] + phase[:, None]).reshape(-1)
    pair = np.repeat(np.arange(len(ia)), len(grid))
    inside = t < t1_s
    t, pair = t[inside], pair[inside]
    got = draw_ranges(distance_m=d[pair], from_xy_m=pos[ia[pair], :2], to_xy_m=pos[ib[pair], :2],
                      model=dataclasses.replace(model, rate_hz=rate_hz), rng=rng)
    positive = got.range_m > 0                  # a range clipped at 0 is no reading
    k = np.flatnonzero(got.keep)[positive]
    names = np.asarray(ids)
    return NetworkRanges.concat([NetworkRanges(t[k], names[ia[pair[k]]], names[ib[pair[k]]],
                                               got.range_m[positive])])
