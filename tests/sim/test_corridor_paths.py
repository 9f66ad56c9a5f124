"""Grid routes and string pulling inside a floor plan (``sim.corridor_paths``)."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import shapely
from shapely.geometry import LineString, Point, box

from hrtls.sim.corridor_paths import free_space_graph, pull_string

# a U of 1 m wide corridors: up the left leg, across the top, down the right leg
U_SHAPE = shapely.union_all([box(0.0, 0.0, 1.0, 6.0), box(0.0, 5.0, 6.0, 6.0),
                             box(5.0, 0.0, 6.0, 6.0)]).buffer(-0.1)


def test_the_graph_joins_grid_neighbours_inside_with_their_lengths() -> None:
    nodes, graph = free_space_graph(inner=U_SHAPE, spacing_m=0.5)
    assert shapely.contains_xy(U_SHAPE, nodes[:, 0], nodes[:, 1]).all()
    assert nx.is_connected(graph)
    for u, v, w in graph.edges(data="weight"):
        assert U_SHAPE.contains(LineString([nodes[u], nodes[v]]))
        np.testing.assert_allclose(w, np.hypot(*(nodes[u] - nodes[v])), rtol=1e-12)
        assert w in (0.5, 0.5 * np.sqrt(2.0))


def test_the_pulled_route_around_the_u_keeps_its_ends_stays_inside_and_is_shorter() -> None:
    nodes, graph = free_space_graph(inner=U_SHAPE, spacing_m=0.5)
    a = int(np.argmin(np.hypot(*(nodes - [0.5, 0.5]).T)))
    b = int(np.argmin(np.hypot(*(nodes - [5.5, 0.5]).T)))
    route = nodes[nx.shortest_path(graph, a, b, weight="weight")]
    corners = np.asarray(pull_string(points_m=route, inner=U_SHAPE))
    np.testing.assert_array_equal(corners[0], route[0])
    np.testing.assert_array_equal(corners[-1], route[-1])
    assert all(U_SHAPE.contains(LineString(s)) for s in itertools.pairwise(corners))
    length = float(np.sum(np.hypot(*np.diff(corners, axis=0).T)))
    assert length < float(np.sum(np.hypot(*np.diff(route, axis=0).T)))
    assert 3 <= len(corners) <= 6                     # two bends of the U, not the grid steps
    assert length > 5.0 + 2 * 4.0                     # it cannot cut across the gap of the U
    assert not U_SHAPE.contains(Point(3.0, 2.0))


def test_a_route_in_line_of_sight_is_pulled_to_its_two_ends() -> None:
    pts = np.array([[0.5, 0.5], [0.6, 1.5], [0.4, 3.0], [0.5, 4.5]])
    out = pull_string(points_m=pts, inner=U_SHAPE)
    np.testing.assert_array_equal(np.asarray(out), pts[[0, -1]])
