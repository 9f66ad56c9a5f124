"""The simulated ranges between dropped nodes (:mod:`hrtls.sim.node_links`)."""

from __future__ import annotations

import numpy as np
import shapely

from hrtls.sim.infrastructure import RangeModel
from hrtls.sim.node_links import node_network_ranges

NODES = {"a": (0.0, 0.0, 0.0), "b": (6.0, 0.0, 0.0), "c": (0.0, 6.0, 0.0),
         "up": (0.0, 1.0, 3.0)}
WALL = shapely.LineString([(3.0, -5.0), (3.0, 5.0)])     # between a and b only


def _pair_errors(seed: int) -> dict[tuple[str, str], np.ndarray]:
    model = RangeModel(sigma_m=0.05, max_range_m=10.0, nlos_bias_mean_m=1.0, walls=WALL,
                       dropout_probability=0.1)
    got = node_network_ranges(NODES, model, rate_hz=1.0, t0_s=0.0, t1_s=200.0,
                              floor_height_m=3.0, rng=np.random.default_rng(seed))
    out: dict[tuple[str, str], np.ndarray] = {}
    for a, b in sorted(set(zip(got.node_a, got.node_b, strict=True))):
        k = (got.node_a == a) & (got.node_b == b)
        d = float(np.linalg.norm(np.subtract(NODES[a], NODES[b])))
        out[(str(a), str(b))] = got.range_m[k] - d
    return out


def test_a_blocked_pair_keeps_one_bias_and_a_clear_pair_has_none() -> None:
    for seed in range(5):
        err = _pair_errors(seed)
        assert set(err) == {("a", "b"), ("a", "c"), ("b", "c")}   # "up" is on another floor
        blocked, clear = err[("a", "b")], err[("a", "c")]
        assert 150 < len(blocked) < 200                         # 10 % dropouts of 200
        # one bias for the whole pair: the spread is the Gaussian noise's, not the bias'
        assert np.std(blocked) < 0.08
        assert np.mean(blocked) > 0.0
        assert abs(np.mean(clear)) < 0.02 and np.std(clear) < 0.08


def test_the_bias_differs_between_blocked_pairs_and_seeds() -> None:
    biases = [float(np.median(_pair_errors(seed)[("a", "b")])) for seed in range(8)]
    assert np.std(biases) > 0.2                                 # exponential, mean 1 m
    assert all(b > -0.05 for b in biases)
