"""Chaining events across short gaps: hand-computed cases and invariants."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.gait.chains import chain_runs, chain_starts


def test_chain_starts_hand_computed() -> None:
    t = np.array([0.0, 1.0, 3.5, 4.0, 6.0, 9.0])
    assert chain_starts(t, max_gap_s=2.0).tolist() == [True, False, True, False, False, True]
    # an earlier event 1 s before the first one continues its chain
    assert chain_starts(t, max_gap_s=2.0, t_before_s=-1.0)[0] == np.False_
    starts, ends = chain_runs(t, max_gap_s=2.0)
    assert starts.tolist() == [0, 2, 5]
    assert ends.tolist() == [2, 5, 6]


def test_chain_runs_empty_and_gap_equal_to_limit() -> None:
    starts, ends = chain_runs(np.zeros(0), max_gap_s=1.0)
    assert starts.size == 0 and ends.size == 0
    # a gap of exactly max_gap_s stays in the chain
    assert chain_starts(np.array([0.0, 2.0]), max_gap_s=2.0).tolist() == [True, False]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 5.0), min_size=1, max_size=30), st.floats(0.1, 3.0))
def test_chain_runs_partition(gaps: list[float], max_gap_s: float) -> None:
    t = np.cumsum(gaps)
    starts, ends = chain_runs(t, max_gap_s=max_gap_s)
    assert starts[0] == 0 and ends[-1] == t.size
    assert np.array_equal(starts[1:], ends[:-1])
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        assert np.all(np.diff(t[a:b]) <= max_gap_s)
        if a > 0:
            assert t[a] - t[a - 1] > max_gap_s
    # streaming: chaining the second half after the first gives the same starts
    k = t.size // 2
    whole = chain_starts(t, max_gap_s=max_gap_s)
    before = -math.inf if k == 0 else float(t[k - 1])
    assert np.array_equal(chain_starts(t[k:], max_gap_s=max_gap_s, t_before_s=before), whole[k:])
