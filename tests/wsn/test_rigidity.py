"""Rigidity claims checked independently: PyRigi when installed, networkx otherwise.

A trilateration graph (each node after the seed triangle linked to >= 3 earlier ones) is
generically globally rigid; so is the localized part of SELA once its shadow edges are added
(Theorem 1: G_e = E + E_s contains a trilateration graph).
"""

import networkx as nx
import numpy as np
import pytest

from hrtls.wsn.network import Network, corner_seed_network
from hrtls.wsn.shadow_edge import shadow_edge_localize
from hrtls.wsn.trilateration import Localization, trilaterate_network


def _graph(net: Network, loc: Localization, with_shadow: bool) -> nx.Graph:
    keep = set(np.flatnonzero(loc.localized).tolist())
    g = nx.Graph()
    g.add_nodes_from(keep)
    g.add_edges_from((a, b) for a, b in net.edges.tolist() if a in keep and b in keep)
    if with_shadow:
        g.add_edges_from(loc.shadow_edges.tolist())
    return g


def _is_trilateration_order(g: nx.Graph, seeds: list[int], order: list[int]) -> bool:
    done = set(seeds)
    for u in order:
        if len(done & set(g.neighbors(u))) < 3:
            return False
        done.add(u)
    return done == set(g.nodes)


def _cases(count: int = 40):
    for s in range(count):
        net = corner_seed_network(np.random.default_rng(s), n_nodes=12, radius_m=0.45)
        yield net, trilaterate_network(net), shadow_edge_localize(net)


def test_localization_order_is_a_trilateration_order_networkx():
    for net, tla, sela in _cases():
        seeds = np.flatnonzero(net.anchor).tolist()
        g = _graph(net, tla, False)
        assert _is_trilateration_order(g, seeds, tla.order.tolist())
        ge = _graph(net, sela, True)
        assert _is_trilateration_order(ge, seeds, sela.order.tolist())
        # the localized part is 2-connected at least (a trilateration graph is 3-connected
        # once it has >= 4 nodes)
        if ge.number_of_nodes() >= 4:
            assert nx.node_connectivity(ge) >= 3


def test_localized_part_is_globally_rigid_pyrigi():
    pyrigi = pytest.importorskip("pyrigi")
    checked = 0
    for net, tla, sela in _cases(12):
        for loc, shadow in ((tla, False), (sela, True)):
            g = _graph(net, loc, shadow)
            if g.number_of_nodes() < 4:
                continue
            pg = pyrigi.Graph(list(g.edges))
            assert pg.is_globally_rigid(dim=2)
            checked += 1
    assert checked >= 8


def test_fig_5_1_shadow_edge_makes_the_framework_globally_rigid_pyrigi():
    pyrigi = pytest.importorskip("pyrigi")
    from tests.wsn.test_localization import _fig51

    net = _fig51(True)
    sela = shadow_edge_localize(net)
    g0 = _graph(net, sela, False)
    ge = _graph(net, sela, True)
    assert g0.number_of_edges() == 5 and ge.number_of_edges() == 6
    assert not pyrigi.Graph(list(g0.edges)).is_globally_rigid(dim=2)
    assert pyrigi.Graph(list(ge.edges)).is_globally_rigid(dim=2)
