"""Fixed-lag smoother (hrtls.mission.graph_window): marginalization by hand, exactness on linear
problems, the loop's bounded state and its snapshots."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csc_matrix

from hrtls.errors import InputError
from hrtls.mission.graph import SmootherParams
from hrtls.mission.graph_window import (
    Layout,
    MarginalPrior,
    carried,
    factor,
    marginalized,
    prior_columns,
    prior_from,
    prior_state,
    restrict,
    schur,
)
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionTracker
from hrtls.pipeline.chunks import split_session

from ._live import restored_half_way, short_mission


def test_the_prior_of_a_two_pose_chain_by_hand() -> None:
    """``x1 ~ N(0, 1)``, ``x2 - x1 ~ N(1, 1)``: ``x2 ~ N(1, 2)``; linearized at ``(0, 3)``."""
    h = csc_matrix(np.array([[2.0, -1.0], [-1.0, 1.0]]))
    g = np.array([-2.0, 2.0])             # J^T r, r = (x1, x2 - x1 - 1) = (0, 2)
    p, b = schur(h, g, np.array([1]), np.array([0]))
    np.testing.assert_allclose(p, [[0.5]])
    np.testing.assert_allclose(b, [1.0])
    prior = factor(p, b, np.array([3.0]), (), ())
    np.testing.assert_allclose(prior.r.T @ prior.r, [[0.5]])
    # the residual R (x2 - 3) + e is zero at the marginal's mean, 1
    np.testing.assert_allclose(prior.r @ (np.array([1.0]) - prior.xbar) + prior.e, [0.0],
                               atol=1e-12)


def _layout(n_pose: int, seg: np.ndarray, n_nodes: int) -> Layout:
    n_seg = int(seg[-1]) + 1
    pc, sc = 0, 2 * n_pose
    nc = sc + 2 * n_seg
    return Layout(["R1"], [np.arange(float(n_pose))], [pc], [sc], [n_seg], [seg],
                  [np.arange(float(n_pose - 1))], [f"N{i}" for i in range(n_nodes)], nc,
                  nc + 2 * n_nodes, nc + 2 * n_nodes + 1)


def _rows(rng: np.random.Generator, cols: np.ndarray, n_col: int, n_rows: int) -> np.ndarray:
    """Random rows on ``cols`` only, with a unit row on each of them (a proper problem)."""
    a = np.zeros((n_rows + cols.size, n_col))
    a[:n_rows, cols] = rng.normal(size=(n_rows, cols.size)) * (rng.random((n_rows, cols.size))
                                                               < 0.5)
    a[n_rows + np.arange(cols.size), cols] = 1.0
    return a


def _windowed_equals_batch(seed: int, n_pose: int, c: int, n_nodes: int) -> None:
    """A linear problem: the kept rows plus the prior give the batch solution of the kept
    columns, for any linearization point."""
    rng = np.random.default_rng(seed)
    seg = np.sort(rng.integers(0, 3, n_pose - 1))
    seg -= seg[0]
    old = _layout(n_pose, seg, n_nodes)
    j = int(seg[c])
    new = _layout(n_pose - c, seg[c:] - j, n_nodes)
    old_of = carried(old, new, {"R1": c})
    hold = MarginalPrior(("R1",), tuple(new.node_ids), np.zeros((0, 1)), np.zeros(0),
                         np.zeros(1))
    k_old = old_of[prior_columns(hold, new)]
    drop = np.setdiff1d(np.arange(old.n), old_of)
    a_rem = _rows(rng, np.concatenate([drop, k_old]), old.n, 3 * drop.size)
    a_kept_new = _rows(rng, np.arange(new.n), new.n, 2 * new.n)
    a_kept = np.zeros((a_kept_new.shape[0], old.n))
    a_kept[:, old_of] = a_kept_new
    y_rem, y_kept = rng.normal(size=a_rem.shape[0]), rng.normal(size=a_kept.shape[0])
    a, y = np.vstack([a_rem, a_kept]), np.concatenate([y_rem, y_kept])
    batch = np.linalg.lstsq(a, y, rcond=None)[0]
    xbar = rng.normal(size=old.n) * 3.0
    prior = marginalized(old, csc_matrix(a.T @ a), a.T @ (a @ xbar - y), xbar, new,
                         csc_matrix(a_kept_new.T @ a_kept_new),
                         a_kept_new.T @ (a_kept_new @ xbar[old_of] - y_kept), {"R1": c},
                         ("R1",))
    cols = prior_columns(prior, new)
    a_p = np.zeros((prior.r.shape[0], new.n))
    a_p[:, cols] = prior.r
    windowed = np.linalg.lstsq(np.vstack([a_kept_new, a_p]),
                               np.concatenate([y_kept, a_p[:, cols] @ prior.xbar - prior.e]),
                               rcond=None)[0]
    np.testing.assert_allclose(windowed, batch[old_of], rtol=1e-7, atol=1e-7)


def test_a_linear_problem_windowed_equals_the_batch_solve() -> None:
    _windowed_equals_batch(0, 8, 3, 2)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(3, 12), st.integers(1, 10), st.integers(0, 3))
def test_any_linear_problem_windowed_equals_the_batch_solve(seed: int, n_pose: int, c: int,
                                                            n_nodes: int) -> None:
    _windowed_equals_batch(seed, n_pose, min(c, n_pose - 2), n_nodes)


def test_a_prior_restricted_to_fewer_variables_is_their_marginal() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(9, 9))
    prior = factor(a.T @ a, rng.normal(size=9), rng.normal(size=9), ("R1",), ("N0", "N1"))
    keep = np.ones(9, dtype=bool)
    keep[:4] = False
    got = restrict(prior, keep)
    assert got.agents == () and got.nodes == ("N0", "N1")
    cov = np.linalg.inv(a.T @ a)[4:, 4:]
    np.testing.assert_allclose(np.linalg.inv(got.r.T @ got.r), cov, rtol=1e-8)
    back = prior_from(prior_state(got))
    assert back is not None
    np.testing.assert_array_equal(back.r, got.r)
    np.testing.assert_array_equal(back.xbar, got.xbar)


def test_window_s_is_checked() -> None:
    with pytest.raises(InputError):
        SmootherParams(window_s=0.0)
    with pytest.raises(InputError):
        SmootherParams(window_s=float("nan"))


WINDOWED = MissionParams(smoother=SmootherParams(every_s=5.0, window_s=10.0,
                                                 feedback="implied"))


def _largest_state(params: MissionParams) -> tuple[int, int, int]:
    """Fed live in 1 s parts: the most rows of an agent, ranges and prior variables held."""
    sessions, kinds = short_mission(2)
    parts = sorted(((k, p) for k, s in sessions.items() for p in split_session(s, 1.0)),
                   key=lambda kp: kp[1].time_span()[1])
    mt = MissionTracker({k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()},
                        kinds=kinds, params=params)
    rows = ranges = prior = 0
    for j, (name, part) in enumerate(parts):
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
        s = mt.smoother
        assert s is not None
        rows = max(rows, *(len(r) for r in s.rows.values())) if s.rows else rows
        ranges = max(ranges, sum(len(p[1]) for p in s.ranges))
        prior = max(prior, 0 if s.prior is None else s.prior.r.shape[1])
    return rows, ranges, prior


def test_the_windowed_loop_keeps_a_bounded_problem() -> None:
    """Count, not time: rows per agent at most (window + cadence) / decimation and a few; the
    prior no larger than 4 per agent, 2 per node and the height; without the window the rows
    grow with the 60 s walks."""
    rows, ranges, prior = _largest_state(WINDOWED)
    full_rows, full_ranges, full_prior = _largest_state(
        MissionParams(smoother=SmootherParams(every_s=5.0, feedback="implied")))
    assert rows <= (10.0 + 5.0) / 1.0 + 3
    assert full_rows > 2 * rows and full_ranges > 2 * ranges
    assert 0 < prior <= 4 * 4 + 2 * 15 + 1 and full_prior == 0


def test_the_windowed_loop_restores_and_runs_live_like_offline() -> None:
    sessions, kinds = short_mission(2)
    want = MissionTracker(sessions, kinds=kinds, params=WINDOWED).run()
    assert any(e.localized for e in want.nodes.values())

    def marginalized_before_the_cut(mt: MissionTracker) -> None:
        assert mt.smoother is not None and mt.smoother.prior is not None

    got = restored_half_way(sessions, kinds, WINDOWED, at_cut=marginalized_before_the_cut).run()
    for n, e in want.nodes.items():
        assert got.nodes[n].localized == e.localized
        if e.localized:
            np.testing.assert_array_equal(got.nodes[n].position_m, e.position_m)
            np.testing.assert_array_equal(got.nodes[n].covariance_m2, e.covariance_m2)
    for name, r in want.agents.items():
        g = got.agents[name].trajectory
        np.testing.assert_array_equal(g.xyz, r.trajectory.xyz[-len(g.t):])
