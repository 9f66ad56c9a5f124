import numpy as np
import pytest
from scipy.optimize import least_squares

from hrtls.errors import InputError
from hrtls.wsn.network import corner_seed_network, network_from_positions
from hrtls.wsn.refine import RefineParams, refine_network, refine_positions
from hrtls.wsn.shadow_edge import shadow_edge_localize
from hrtls.wsn.trilateration import PropagationParams


def _noisy(seed: int, noise: float = 0.02, n_nodes: int = 60):
    net = corner_seed_network(np.random.default_rng(seed), n_nodes=n_nodes, radius_m=0.3,
                              range_noise_fraction=noise)
    return net, shadow_edge_localize(net, params=PropagationParams.for_noise(noise))


def test_exact_ranges_stay_exact():
    net = corner_seed_network(np.random.default_rng(3), n_nodes=60, radius_m=0.3)
    loc = shadow_edge_localize(net)
    r = refine_network(net, loc, params=RefineParams(range_sigma_fraction=0.01))
    m = loc.localized
    assert np.allclose(r.estimate_m[m], net.position_m[m], atol=1e-9)
    assert r.normalized_rms < 1e-6


def test_matches_scipy_least_squares():
    for seed in range(50):
        net, loc = _noisy(seed, n_nodes=30)
        m = loc.localized & ~net.anchor
        if m.sum() >= 8:
            break
    assert m.sum() >= 8
    r = refine_network(net, loc, params=RefineParams(range_sigma_fraction=0.02,
                                                     step_tolerance_m=1e-13))
    free = np.flatnonzero(m)
    use = [k for k, (a, b) in enumerate(net.edges.tolist())
           if loc.localized[a] and loc.localized[b] and (m[a] or m[b])]
    e = net.edges[use]
    d = net.distance_m[use]

    def res(x):
        p = loc.estimate_m.copy()
        p[free] = x.reshape(-1, 2)
        return (d - np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)) / (0.02 * d)

    sol = least_squares(res, loc.estimate_m[free].ravel(), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert np.allclose(r.estimate_m[free], sol.x.reshape(-1, 2), atol=1e-6)
    assert abs(np.sum(res(r.estimate_m[free].ravel()) ** 2) - np.sum(sol.fun**2)) < 1e-6


def test_refinement_reduces_error_and_covariance_is_calibrated():
    sq0 = sq1 = 0.0
    nees = []
    for s in range(15):
        net, loc = _noisy(s)
        m = loc.localized & ~net.anchor
        if not m.any():
            continue
        r = refine_network(net, loc)
        e0 = loc.estimate_m[m] - net.position_m[m]
        e1 = r.estimate_m[m] - net.position_m[m]
        sq0 += float(np.sum(e0**2))
        sq1 += float(np.sum(e1**2))
        c = r.covariance_m2[m]
        assert np.allclose(c, np.transpose(c, (0, 2, 1)))
        assert np.all(np.linalg.eigvalsh(c) > 0)
        nees.extend(np.einsum("ni,nij,nj->n", e1, np.linalg.inv(c), e1).tolist())
    assert sq1 < sq0
    assert 0.5 < np.median(nees) < 3.0  # chi2(2) median is 1.39


def test_sparse_covariance_path_matches_dense(monkeypatch):
    import hrtls.wsn.refine as rf

    net, loc = _noisy(2)
    dense = refine_network(net, loc)
    monkeypatch.setattr(rf, "DENSE_COVARIANCE_MAX_UNKNOWNS", 4)
    sparse = refine_network(net, loc)
    assert np.allclose(dense.covariance_m2, sparse.covariance_m2, rtol=1e-6, atol=1e-15)
    m = dense.refined
    assert np.all(dense.covariance_m2[~m] == 0)


def test_gauge_needs_fixed_nodes():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    net = network_from_positions(p, radius_m=2.0)
    with pytest.raises(InputError, match="gauge"):
        refine_positions(net.edges, net.distance_m, p, np.ones(3, bool))
    r = refine_positions(net.edges, net.distance_m, p, np.ones(3, bool),
                         prior_sigma_m=np.array([0.1, 0.1, 0.1]))
    assert np.allclose(r.estimate_m, p)
    with pytest.raises(InputError):
        RefineParams(max_iterations=0)
