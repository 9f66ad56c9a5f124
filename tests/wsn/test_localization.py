"""TLA and SELA: hand cases, the compiled kernel against the reference, properties."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.wsn._propagation_reference import propagate_reference
from hrtls.wsn.network import Network, corner_seed_network, network_from_positions
from hrtls.wsn.shadow_edge import circle_candidates, shadow_edge_localize
from hrtls.wsn.trilateration import PropagationParams, trilaterate, trilaterate_network


def test_trilaterate_hand_case():
    pts = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]])
    x = np.array([1.0, 1.0])
    d = np.linalg.norm(pts - x, axis=1)
    est, worst = trilaterate(pts, d)
    assert np.allclose(est, x, atol=1e-12)
    assert worst < 1e-12
    with pytest.raises(InputError, match="collinear"):
        trilaterate(np.array([[0.0, 0], [1, 0], [2, 0]]), np.ones(3))
    with pytest.raises(InputError):
        trilaterate(pts[:2], d[:2])


def test_circle_candidates_hand_case():
    c = circle_candidates(np.array([0.0, 0]), 5.0, np.array([8.0, 0]), 5.0)
    assert np.allclose(sorted(c[:, 1]), [-3.0, 3.0])
    assert np.allclose(c[:, 0], 4.0)
    with pytest.raises(InputError, match="do not intersect"):
        circle_candidates(np.array([0.0, 0]), 1.0, np.array([5.0, 0]), 1.0)


def _fig51(with_witness: bool) -> Network:
    """Fig. 5.1: seeds h, k, j; node i hears h and k only; j would hear i's mirror."""
    p = np.array([
        [0.0, 0.0],    # h (anchor)
        [1.0, 0.0],    # k (anchor)
        [0.5, 0.8],    # j (anchor), linked to h and k
        [0.5, -0.6],   # i: true position below the line h-k
    ])
    anchor = np.array([True, True, True, False])
    if not with_witness:
        p[2] = [0.5, 3.0]  # j far away: unlinked, cannot rule out anything
    return network_from_positions(p, radius_m=1.0, anchor=anchor)


def test_shadow_edge_places_node_of_fig_5_1():
    net = _fig51(True)
    assert (2, 3) not in {tuple(e) for e in net.edges.tolist()}
    tla = trilaterate_network(net)
    assert not tla.localized[3]
    assert tla.status_names[3] == "too-few-neighbours"
    sela = shadow_edge_localize(net)
    assert sela.localized[3]
    assert sela.method_names[3] == "shadow-edge"
    assert np.allclose(sela.estimate_m[3], [0.5, -0.6], atol=1e-12)
    assert sela.shadow_edges.tolist() == [[3, 2]]


def test_ambiguous_node_is_left_unlocalized():
    net = _fig51(False)
    sela = shadow_edge_localize(net)
    assert not sela.localized[3]
    assert sela.status_names[3] == "ambiguous"


def test_inconsistent_candidates_are_flagged():
    # both candidates of node 3 lie within rho of a non-linked localized node -> impossible
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.8], [0.5, -0.6], [0.3, -0.9]])
    net0 = network_from_positions(p, radius_m=1.0, anchor=np.array([1, 1, 1, 0, 1], bool))
    keep = [k for k, (a, b) in enumerate(net0.edges.tolist()) if (a, b) != (3, 4)]
    net = Network(ids=net0.ids, radius_m=1.0, anchor=net0.anchor, position_m=p,
                  has_position=net0.has_position, edges=net0.edges[keep],
                  distance_m=net0.distance_m[keep])
    sela = shadow_edge_localize(net)
    assert not sela.localized[3]
    assert sela.inconsistent().tolist() == [3]


def test_trilateration_residual_check_flags_bad_ranges():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.4, 0.4]])
    net = network_from_positions(p, radius_m=2.0, anchor=np.array([1, 1, 1, 0], bool))
    d = net.distance_m.copy()
    d[np.flatnonzero((net.edges == [0, 3]).all(axis=1))] *= 1.3
    bad = Network(ids=net.ids, radius_m=2.0, anchor=net.anchor, position_m=p,
                  has_position=net.has_position, edges=net.edges, distance_m=d)
    loc = trilaterate_network(bad)
    assert not loc.localized[3]
    assert loc.status_names[3] == "inconsistent"
    ok = trilaterate_network(bad, params=PropagationParams(range_tolerance_fraction=0.5))
    assert ok.localized[3]


def test_json_anchor_only_seed_network_does_nothing_without_links():
    p = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    net = network_from_positions(p, radius_m=1.0, anchor=np.array([1, 1, 0], bool))
    loc = shadow_edge_localize(net)
    assert loc.localized.tolist() == [True, True, False]
    assert loc.order.size == 0


def _check(net: Network, tla, sela) -> None:
    rho = net.radius_m
    # Corollary 2: SELA localizes a superset of TLA from the same seeds
    assert not np.any(tla.localized & ~sela.localized)
    for r in (tla, sela):
        m = r.localized
        err = np.linalg.norm(r.estimate_m[m] - net.position_m[m], axis=1)
        # exact ranges -> exact positions; in particular no wrong candidate anywhere
        assert err.max(initial=0.0) <= 1e-9 * rho
        assert np.all(np.isfinite(r.estimate_m))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(8, 90), rho=st.floats(0.12, 0.45))
def test_properties_on_random_networks(seed, n, rho):
    net = corner_seed_network(np.random.default_rng(seed), n_nodes=n, radius_m=rho)
    _check(net, trilaterate_network(net), shadow_edge_localize(net))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(10, 60))
def test_properties_with_random_anchor_sets(seed, n):
    rng = np.random.default_rng(seed)
    p = rng.uniform(size=(n, 2))
    anchor = np.zeros(n, dtype=bool)
    anchor[rng.choice(n, size=min(n, 5), replace=False)] = True
    net = network_from_positions(p, radius_m=0.35, anchor=anchor)
    _check(net, trilaterate_network(net), shadow_edge_localize(net))


def test_kernel_matches_reference():
    prm = PropagationParams()
    for s in range(25):
        net = corner_seed_network(np.random.default_rng(s), n_nodes=40, radius_m=0.3)
        adj = net.adjacency
        for shadow, run in ((False, trilaterate_network), (True, shadow_edge_localize)):
            fast = run(net)
            rho = net.radius_m
            pos0 = np.where(net.anchor[:, None], net.position_m, 0.0)
            loc, pos, meth = propagate_reference(
                adj.indptr, adj.indices, adj.distance_m, pos0, net.anchor.copy(), rho, shadow,
                prm.range_tolerance_fraction * rho, prm.min_spread_fraction * rho,
                prm.shadow_margin_fraction * rho, prm.max_gdop, prm.flip_tolerance * rho)
            assert np.array_equal(loc, fast.localized), s
            assert np.allclose(pos[loc], fast.estimate_m[loc], atol=1e-9 * rho)
            if not shadow:  # with shadow edges the method depends on the visiting order
                assert np.array_equal(meth[loc & ~net.anchor], fast.method[loc & ~net.anchor])


def test_large_network_localizes_exactly():
    n = 3000
    rho = float(np.sqrt(15 / (np.pi * n)))
    net = corner_seed_network(np.random.default_rng(11), n_nodes=n, radius_m=rho)
    loc = shadow_edge_localize(net)
    assert loc.n_localized > 0.95 * n
    err = np.linalg.norm(loc.estimate_m[loc.localized] - net.position_m[loc.localized], axis=1)
    assert err.max() < 1e-9 * rho


def test_noise_params_avoid_flips_and_flag():
    pp = PropagationParams.for_noise(0.02)
    assert pp.max_gdop == 2.5
    assert PropagationParams.for_noise(0.0) == PropagationParams()
    with pytest.raises(InputError):
        PropagationParams(range_tolerance_fraction=-1.0)
    with pytest.raises(InputError):
        PropagationParams(max_gdop=0.0)


def test_thousands_of_study_networks():
    """Corollary 2, exactness and no wrong candidate on 2000 Fig. 6.11 networks."""
    for s in range(2000):
        net = corner_seed_network(np.random.default_rng(s), n_nodes=50, radius_m=0.2)
        _check(net, trilaterate_network(net), shadow_edge_localize(net))
