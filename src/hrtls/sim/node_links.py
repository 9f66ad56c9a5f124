"""Simulated ranges between the dropped nodes (the same radio as the agents' node ranges).

Every pair of alive nodes on the same floor within ``max_range_m`` ranges each other at
``rate_hz`` (attempts on a regular grid with a random phase per pair) over the mission's span,
drawn by :func:`hrtls.sim.infrastructure.draw_ranges` (Gaussian noise, dropouts): the radio is
modelled once. The NLOS bias of a pair whose line of sight crosses the walls is drawn once per
pair (exponential, ``nlos_bias_mean_m``) and kept for all its ranges: two nodes that do not move
see the same excess path every time, so repeating a range does not average its bias away.
Failed nodes do not range.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np
import shapely

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
                      model=dataclasses.replace(model, rate_hz=rate_hz, walls=None), rng=rng)
    bias = _pair_nlos_bias_m(pos[ia, :2], pos[ib, :2], model, rng)
    kept = np.flatnonzero(got.keep)
    range_m = got.range_m + bias[pair[kept]]
    positive = range_m > 0                      # a range clipped at 0 is no reading
    k = kept[positive]
    names = np.asarray(ids)
    return NetworkRanges.concat([NetworkRanges(t[k], names[ia[pair[k]]], names[ib[pair[k]]],
                                               range_m[positive])])


def _pair_nlos_bias_m(a_xy_m: np.ndarray, b_xy_m: np.ndarray, model: RangeModel,
                      rng: np.random.Generator) -> np.ndarray:
    """One exponential NLOS bias per pair whose segment crosses the walls, else 0, m."""
    if model.walls is None or model.nlos_bias_mean_m <= 0:
        return np.zeros(len(a_xy_m))
    blocked = shapely.intersects(shapely.linestrings(np.stack([a_xy_m, b_xy_m], axis=1)),
                                 model.walls)
    return blocked * rng.exponential(model.nlos_bias_mean_m, len(a_xy_m))
