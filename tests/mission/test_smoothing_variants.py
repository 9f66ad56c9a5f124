"""The smoother's heading-update variants on an agent's path (hrtls.mission.smoothing)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hrtls.mission.floors import FloorLog
from hrtls.mission.graph import SmootherParams
from hrtls.mission.smoothing import SmootherState, problem
from hrtls.pipeline.schedule import MAGNETIC, RANGE, TAGS
from hrtls.pipeline.tracker import Tracker


def _mission(heading_updates: str) -> SimpleNamespace:
    """One agent walking east at 1 m/s with a tag fix (+0.5 m in y) at 2 s, a magnetic heading
    update (+0.2 m in x) at 3 s and a range to a mission node at 4 s (+0.1 m in y)."""
    st = SmootherState()
    t = np.arange(0.0, 7.0)
    jumps = np.array([[0.0, 0.5], [0.2, 0.0], [0.0, 0.1]])
    tc = np.array([2.0, 3.0, 4.0])
    xy = np.column_stack([t, np.zeros_like(t)])
    for tk, j in zip(tc, jumps, strict=True):
        xy[t >= tk] += j
    cov = np.eye(2) * (1.0 + 0.1 * t)[:, None, None]
    st.rows["R1"] = [[tk, *p, *c.reshape(-1)] for tk, p, c in zip(t, xy, cov, strict=True)]
    st.start_cov["R1"] = cov[0]
    m0 = xy[[2, 3, 4]] - jumps
    c0 = np.repeat(np.eye(2)[None] * 2.0, 3, axis=0)
    c1 = np.repeat(np.eye(2)[None] * 1.0, 3, axis=0)
    st.corr["R1"] = [[tc, np.array([TAGS, MAGNETIC, RANGE]), np.array(["T1", "", "N1"]),
                      m0, c0, m0 + jumps, c1]]
    st.ranges = [[0, np.array([5.0]), np.array(["N1"]), np.array([3.0]), np.array([0.1])]]
    return SimpleNamespace(smoother=st, params=SimpleNamespace(
        smoother=SmootherParams(heading_updates=heading_updates)), names=["R1"],
        known=[np.array(["T1"])], trackers={"R1": object.__new__(Tracker)},
        floor_logs={"R1": FloorLog()})


@pytest.mark.parametrize(("variant", "removed", "factors"),
                         [("factor", [0, 1, 2], [2.0, 3.0]), ("drop", [0, 1, 2], [2.0]),
                          ("chain", [0, 2], [2.0])])
def test_heading_updates_leave_the_chain_and_the_factors_as_told(
        variant: str, removed: list[int], factors: list[float]) -> None:
    got = problem(_mission(variant))   # type: ignore[arg-type]
    assert got is not None
    path = got[0][0]
    jumps = np.array([[0.0, 0.5], [0.2, 0.0], [0.0, 0.1]])
    tc = np.array([2.0, 3.0, 4.0])
    expected = np.column_stack([path.t, np.zeros_like(path.t)])
    for k in set(range(3)) - set(removed):
        expected[path.t >= tc[k]] += jumps[k]
    assert path.dead_reckoning_m is not None and path.factors is not None
    np.testing.assert_allclose(path.dead_reckoning_m, expected, atol=1e-12)
    np.testing.assert_allclose(path.factors[0], factors)
    # the growth curve adds back the shrinkage (1 m^2 per axis) of the removed jumps
    assert path.growth_m2 is not None
    np.testing.assert_allclose(path.growth_m2[-1], np.eye(2) * (1.6 + len(removed)))
