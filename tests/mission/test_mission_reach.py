"""Where the nodes not localized were lost (``benchmarks/_mission_reach.py``)."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
import pytest
from shapely.geometry import box


@pytest.fixture(scope="module")
def reach(benchmark_import: Callable[[str], ModuleType]) -> ModuleType:
    return benchmark_import("_mission_reach")


CROSS = (box(0, 0, 20, 3), box(0, 0, 3, 20))  # an L: the square 0..3 x 0..3 is in both


def test_corridors_count_the_points_lying_in_one_corridor_only(reach: ModuleType) -> None:
    along = np.column_stack([np.linspace(4.0, 18.0, 8), np.full(8, 1.5)])
    corner = np.array([[1.0, 1.0], [2.0, 2.0], [1.5, 1.5], [2.5, 0.5]])  # in both: neither
    up = np.array([[1.5, 5.0], [1.5, 6.0], [1.5, 7.0]])
    assert reach.corridors_seen(along, CROSS) == 1
    assert reach.corridors_seen(np.vstack([along, corner]), CROSS) == 1
    assert reach.corridors_seen(np.vstack([along, up]), CROSS) == 2
    assert reach.corridors_seen(np.vstack([along, up[:2]]), CROSS) == 1  # 2 < min_readings
    assert reach.corridors_seen(np.vstack([along, up[:2]]), CROSS, min_readings=2) == 2
    assert reach.corridors_seen(np.zeros((0, 2)), CROSS) == 0


def test_the_classes_are_checked_in_order(reach: ModuleType) -> None:
    def cls(**kw: float) -> str:
        base = {"closest_m": 2.0, "max_range_m": 10.0, "n_ranges": 40, "n_readings": 30,
                "corridors": 2}
        return str(reach.reach_class(**{**base, **kw}))

    assert cls(closest_m=10.5, n_ranges=0, n_readings=0, corridors=0) == "never in range"
    assert cls(n_ranges=0, n_readings=0, corridors=0) == "silent"
    assert cls(n_readings=0, corridors=0) == "not kept"
    assert cls(corridors=1) == "one corridor"
    assert cls() == "rejected"
    assert cls(closest_m=10.0) == "rejected"  # at the radio's range: in range


def test_the_lines_count_each_class(reach: ModuleType) -> None:
    rows = [reach.NodeReach("N3", "one corridor", 1.0, 12.0, 30, 28, 2, 1, "one straight pass "
                            "/ mirror", False),
            reach.NodeReach("N9", "never in range", 11.0, float("inf"), 0, 0, 0, 0, "", False)]
    lines = reach.reach_lines(4, 40, rows)
    assert lines[0] == ("seed 4: 38 of 40 localized; not: never in range 1, silent 0, not kept "
                        "0, one corridor 1, rejected 0")
    assert lines[1].startswith("  N3: one corridor; closest agent 1.0 m, robot 12.0 m; 30 ranges")
    assert "from true positions not localized" in lines[1]
    assert "estimator" not in lines[2]
