"""Increment noise of the smoother's pose chain (hrtls.mission.increment_noise) and the exact
Jacobian of the smoother's residuals with it."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.mission.graph import AgentPath, RangeSet, SmootherParams, _Problem
from hrtls.mission.increment_noise import (
    ChainNoise,
    growth_curve,
    psd_part,
    robot_chain,
    whitening,
)


def test_growth_curve_adds_back_the_corrections_shrinkage_by_hand() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    cov = np.array([np.eye(2) * v for v in (1.0, 2.0, 1.5, 2.5)])
    # a correction at row 2's time shrinks the covariance by 1.0 (xx) and 0.5 (yy)
    c0 = np.array([np.diag([2.5, 2.0])])
    c1 = np.array([np.diag([1.5, 1.5])])
    g = growth_curve(cov, t, np.array([2.0]), c0, c1)
    np.testing.assert_allclose(g[:, 0, 0], [1.0, 2.0, 2.5, 3.5])
    np.testing.assert_allclose(g[:, 1, 1], [1.0, 2.0, 2.0, 3.0])
    np.testing.assert_allclose(g[:, 0, 1], 0.0)


def test_whitening_by_hand() -> None:
    d = np.array([[3.0, 4.0], [0.0, 0.0]])
    w = whitening(d, odo_sigma_m=0.15, odo_fraction=0.1)
    np.testing.assert_allclose(w[0], np.eye(2) / np.sqrt(0.15 ** 2 + 0.5 ** 2))
    np.testing.assert_allclose(w[1], np.eye(2) / 0.15)
    # growth diag(1, 3) then a shrinking step (negative part dropped), floor 1 m
    growth = np.array([np.zeros((2, 2)), np.diag([1.0, 3.0]), np.diag([0.0, 4.0])])
    w = whitening(d, odo_sigma_m=1.0, odo_fraction=0.1, growth_m2=growth)
    info = np.einsum("nji,njk->nik", w, w)
    np.testing.assert_allclose(info[0], np.diag([0.5, 0.25]), atol=1e-12)
    np.testing.assert_allclose(info[1], np.diag([1.0, 0.5]), atol=1e-12)


def test_psd_part_by_hand() -> None:
    np.testing.assert_allclose(psd_part(np.array([np.diag([-1.0, 2.0])]))[0],
                               np.diag([0.0, 2.0]), atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-5.0, 5.0), min_size=4, max_size=4),
       st.floats(0.01, 2.0))
def test_the_whitening_inverts_the_increment_covariance(a: list[float], floor_m: float) -> None:
    b = np.array(a).reshape(2, 2)
    step = b @ b.T - np.diag([a[0] ** 2, 0.0])          # may be indefinite
    growth = np.array([np.zeros((2, 2)), step])
    w = whitening(np.zeros((1, 2)), odo_sigma_m=floor_m, odo_fraction=0.0, growth_m2=growth)
    q = psd_part(step[None])[0] + floor_m ** 2 * np.eye(2)
    np.testing.assert_allclose(w[0].T @ w[0] @ q, np.eye(2), atol=1e-8)
    assert np.all(np.linalg.eigvalsh(psd_part(step[None])[0]) >= -1e-12)


def _problem(noise: str, chain: ChainNoise | None = None) -> tuple[_Problem, np.ndarray]:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 30.0, 0.5)
    xy = np.column_stack([np.minimum(t, 15.0), np.maximum(t - 15.0, 0.0)])
    growth = np.cumsum(rng.uniform(0.0, 0.05, (len(t), 2, 2)), axis=0)
    growth = 0.5 * (growth + np.swapaxes(growth, 1, 2)) + np.eye(2) * t[:, None, None] * 0.05
    z = xy[5:40:5] + 0.1
    wm = np.repeat(np.array([[[2.0, 0.5], [0.0, 1.0]]]), len(z), axis=0)
    path = AgentPath("R1", t, xy, 0.1 * np.eye(2), xy + 0.2, (t[5:40:5] + 0.25, z, wm),
                     growth_m2=growth, chain=chain)
    nodes = np.array([[4.0, 3.0], [12.0, -2.0]])
    ra = np.repeat(t[::3], 2)
    rn = np.tile(["A", "B"], len(t[::3]))
    rxy = np.repeat(xy[::3], 2, axis=0)
    dist = np.hypot(*(nodes[(rn == "B").astype(int)] - rxy).T)
    ranges = RangeSet(np.zeros(len(ra), np.int64), ra + 0.2, rn, dist, np.full(len(ra), 0.2))
    prm = SmootherParams(increment_noise=noise, segment_m=5.0)
    prob = _Problem([path], ranges, ["A", "B"], prm)
    x = rng.normal(0.0, 0.3, prob.n)
    for a, col in enumerate(prob.pose_col):
        x[col:col + 2 * len(prob.t[a])] += prob.f[a].reshape(-1)
    x[prob.node_col:prob.node_col + 4] += nodes.reshape(-1)
    x[prob.height_col] = 0.7
    return prob, x


def test_the_jacobian_is_exact_with_either_increment_noise() -> None:
    for noise in ("length", "tracker"):
        prob, x = _problem(noise)
        jac = prob.jacobian(x).toarray()
        h = 1e-6
        fd = np.column_stack([(prob.residuals(x + h * e) - prob.residuals(x - h * e)) / (2 * h)
                              for e in np.eye(prob.n)])
        np.testing.assert_allclose(jac, fd, atol=1e-5, rtol=1e-5)


def test_robot_chain_by_hand() -> None:
    c = robot_chain(odometry_fraction=0.03, heading_var_per_m=1e-4, start_heading_sigma_rad=0.05,
                    segment_m=10.0, floor_sigma_m=0.02, scale_sigma=0.01, variance_scale=1.0)
    assert (c.odo_sigma_m, c.odo_fraction, c.scale_sigma) == (0.02, 0.03, 0.01)
    assert c.scale_walk_sigma == 0.001 and c.heading_sigma_rad == 0.05
    assert c.heading_walk_rad == np.sqrt(1e-3)
    c4 = robot_chain(odometry_fraction=0.03, heading_var_per_m=1e-4,
                     start_heading_sigma_rad=0.05, segment_m=10.0, floor_sigma_m=0.02,
                     scale_sigma=0.01, variance_scale=4.0)
    assert c4.odo_fraction == 0.06 and c4.heading_walk_rad == 2.0 * np.sqrt(1e-3)
    assert c4.odo_sigma_m == 0.04 and c4.scale_walk_sigma == 0.002


def test_an_agent_chain_equal_to_the_params_changes_nothing_and_a_robot_chain_is_exact() -> None:
    prm = SmootherParams()
    same = ChainNoise(odo_sigma_m=prm.odo_sigma_m, odo_fraction=prm.odo_fraction,
                      scale_sigma=prm.scale_sigma, scale_walk_sigma=prm.scale_walk_sigma,
                      heading_sigma_rad=prm.heading_sigma_rad,
                      heading_walk_rad=prm.heading_walk_rad)
    p0, x = _problem("length")
    p1, _ = _problem("length", same)
    np.testing.assert_array_equal(p0.residuals(x), p1.residuals(x))
    robot = robot_chain(odometry_fraction=0.03, heading_var_per_m=1e-4,
                        start_heading_sigma_rad=0.02, segment_m=5.0)
    for noise in ("length", "tracker"):         # an agent's own chain: always "length"
        prob, _ = _problem(noise, robot)
        r = prob.residuals(x)
        assert not np.allclose(r, p0.residuals(x))
        jac = prob.jacobian(x).toarray()
        h = 1e-6
        fd = np.column_stack([(prob.residuals(x + h * e) - prob.residuals(x - h * e)) / (2 * h)
                              for e in np.eye(prob.n)])
        np.testing.assert_allclose(jac, fd, atol=1e-5, rtol=1e-5)
    np.testing.assert_array_equal(_problem("tracker", robot)[0].odo_w,
                                  _problem("length", robot)[0].odo_w)
