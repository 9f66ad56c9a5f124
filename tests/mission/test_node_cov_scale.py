"""The smoother's node covariance calibration (``SmootherParams.node_cov_scale``,
``link_cov_scale``) and the default mode's node NEES on seeded missions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from hrtls.errors import InputError
from hrtls.mission.graph import AgentPath, SmootherParams, smooth
from hrtls.mission.graph_links import NodeLinks
from hrtls.mission.tracker import MissionTracker
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

from .test_graph import NODES, _range_set, _ranges, _walk


def _solve(links: NodeLinks | None, **kw: float):  # type: ignore[no-untyped-def]
    t = np.arange(0.0, 40.0, 1.0)
    walks = [_walk(t), _walk(t)[:, ::-1] + 0.5]
    paths = [AgentPath(f"R{a}", t, w, 0.01 * np.eye(2)) for a, w in enumerate(walks)]
    rows = [r for a, w in enumerate(walks) for r in _ranges(a, t, w, NODES)]
    prm = SmootherParams(max_evaluations=200, range_correlation_s=0.0, **kw)  # type: ignore[arg-type]
    return smooth(paths, _range_set(rows), params=prm, links=links)


@pytest.mark.parametrize("with_links", [False, True])
def test_the_scales_multiply_the_reported_covariances_and_nothing_else(with_links: bool) -> None:
    """Hand case: A and B linked (their true distance, 0.2 m), C not. With ``node_cov_scale``
    1.5 and ``link_cov_scale`` 2 the covariances of A and B are 3 times, C's 1.5 times those
    without; positions, localization and the fed-back poses are the same."""
    d_ab = float(np.linalg.norm(NODES["A"] - NODES["B"]))
    links = NodeLinks(np.array(["A"]), np.array(["B"]), np.array([d_ab]), np.array([0.2]),
                      np.array([10])) if with_links else None
    one = _solve(links)
    two = _solve(links, node_cov_scale=1.5, link_cov_scale=2.0)
    assert set(one.nodes) == set(two.nodes) == set(NODES)
    for n, (p, c, ok) in one.nodes.items():
        k = 3.0 if with_links and n in ("A", "B") else 1.5
        np.testing.assert_array_equal(two.nodes[n][0], p)
        np.testing.assert_allclose(two.nodes[n][1], k * c, rtol=1e-12)
        assert two.nodes[n][2] == ok
    for name, (t, m, p) in one.last_pose.items():
        assert two.last_pose[name][0] == t
        np.testing.assert_array_equal(two.last_pose[name][1], m)
        np.testing.assert_array_equal(two.last_pose[name][2], p)


@pytest.mark.parametrize("field", ["node_cov_scale", "link_cov_scale"])
@pytest.mark.parametrize("value", [0.9, 0.0, float("nan"), float("inf")])
def test_scales_below_one_or_not_finite_are_refused(field: str, value: float) -> None:
    with pytest.raises(InputError, match=field):
        SmootherParams(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize("value", [-0.1, float("nan"), float("inf")])
def test_a_negative_or_not_finite_link_bias_is_refused(value: float) -> None:
    with pytest.raises(InputError, match="link_bias_sigma_m"):
        SmootherParams(link_bias_sigma_m=value)


def test_the_default_modes_smoother_nodes_are_not_over_confident() -> None:
    """Seeded regression (seeds 1 and 2, 150 s walks, 20 nodes, 2 % range noise, the default
    mode ``feedback``): pooled NEES (2 dof) of the nodes the smoother localized at most 2 (its
    expectation) and above the 95 % chi-square lower bound. Without the calibration (main at
    3c12ba1): 2.50; with ``node_cov_scale`` 1.35: 1.85."""
    nees: list[float] = []
    for seed in (1, 2):
        m = inderst_hybrid_mission(seed, MissionOptions(walk_s=150.0, n_nodes=20,
                                                        range_sigma_fraction=0.02))
        mt = MissionTracker({k: s.with_parts(truth=None, checkpoints=None)
                             for k, s in m.agents.items()}, kinds=m.kinds)
        res = mt.run()
        assert mt.smoother is not None
        for n in sorted(mt.smoother.owned):
            e = res.nodes[n]
            if e.localized:
                d = e.position_m - m.node_truth_m[n]
                nees.append(float(d @ np.linalg.solve(e.covariance_m2, d)))
    assert len(nees) >= 20
    assert chi2.ppf(0.025, 2 * len(nees)) / len(nees) < float(np.mean(nees)) <= 2.0
