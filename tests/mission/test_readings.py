"""NodeReadings.ranges: every reading keeps its own time, passes group one agent's readings."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.mission.readings import NodeReadings


def _rows(agent: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows whose x is the time and y the agent, covariance growing with time."""
    t = np.arange(0.0, 100.0, 0.5)
    xy = np.column_stack([t, np.full(len(t), float(agent))])
    cov = (1.0 + t)[:, None, None] * np.eye(2)
    return t, xy, cov


def _add(nr: NodeReadings, agent: int, t_s: list[float]) -> None:
    t = np.asarray(t_s)
    nr.add(agent=agent, t_s=t, rows=_rows(agent), range_m=np.full(len(t), 3.0),
           sigma_m=np.full(len(t), 0.1))


def test_interleaved_agents_keep_each_readings_time_and_pass() -> None:
    nr = NodeReadings()        # as windows append them: agent 0, agent 1, then agent 0 again
    _add(nr, 0, [1.0, 2.0])
    _add(nr, 1, [1.5])
    _add(nr, 0, [3.0])
    obs = nr.ranges(pass_gap_s=10.0)
    assert obs.t_s is not None
    np.testing.assert_array_equal(obs.t_s, [1.0, 2.0, 1.5, 3.0])
    np.testing.assert_array_equal(obs.agent_xy_m[:, 0], obs.t_s)   # x of a row is its time
    np.testing.assert_array_equal(obs.chain, [0, 0, 1, 0])
    g = obs.group
    assert g[0] == g[1] == g[3] != g[2]
    obs = nr.ranges(pass_gap_s=0.9)    # gaps of 1 s split agent 0's readings
    assert len(set(obs.group.tolist())) == 4


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.lists(st.floats(0.0, 99.0), min_size=1,
                                                       max_size=4)), min_size=1, max_size=8),
       st.floats(0.1, 30.0))
def test_times_stay_with_their_readings(windows: list[tuple[int, list[float]]],
                                        gap_s: float) -> None:
    nr = NodeReadings()
    for agent, t in windows:
        _add(nr, agent, t)
    obs = nr.ranges(pass_gap_s=gap_s)
    assert obs.t_s is not None
    np.testing.assert_array_equal(obs.t_s, nr.t)
    np.testing.assert_allclose(obs.agent_xy_m[:, 0], obs.t_s)
    np.testing.assert_array_equal(obs.agent_xy_m[:, 1], obs.chain)
    for g in np.unique(obs.group):        # a pass: one agent, no gap above gap_s inside
        m = obs.group == g
        assert len(set(obs.chain[m].tolist())) == 1
        assert np.all(np.diff(np.sort(obs.t_s[m])) <= gap_s)
