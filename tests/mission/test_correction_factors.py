"""Corrections as dead reckoning plus position factors (hrtls.mission.correction_factors)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.mission.correction_factors import dead_reckoning, implied_factors


def _kalman(m0: np.ndarray, p0: np.ndarray, h: np.ndarray, r: np.ndarray, z: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """A linear update of ``N(m0, p0)`` by ``z = h x + N(0, r)``."""
    s = h @ p0 @ h.T + r
    k = p0 @ h.T @ np.linalg.inv(s)
    return m0 + k @ (z - h @ m0), (np.eye(2) - k @ h) @ p0


def test_a_position_fix_gives_back_its_position_and_covariance() -> None:
    # prior N(0, 4 I), fix (3, 0) with R = I: posterior 0.8 I at (2.4, 0) (by hand)
    m1, p1 = _kalman(np.zeros(2), 4.0 * np.eye(2), np.eye(2), np.eye(2), np.array([3.0, 0.0]))
    np.testing.assert_allclose(m1, [2.4, 0.0])
    np.testing.assert_allclose(p1, 0.8 * np.eye(2))
    z, w = implied_factors(np.zeros((1, 2)), 4.0 * np.eye(2)[None], m1[None], p1[None])
    np.testing.assert_allclose(z[0], [3.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(w[0].T @ w[0], np.eye(2), atol=1e-12)


def test_a_range_gives_rank_one_information_along_the_line_of_sight() -> None:
    # node at (10, 10) from the prior mean (0, 0): u = (-1, -1)/sqrt 2, range 12 m, sigma 0.5 m
    m0, p0, node, s = np.zeros(2), np.diag([4.0, 1.0]), np.array([10.0, 10.0]), 0.5
    d = float(np.hypot(*node))
    u = (m0 - node) / d
    # EKF: r = d + u^T (x - m0); innovation 12 - d
    m1, p1 = _kalman(m0, p0, u[None, :], np.array([[s * s]]), np.array([12.0 - d + u @ m0]))
    z, w = implied_factors(m0[None], p0[None], m1[None], p1[None])
    lam = w[0].T @ w[0]
    np.testing.assert_allclose(lam, np.outer(u, u) / s ** 2, atol=1e-9)
    assert np.linalg.matrix_rank(lam, tol=1e-6) == 1
    # the factor's position is 12 m from the node along the line of sight
    np.testing.assert_allclose(u @ (z[0] - node), 12.0, atol=1e-9)


def test_an_update_that_widens_the_covariance_gives_no_information() -> None:
    z, w = implied_factors(np.zeros((1, 2)), np.eye(2)[None], np.ones((1, 2)),
                           2.0 * np.eye(2)[None])
    np.testing.assert_array_equal(w[0], np.zeros((2, 2)))
    np.testing.assert_array_equal(z[0], np.zeros(2))


finite = st.floats(-50.0, 50.0)


@st.composite
def _spd(draw: st.DrawFn, lo: float, hi: float) -> np.ndarray:
    a = draw(st.floats(0.0, np.pi))
    e = np.array([draw(st.floats(lo, hi)), draw(st.floats(lo, hi))])
    v = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return v @ np.diag(e) @ v.T


@settings(max_examples=60, deadline=None)
@given(_spd(0.05, 30.0), _spd(0.05, 30.0), finite, finite, finite, finite)
def test_random_position_updates_give_back_their_measurement(
        p0: np.ndarray, r: np.ndarray, mx: float, my: float, zx: float, zy: float) -> None:
    m0, zt = np.array([mx, my]), np.array([zx, zy])
    m1, p1 = _kalman(m0, p0, np.eye(2), r, zt)
    z, w = implied_factors(m0[None], p0[None], m1[None], 0.5 * (p1 + p1.T)[None])
    lam = w[0].T @ w[0]
    np.testing.assert_allclose(lam, np.linalg.inv(r), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(z[0], zt, rtol=1e-6, atol=1e-6)


def test_the_rows_without_the_jumps_are_the_dead_reckoning() -> None:
    t = np.arange(0.0, 10.0)
    walk = np.column_stack([0.8 * t, 0.1 * t ** 2])          # the dead reckoning
    tc = np.array([2.0, 2.0, 5.5, 9.0])                        # two at one row, one between rows
    jumps = np.array([[1.0, 0.0], [0.0, -2.0], [0.5, 0.5], [-3.0, 1.0]])
    rows = walk.copy()
    for tk, j in zip(tc, jumps, strict=True):
        rows[t >= tk] += j                                     # the row at tk holds the correction
    g = dead_reckoning(t, rows, tc, jumps)
    np.testing.assert_allclose(np.diff(g, axis=0), np.diff(walk, axis=0), atol=1e-12)
    np.testing.assert_allclose(g, walk, atol=1e-12)
    np.testing.assert_array_equal(dead_reckoning(t, rows, np.zeros(0), np.zeros((0, 2))), rows)
