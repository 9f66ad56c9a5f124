"""Floors in the mission's range-SLAM smoother: the ranges of a node's floor only."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import FormatError
from hrtls.mission.floors import FloorLog, node_floor, on_node_floor
from hrtls.mission.graph import RangeSet, SmootherParams, smooth
from hrtls.mission.network_feed import NetworkState
from hrtls.mission.smoothing import SmootherState, problem, solve, state_from, state_of


def test_on_node_floor_by_hand() -> None:
    node = np.array(["A", "A", "A", "B", "B"])
    floor = np.array([0, 1, 1, 0, 2])
    keep, floors = on_node_floor(node, floor)
    assert floors == {"A": 1, "B": 0}                    # B: a tie, the lowest
    assert keep.tolist() == [False, True, True, True, False]
    keep, floors = on_node_floor(node, floor, {"A": {0: 3}, "C": {1: 9}})
    assert floors == {"A": 0, "B": 0}                    # A: 4 on floor 0 (3 cut) vs 2
    assert keep.tolist() == [True, False, False, True, False]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from("ABC"), st.integers(-1, 2)), max_size=40))
def test_on_node_floor_is_node_floor_per_node(reads: list[tuple[str, int]]) -> None:
    node = np.array([r[0] for r in reads], dtype=str)
    floor = np.array([r[1] for r in reads], dtype=np.int64)
    keep, floors = on_node_floor(node, floor)
    assert set(floors) == set(node.tolist())
    for n, f in floors.items():
        assert f == node_floor(floor[node == n].tolist())
    assert keep.tolist() == [f == floors[n] for n, f in reads]


def _mission(ranges: list[list[Any]], floors_cut: dict[str, dict[int, int]] | None = None
             ) -> Any:
    """The parts of a mission tracker that :func:`problem` reads: two agents ranging node N.

    R0 walks a circle of 4 m around (5, 5) on floor 0, R1 one around (20, 5) on floor 1.
    """
    t = np.arange(12.0)
    ang = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    rows, logs = {}, {}
    for name, cx, fl in (("R0", 5.0, 0), ("R1", 20.0, 1)):
        xy = np.column_stack([cx + 4 * np.cos(ang), 5 + 4 * np.sin(ang)])
        rows[name] = [[t[k], xy[k, 0], xy[k, 1], 0.01, 0.0, 0.0, 0.01] for k in range(12)]
        logs[name] = FloorLog()
        logs[name].add(t, np.full(12, fl, np.int64))
    sm = SmootherState(rows=rows, start_cov={k: np.eye(2) * 0.01 for k in rows},
                       ranges=ranges, floors_cut=dict(floors_cut or {}))
    return SimpleNamespace(
        smoother=sm, params=SimpleNamespace(smoother=SmootherParams(decimate_s=1.0)),
        names=["R0", "R1"], trackers={"R0": object(), "R1": object()}, known=[[], []],
        floor_logs=logs, network=NetworkState())


def _ranges(agent: int, centre: tuple[float, float]) -> list[Any]:
    """Agent ``agent``'s exact ranges (with the default height) to N at ``centre``."""
    t = np.arange(12.0)
    ang = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    cx = 5.0 if agent == 0 else 20.0
    xy = np.column_stack([cx + 4 * np.cos(ang), 5 + 4 * np.sin(ang)])
    r = np.hypot(np.hypot(*(xy - np.asarray(centre)).T), 1.0)
    return [agent, t, np.full(12, "N"), r, np.full(12, 0.1)]


def _same(a: RangeSet, b: RangeSet) -> None:
    for f in ("agent", "t", "node", "range_m", "sigma_m", "floor"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))


def test_a_node_ranged_on_two_floors_is_solved_from_its_floor_only() -> None:
    """12 ranges on floor 0 fit N at (5, 5); 8 on floor 1 (a wrong floor's) fit (20, 5)."""
    r0, r1 = _ranges(0, (5.0, 5.0)), _ranges(1, (20.0, 5.0))
    r1 = [1, *(v[:8] for v in r1[1:])]
    both = problem(_mission([r0, r1]))
    alone = problem(_mission([r0]))
    assert both is not None and alone is not None
    _same(both[1], alone[1])
    assert both[1].floor is not None and set(both[1].floor.tolist()) == {0}
    prm = SmootherParams(decimate_s=1.0)
    got, want = smooth(*both, params=prm), smooth(*alone, params=prm)
    np.testing.assert_array_equal(got.nodes["N"][0], want.nodes["N"][0])
    np.testing.assert_allclose(got.nodes["N"][0], [5.0, 5.0], atol=0.2)   # the paths move too
    paths, ranges = both
    every = RangeSet(np.r_[ranges.agent, np.ones(8, np.int64)], np.r_[ranges.t, r1[1]],
                     np.r_[ranges.node, r1[2]], np.r_[ranges.range_m, r1[3]],
                     np.r_[ranges.sigma_m, r1[4]])       # what the smoother took before floors
    assert np.hypot(*(smooth(paths, every, params=prm).nodes["N"][0] - [5.0, 5.0])) > 0.5


def test_the_ranges_the_window_cut_still_count_for_the_floor() -> None:
    r0, r1 = _ranges(0, (5.0, 5.0)), _ranges(1, (20.0, 5.0))
    r1 = [1, *(v[:8] for v in r1[1:])]
    got = problem(_mission([r0, r1], {"N": {1: 5}}))     # 13 on floor 1 against 12
    assert got is not None
    assert got[1].agent.tolist() == [1] * 8 and got[1].floor is not None
    assert set(got[1].floor.tolist()) == {1}


def test_a_node_the_smoother_localizes_takes_its_floor() -> None:
    r0, r1 = _ranges(0, (5.0, 5.0)), _ranges(1, (20.0, 5.0))
    r1 = [1, *(v[:8] for v in r1[1:])]
    for cut, floor, xy in (({}, 0, [5.0, 5.0]), ({"N": {1: 5}}, 1, [20.0, 5.0])):
        mt = _mission([r0, r1], cut)
        mt.params.cooperate = False
        mt.estimates, mt.versions, mt.history, mt.node_floor = {}, {}, {}, {"N": 1 - floor}
        assert solve(mt, 12.0, final=True) == ["N"]
        assert mt.node_floor == {"N": floor}
        np.testing.assert_allclose(mt.estimates["N"].position_m, xy, atol=0.2)


def test_the_cut_counts_go_through_a_snapshot_and_an_older_one_is_refused() -> None:
    d = state_of(SmootherState(floors_cut={"N": {0: 3, 1: 2}}))
    assert d is not None
    back = state_from(d)
    assert back is not None and back.floors_cut == {"N": {0: 3, 1: 2}}
    d.pop("floors_cut")
    with pytest.raises(FormatError, match="older snapshot"):
        state_from(d)
