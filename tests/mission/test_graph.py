"""Range-SLAM smoother (hrtls.mission.graph): hand-made cases, invariants, the mission loop."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.mission.graph import AgentPath, RangeSet, SmootherParams, smooth
from hrtls.mission.graph_covariance import node_inflation
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

from ._live import restored_half_way, short_mission

H_M = 0.5
NODES = {"A": np.array([5.0, 4.0]), "B": np.array([15.0, -3.0]), "C": np.array([22.0, 9.0])}


def _walk(t: np.ndarray) -> np.ndarray:
    """An L-shaped walk at 1 m/s: 20 m east, then north."""
    return np.column_stack([np.minimum(t, 20.0), np.maximum(t - 20.0, 0.0)])


def _ranges(agent: int, t: np.ndarray, xy: np.ndarray, nodes: dict[str, np.ndarray]
            ) -> list[tuple[int, float, str, float]]:
    out = []
    for n, p in nodes.items():
        d = np.sqrt(np.sum((xy - p) ** 2, axis=1) + H_M ** 2)
        out += [(agent, float(tk), n, float(dk)) for tk, dk in zip(t, d, strict=True)]
    return out


def _range_set(rows: list[tuple[int, float, str, float]]) -> RangeSet:
    return RangeSet(np.array([r[0] for r in rows], np.int64), np.array([r[1] for r in rows]),
                    np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
                    np.full(len(rows), 0.1))


def _dead_reckoned(truth: np.ndarray, *, scale: float = 1.0, drift_rad: float = 0.0
                   ) -> np.ndarray:
    """The true increments scaled by ``scale`` and rotated by ``drift_rad`` more every 10 m
    walked (the smoother's default segment)."""
    d = np.diff(truth, axis=0)
    walked = np.concatenate([[0.0], np.cumsum(np.hypot(d[:, 0], d[:, 1]))])[:-1]
    a = drift_rad * np.floor(walked / 10.0 + 1e-9)
    rd = scale * np.column_stack([np.cos(a) * d[:, 0] - np.sin(a) * d[:, 1],
                                  np.sin(a) * d[:, 0] + np.cos(a) * d[:, 1]])
    return np.vstack([truth[:1], truth[:1] + np.cumsum(rd, axis=0)])


def _solve_one(f: np.ndarray, t: np.ndarray, truth: np.ndarray, **kw: float):  # type: ignore[no-untyped-def]
    # tight increments: the scale and rotation, not the increments, must take the error;
    # exact independent ranges
    prm = SmootherParams(max_evaluations=200, odo_sigma_m=0.05, odo_fraction=0.05,
                         range_correlation_s=0.0, **kw)  # type: ignore[arg-type]
    return smooth([AgentPath("R1", t, f, 0.01 * np.eye(2))],
                  _range_set(_ranges(0, t, truth, NODES)), params=prm)


def test_a_step_length_scale_error_is_recovered_with_the_nodes() -> None:
    t = np.arange(0.0, 40.0, 1.0)
    truth = _walk(t)
    f = _dead_reckoned(truth, scale=1.1)           # the walker's steps read 10 % long
    sol = _solve_one(f, t, truth, scale_walk_sigma=0.001)
    # corrected increments (1 + s) * 1.1 d = d: s = 1 / 1.1 - 1
    assert np.allclose(sol.scale["R1"], 1 / 1.1 - 1, atol=0.01)
    for n, p in NODES.items():
        pos, _, ok = sol.nodes[n]
        assert ok
        assert np.linalg.norm(pos - p) < 0.1, n
    assert sol.height_m == pytest.approx(H_M, abs=0.1)
    assert np.max(np.abs(sol.paths["R1"][1] - truth)) < 0.15


def test_a_heading_drift_is_recovered_with_the_nodes() -> None:
    t = np.arange(0.0, 40.0, 1.0)
    truth = _walk(t)
    f = _dead_reckoned(truth, drift_rad=0.05)      # 0.05 rad more every 10 m
    before = float(np.linalg.norm(f[-1] - truth[-1]))
    assert before > 2.0
    sol = _solve_one(f, t, truth)
    assert np.allclose(sol.heading_rad["R1"], -0.05 * np.arange(4), atol=0.01)
    for n, p in NODES.items():
        assert np.linalg.norm(sol.nodes[n][0] - p) < 0.1, n
    assert np.linalg.norm(sol.paths["R1"][1][-1] - truth[-1]) < 0.1


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000))
def test_permuting_nodes_and_agents_gives_the_same_solution_and_exact_data_exact_nodes(
        seed: int) -> None:
    rng = np.random.default_rng(seed)
    nodes = {f"N{k}": rng.uniform([0, -8], [25, 25]) for k in range(4)}
    t = np.arange(0.0, 40.0, 1.0)
    walks = [_walk(t), _walk(t)[:, ::-1] + rng.uniform(-1, 1, 2)]
    paths = [AgentPath(f"R{a}", t + a, w, 0.01 * np.eye(2)) for a, w in enumerate(walks)]
    rows = [r for a, w in enumerate(walks) for r in _ranges(a, t + a, w, nodes)]
    prm = SmootherParams(max_evaluations=200, range_correlation_s=0.0)
    one = smooth(paths, _range_set(rows), params=prm)
    order = rng.permutation(len(rows))
    renamed = [(1 - a, tk, n, d) for a, tk, n, d in (rows[i] for i in order)]
    two = smooth(paths[::-1], _range_set(renamed), params=prm)
    for n, p in nodes.items():
        if not one.nodes.get(n, (None, None, False))[2]:
            continue
        assert np.allclose(one.nodes[n][0], two.nodes[n][0], atol=1e-6)
        assert np.allclose(one.nodes[n][1], two.nodes[n][1], rtol=1e-5, atol=1e-9)
        assert np.linalg.norm(one.nodes[n][0] - p) < 0.01     # exact up to convergence
    assert sum(v[2] for v in one.nodes.values()) >= 2


def test_params_are_checked() -> None:
    with pytest.raises(InputError):
        SmootherParams(segment_m=0.0)
    with pytest.raises(InputError):
        SmootherParams(loss="l3")
    with pytest.raises(InputError):
        SmootherParams(min_ranges=2)
    with pytest.raises(InputError):
        SmootherParams(increment_noise="gyro")
    with pytest.raises(InputError):
        SmootherParams(heading_updates="twice")
    with pytest.raises(InputError):
        SmootherParams(localize_spread_m=0.0)


PARAMS = MissionParams(smoother=SmootherParams(every_s=20.0))


def test_the_loop_with_the_smoother_restores_and_runs_live_like_offline() -> None:
    sessions, kinds = short_mission(2)
    want = MissionTracker(sessions, kinds=kinds, params=PARAMS).run()
    assert any(e.localized for e in want.nodes.values())

    def solved_before_the_cut(mt: MissionTracker) -> None:
        assert mt.smoother is not None and mt.smoother.warm is not None

    mt = restored_half_way(sessions, kinds, PARAMS, at_cut=solved_before_the_cut)
    got = mt.run()
    for n, e in want.nodes.items():
        assert got.nodes[n].localized == e.localized
        if e.localized:
            np.testing.assert_array_equal(got.nodes[n].position_m, e.position_m)
            np.testing.assert_array_equal(got.nodes[n].covariance_m2, e.covariance_m2)
    assert set(got.node_history) == set(want.node_history)


def test_on_a_dev_mission_the_smoother_beats_the_per_node_estimator() -> None:
    """Seeded regression (dev seed 4, cooperation off): node RMSE on the nodes both localize."""
    m = inderst_hybrid_mission(4, MissionOptions())
    from hrtls.pipeline.config import TrackerConfig
    from hrtls.sim.mission import RESCUER_PREDICTION

    cfg = TrackerConfig.model_validate({"prediction": RESCUER_PREDICTION})
    mt = MissionTracker(m.agents, kinds=m.kinds, config=cfg, params=MissionParams(
        cooperate=False, smoother=SmootherParams(every_s=1e9)))   # one solve, at the end
    res = mt.run()
    assert mt.smoother is not None and mt.smoother.warm is not None
    warm = mt.smoother.warm
    # the per-node estimates: each node's history before the smoother's entry at the end
    owned = mt.smoother.owned
    per_node = {n: h.position_m[-2 if n in owned else -1] for n, h in res.node_history.items()
                if len(h.t) > (n in owned)}
    both = [n for n, (_, _, ok) in warm.nodes.items() if ok and n in per_node]
    assert len(both) >= 5
    e0 = np.sqrt(np.mean([np.sum((per_node[n] - m.node_truth_m[n]) ** 2) for n in both]))
    e1 = np.sqrt(np.mean([np.sum((warm.nodes[n][0] - m.node_truth_m[n]) ** 2) for n in both]))
    assert e1 < e0


def test_on_a_dev_mission_the_smoother_on_dead_reckoning_and_tags_localizes_nodes_well() -> None:
    """Seeded regression (dev seed 6, 2 % range noise, cooperation off, the benchmark's
    rescuers): the smoother's localized nodes within 1.0 m RMS of the truth. The chain on the
    filtered rows (the jumps at the door tags taken as walked motion, no tag factors) left
    them 3.09 m off (measured at 3bb8166; 0.48 m with the tighter chain and the soft-L1 loss,
    0.50 m now)."""
    from hrtls.pipeline import preset

    m = inderst_hybrid_mission(6, MissionOptions(range_sigma_fraction=0.02))
    mt = MissionTracker(m.agents, kinds=m.kinds, config=preset("rescue-mission"),
                        params=MissionParams(cooperate=False, smoother=SmootherParams()))
    mt.run()
    assert mt.smoother is not None and mt.smoother.warm is not None
    ok = [n for n, (_, _, good) in mt.smoother.warm.nodes.items() if good]
    assert len(ok) >= 10
    d = np.array([mt.smoother.warm.nodes[n][0] - m.node_truth_m[n] for n in ok])
    assert float(np.sqrt(np.mean(np.sum(d * d, axis=1)))) < 1.0


def test_node_inflation_by_hand() -> None:
    # node 0: residuals 1, 3 (mean square 5); node 1: 0.5, 1 and an outlier 10 left out
    e = np.array([1.0, 3.0, 0.5, 1.0, 10.0])
    inlier = np.array([True, True, True, True, False])
    node = np.array([0, 0, 1, 1, 1])
    got = node_inflation(e, inlier, node, 3)
    # all inliers: (1 + 9 + 0.25 + 1) / 4 = 2.8125; node 2 has no range: the global value
    np.testing.assert_allclose(got, [5.0, 2.8125, 2.8125])
    np.testing.assert_allclose(node_inflation(0.1 * e, inlier, node, 2), [1.0, 1.0])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_node_inflation_is_at_least_one_and_the_global_value(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    e = rng.standard_t(2, n) * rng.uniform(0.1, 3.0)
    inlier = np.abs(e) < 6.0
    node = rng.integers(0, 5, n)
    got = node_inflation(e, inlier, node, 5)
    total = float(np.mean(e[inlier] ** 2)) if inlier.any() else 1.0
    assert np.all(got >= 1.0)
    assert np.all(got >= total - 1e-12)
    for k in range(5):
        m = inlier & (node == k)
        if m.any():
            assert got[k] >= float(np.mean(e[m] ** 2)) - 1e-12


def test_on_a_dev_mission_the_smoother_nodes_are_consistent() -> None:
    """Seeded regression (dev seed 1, 2 % range noise, cooperation off, the benchmark's
    rescuers): mean NEES of the smoother's localized nodes below 5 and their RMSE below 0.7 m.
    With the increments at 0.05 m + 5 %, the soft-L1 loss and one inflation for all nodes:
    NEES 8.2, RMSE 0.80 m (3.4 and 0.58 m now)."""
    from hrtls.pipeline import preset

    m = inderst_hybrid_mission(1, MissionOptions(range_sigma_fraction=0.02))
    mt = MissionTracker(m.agents, kinds=m.kinds, config=preset("rescue-mission"),
                        params=MissionParams(cooperate=False, smoother=SmootherParams()))
    mt.run()
    assert mt.smoother is not None and mt.smoother.warm is not None
    nodes = mt.smoother.warm.nodes
    ok = [n for n, (_, _, good) in nodes.items() if good]
    assert len(ok) >= 10
    d = np.array([nodes[n][0] - m.node_truth_m[n] for n in ok])
    nees = [float(di @ np.linalg.solve(nodes[n][1], di)) for di, n in zip(d, ok, strict=True)]
    assert float(np.mean(nees)) < 5.0
    assert float(np.sqrt(np.mean(np.sum(d * d, axis=1)))) < 0.7


def test_a_node_seen_from_a_line_helps_but_is_not_localized() -> None:
    t = np.arange(0.0, 40.0, 1.0)
    truth = _walk(t)
    line = t <= 22.0                    # D is ranged on the east leg and 2 m into the north leg
    rows = _ranges(0, t, truth, NODES) + _ranges(0, t[line], truth[line],
                                                 {"D": np.array([8.0, 1.5])})
    path = AgentPath("R1", t, _dead_reckoned(truth, scale=1.05), 0.01 * np.eye(2))
    for localize, ok in ((2.0, False), (0.1, True)):
        prm = SmootherParams(max_evaluations=200, min_spread_m=0.1, localize_spread_m=localize)
        sol = smooth([path], _range_set(rows), params=prm)
        assert "D" in sol.nodes                     # in the problem either way
        assert sol.nodes["D"][2] is ok
        assert all(sol.nodes[n][2] for n in NODES)


def test_correlated_ranges_weigh_less_and_exact_data_stay_exact() -> None:
    t = np.arange(0.0, 40.0, 1.0)
    truth = _walk(t)
    path = [AgentPath("R1", t, _dead_reckoned(truth, scale=1.05), 0.01 * np.eye(2))]
    ranges = _range_set(_ranges(0, t, truth, NODES))
    one = smooth(path, ranges, params=SmootherParams(max_evaluations=200,
                                                    range_correlation_s=0.0))
    five = smooth(path, ranges, params=SmootherParams(max_evaluations=200,
                                                     range_correlation_s=5.0))
    for n, p in NODES.items():
        assert np.linalg.norm(five.nodes[n][0] - p) < 0.1, n
        # 5 ranges in a window weigh as one: the covariance grows (the poses share the rest)
        assert np.all(np.linalg.eigvalsh(five.nodes[n][1] - one.nodes[n][1]) > -1e-9), n
        assert np.trace(five.nodes[n][1]) > 1.02 * np.trace(one.nodes[n][1]), n
