"""Correlated ranges in the smoother (hrtls.mission.range_weights)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.mission.range_weights import correlated_sigma, neighbours


def test_neighbours_by_hand() -> None:
    agent = np.array([0, 0, 0, 0, 1, 0])
    node = np.array([0, 0, 0, 1, 0, 0])
    t = np.array([0.0, 1.0, 2.5, 1.0, 1.0, 10.0])
    # window 3 s: +-1.5 s around each range of the same agent and node
    np.testing.assert_array_equal(neighbours(agent, node, t, 3.0), [2, 3, 2, 1, 1, 1])
    np.testing.assert_array_equal(neighbours(agent, node, t, 0.0), [1] * 6)
    s = correlated_sigma(agent, node, t, np.full(6, 0.5), window_s=3.0)
    np.testing.assert_allclose(s, 0.5 * np.sqrt([2, 3, 2, 1, 1, 1]))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.integers(0, 3), st.integers(0, 400)),
                min_size=1, max_size=40), st.integers(0, 30))
def test_neighbours_count_a_brute_force(rows: list[tuple[int, int, int]], half: int) -> None:
    # times on a 0.25 s grid, half windows off it: no range on a window's edge
    a = np.array([r[0] for r in rows], np.int64)
    n = np.array([r[1] for r in rows], np.int64)
    t = np.array([0.25 * r[2] for r in rows])
    window_s = 0.0 if half == 0 else 2.0 * (0.25 * half + 0.1)
    got = neighbours(a, n, t, window_s)
    if window_s <= 0:
        assert np.all(got == 1)
        return
    want = [int(np.sum((a == a[i]) & (n == n[i]) & (np.abs(t - t[i]) <= 0.5 * window_s)))
            for i in range(len(t))]
    np.testing.assert_array_equal(got, want)
