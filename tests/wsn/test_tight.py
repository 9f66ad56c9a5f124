import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.wsn.agents import RangeWorld, RobotAgent, RobotParams
from hrtls.wsn.network import connected_components, network_from_positions, random_network
from hrtls.wsn.refine import refine_network
from hrtls.wsn.tight import TightParams, tight_cooperation

RHO = 0.2
DELTA = 0.01


def _run(net, side=1.0, seed=0):
    world = RangeWorld(true_positions_m=net.position_m, link_radius_m=RHO,
                       radio_range_m=2 * RHO)
    robot = RobotAgent(world, np.zeros(3), params=RobotParams(arrival_radius_m=0.002), seed=seed)
    return tight_cooperation(net, robot, params=TightParams(
        delta_m=DELTA, radio_range_m=2 * RHO, search_region_m=(0, 0, side, side)))


def test_random_networks_are_localized_within_a_few_delta():
    for s in range(4):
        net = random_network(np.random.default_rng(s), n_nodes=30, radius_m=RHO, anchors="none")
        res = _run(net, seed=s)
        if connected_components(net, radius_m=2 * RHO).max() == 0:  # Theorem 2 applies
            assert res.complete, s
        loc = res.localization
        m = loc.localized
        err = np.linalg.norm(loc.estimate_m[m] - net.position_m[m], axis=1)
        assert np.sqrt(np.mean(err**2)) < 0.1 * RHO
        assert set(res.assigned.tolist()) == set(np.flatnonzero(loc.method == 4).tolist())
        assert res.assigned.size >= 3
        # agent-assigned positions are within Delta + tracking error of the truth
        ea = np.linalg.norm(loc.estimate_m[res.assigned] - net.position_m[res.assigned], axis=1)
        assert ea.max() < 3 * DELTA
        prior = np.full(net.n_nodes, np.inf)
        prior[res.assigned] = DELTA
        ref = refine_network(net, loc, prior_sigma_m=prior)
        e2 = np.linalg.norm(ref.estimate_m[m] - net.position_m[m], axis=1)
        assert np.all(np.isfinite(e2))


def test_disconnected_components_reached_through_bridge():
    # two clusters 0.3 m apart (> rho, < d_r = 2 rho): Fig. 6.14-6.15
    rng = np.random.default_rng(5)
    a = rng.uniform(0.05, 0.3, size=(6, 2))
    b = rng.uniform(0.05, 0.3, size=(5, 2)) + np.array([0.55, 0.0])
    p = np.vstack([a, b])
    net = network_from_positions(p, radius_m=RHO)
    lab = connected_components(net)
    assert lab.max() >= 1
    res = _run(net, side=1.0)
    assert res.complete
    loc = res.localization
    err = np.linalg.norm(loc.estimate_m - net.position_m, axis=1)
    assert err.max() < 0.2 * RHO
    # every component needed its own agent-assigned nodes
    assert len({int(lab[v]) for v in res.assigned}) == lab.max() + 1


def test_params_validation():
    with pytest.raises(InputError):
        TightParams(delta_m=0.0, radio_range_m=1.0, search_region_m=(0, 0, 1, 1))
    with pytest.raises(InputError):
        TightParams(delta_m=0.1, radio_range_m=1.0, search_region_m=(0, 0, 0, 1))
