"""The benchmark's classes of nodes not localized (``benchmarks/_mission_why.py``)."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
import pytest

from hrtls.mission.nodes import NodeEstimator, NodeRanges


@pytest.fixture(scope="module")
def why(benchmark_import: Callable[[str], ModuleType]) -> ModuleType:
    return benchmark_import("_mission_why")


def _ranges(xy: np.ndarray, node: np.ndarray) -> NodeRanges:
    k = len(xy)
    return NodeRanges.build(agent_xy_m=xy, agent_cov_m2=np.tile(0.01 * np.eye(2), (k, 1, 1)),
                            range_m=np.hypot(*(xy - node).T), range_sigma_m=np.full(k, 0.1),
                            group=np.zeros(k, dtype=int))


def test_the_estimators_reasons_fall_in_their_classes(why: ModuleType) -> None:
    est = NodeEstimator()
    node = np.array([5.0, 4.0])
    few = est.estimate(_ranges(np.array([[0.0, 0.0], [1.0, 0.0]]), node))
    line = est.estimate(_ranges(np.column_stack([np.linspace(0, 10, 11), np.zeros(11)]), node))
    assert not few.localized and why.reason_class(few.reason) == "too few readings"
    assert not line.localized and why.reason_class(line.reason) == "one straight pass / mirror"
    assert why.reason_class("mirror ambiguity across pass 3") == "one straight pass / mirror"
    assert why.reason_class("ranges of the passes disagree") == "NLOS / pass gates"
    assert why.reason_class("too few ranges left after the NLOS gate") == "NLOS / pass gates"
    assert why.reason_class("ranges inconsistent with the solution (...)") == "fit gate"
    assert why.reason_class("sigma 6.2 m above 5 m") == "sigma too large"
    assert why.reason_class("singular geometry") == "other"


def test_the_table_sums_the_seeds_and_gives_shares_of_all_nodes(why: ModuleType) -> None:
    a = dict.fromkeys((*why.CLASSES, *why.EXTRA), 0)
    b = dict(a)
    a.update({"localized": 3, "sigma too large": 1, "from true positions": 1})
    b.update({"localized": 2, "never in range": 2})
    text = why.why_table({"on": [a, b]})
    assert "| localized | 5 (0.62) |" in text  # 5 of the 8 nodes of both seeds
    assert "| never in range | 2 (0.25) |" in text
    assert "| from true positions | 1 (0.12) |" in text
