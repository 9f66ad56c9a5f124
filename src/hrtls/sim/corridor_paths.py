"""Shortest paths inside a floor plan's free space: a grid graph and string pulling.

:func:`free_space_graph` samples the free space (a shapely polygon already shrunk by the
walker's margin) on a square grid and joins each grid point to its 8 neighbours when the segment
between them stays inside; edge weights are the segment lengths, so a shortest path on the graph
(``networkx.shortest_path(..., weight="weight")``) is the shortest grid route. :func:`pull_string`
straightens such a route: from each kept point it jumps to the farthest later point in line of
sight (greedy string pulling), which removes the grid's zig-zags without leaving the free space.
Used by the random floor-plan walks (:mod:`hrtls.sim.motion_truth`) and the robot's corridor
router (:mod:`hrtls.sim.robot_driver`).
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

FloatArray = NDArray[np.float64]


def free_space_graph(*, inner: BaseGeometry, spacing_m: float) -> tuple[FloatArray, nx.Graph]:
    """Grid points inside ``inner`` and their graph (module doc).

    Returns the ``(N, 2)`` grid points (m, on ``spacing_m`` steps from the lower-left corner of
    ``inner``'s bounds) and a graph whose node ``k`` is point ``k``; an edge joins two of the 8
    neighbours whose segment ``inner`` contains, with weight its length (m).
    """
    minx, miny, maxx, maxy = inner.bounds
    gx = np.arange(minx, maxx + 1e-9, spacing_m)
    gy = np.arange(miny, maxy + 1e-9, spacing_m)
    xx, yy = np.meshgrid(gx, gy, indexing="ij")
    inside = shapely.contains_xy(inner, xx, yy)
    index = -np.ones(xx.shape, dtype=np.int64)
    index[inside] = np.arange(int(inside.sum()))
    nodes = np.column_stack([xx[inside], yy[inside]])
    graph = nx.Graph()
    graph.add_nodes_from(range(len(nodes)))
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        i0, i1 = max(0, -di), xx.shape[0] - max(0, di)
        j0, j1 = max(0, -dj), xx.shape[1] - max(0, dj)
        a = index[i0:i1, j0:j1]
        b = index[i0 + di:i1 + di, j0 + dj:j1 + dj]
        ok = (a >= 0) & (b >= 0)
        ia, ib = a[ok], b[ok]
        if len(ia) == 0:
            continue
        segs = shapely.linestrings(np.stack([nodes[ia], nodes[ib]], axis=1))
        good = shapely.contains(inner, segs)
        w = float(np.hypot(di, dj) * spacing_m)
        graph.add_weighted_edges_from((int(u), int(v), w)
                                      for u, v in zip(ia[good], ib[good], strict=True))
    return nodes, graph


def pull_string(*, points_m: FloatArray, inner: BaseGeometry) -> list[FloatArray]:
    """The corners of the route ``points_m`` (``(k, 2)``, m) straightened inside ``inner``.

    Keeps the first and last points; from each kept point goes to the farthest later point whose
    segment ``inner`` contains (greedy, module doc).
    """
    out = [points_m[0]]
    i = 0
    while i < len(points_m) - 1:
        j = len(points_m) - 1
        while j > i + 1 and not inner.contains(LineString([points_m[i], points_m[j]])):
            j -= 1
        out.append(points_m[j])
        i = j
    return out
