"""Floors in the mission loop: floor logs, node floors, readings of one floor, a two-floor
mission tracked offline, live and from a snapshot alike."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Session
from hrtls.errors import InputError
from hrtls.mission import smoothing
from hrtls.mission.floors import FloorLog, node_floor
from hrtls.mission.nodes import NodeEstimator
from hrtls.mission.readings import NodeReadings
from hrtls.mission.smoother_modes import smoother_params
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionResult, MissionTracker
from hrtls.pipeline import snapshot as codec
from hrtls.pipeline.chunks import split_session
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission
from hrtls.sim.mission_floors import FLOOR_HEIGHT_M, NODE_HEIGHT_M


def test_floor_log_keeps_the_changes_and_replaces_a_revised_last_row() -> None:
    log = FloorLog()
    assert log.now() == 0
    log.add(np.array([1.0, 2.0, 3.0]), np.array([0, 1, 1]))
    assert (log.t, log.floor) == ([2.0], [1])
    np.testing.assert_array_equal(log.at(np.array([0.5, 1.9, 2.0, 9.0])), [0, 0, 1, 1])
    log.add(np.array([2.0, 4.0]), np.array([0, 0]))      # the row at 2 s revised: floor 0
    assert (log.t, log.floor, log.now()) == ([], [], 0)
    log.add(np.array([5.0, 6.0]), np.array([1, 2]))
    assert (log.t, log.floor, log.now()) == ([5.0, 6.0], [1, 2], 2)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(-1, 3), min_size=1, max_size=40), st.integers(1, 39))
def test_floor_log_gives_each_row_its_floor_whatever_the_pulls(floors: list[int],
                                                               cut: int) -> None:
    t = np.arange(len(floors), dtype=float)
    f = np.asarray(floors, dtype=np.int64)
    log = FloorLog()
    k = min(cut, len(t))
    log.add(t[:k], f[:k])
    log.add(t[max(k - 1, 0):], f[max(k - 1, 0):])      # the last row read again
    np.testing.assert_array_equal(log.at(t), f)


def test_node_floor_is_the_floor_of_most_readings_ties_the_lowest() -> None:
    assert node_floor([]) == 0
    assert node_floor([1, 1, 0]) == 1
    assert node_floor([1, 0]) == 0
    assert node_floor([-1, -1, 2]) == -1


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.integers(-1, 2)), min_size=1, max_size=30))
def test_the_readings_of_each_floor_partition_all_readings(reads: list[tuple[int, int]]) -> None:
    nr = NodeReadings()
    for k, (agent, floor) in enumerate(reads):
        t = np.array([float(k)])
        nr.add(agent=agent, t_s=t, rows=(t, np.array([[float(k), 0.0]]), np.eye(2)[None]),
               range_m=np.array([1.0 + k]), sigma_m=np.array([0.1]),
               floor=np.array([floor], dtype=np.int64))
    parts = [nr.ranges(15.0, floor=f) for f in (-1, 0, 1, 2)]
    assert sum(len(p) for p in parts) == len(nr.ranges(15.0)) == len(reads)
    for f, p in zip((-1, 0, 1, 2), parts, strict=True):
        want = [1.0 + k for k, (_, fl) in enumerate(reads) if fl == f]
        assert sorted(p.range_m.tolist()) == want
        assert sorted(p.agent_xy_m[:, 0].tolist()) == [w - 1.0 for w in want]


def test_a_node_is_never_estimated_from_readings_of_another_floor() -> None:
    """Hand-built: 12 readings on floor 0 fit a node at (5, 5); 8 readings on floor 1 (an
    agent whose floor estimate is right there: another node id reused) fit (20, 5)."""
    reads = NodeReadings()
    cov = np.tile(np.eye(2) * 0.01, (12, 1, 1))
    ang = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    xy0 = np.column_stack([5 + 4 * np.cos(ang), 5 + 4 * np.sin(ang)])
    t0 = np.arange(12.0)
    reads.add(agent=0, t_s=t0, rows=(t0, xy0, cov), range_m=np.hypot(*(xy0 - [5, 5]).T),
              sigma_m=np.full(12, 0.1), floor=np.zeros(12, dtype=np.int64))
    xy1 = xy0[:8] + np.array([15.0, 0.0])
    t1 = 100.0 + np.arange(8.0)
    reads.add(agent=1, t_s=t1, rows=(t1, xy1, cov[:8]), range_m=np.hypot(*(xy1 - [20, 5]).T),
              sigma_m=np.full(8, 0.1), floor=np.ones(8, dtype=np.int64))
    floor = node_floor(reads.floor)
    assert floor == 0
    obs = reads.ranges(15.0, floor=floor)
    assert len(obs) == 12 and set(obs.chain.tolist()) == {0}
    est = NodeEstimator().estimate(obs)
    assert est.localized
    np.testing.assert_allclose(est.position_m, [5.0, 5.0], atol=0.05)
    assert len(reads.ranges(15.0)) == 20                 # all floors: what the old loop used


@pytest.mark.parametrize("options", [{"n_floors": 3}, {"n_floors": 0},
                                     {"n_floors": 2, "peer_ranges": True},
                                     {"n_floors": 2, "rescuer_driver": "planner"}])
def test_two_floor_options_are_checked(options: dict[str, object]) -> None:
    with pytest.raises(InputError):
        MissionOptions(**options)  # type: ignore[arg-type]


OPTIONS = MissionOptions(n_floors=2, walk_s=60.0, stagger_s=15.0, n_nodes=16, n_rescuers=2)


@pytest.fixture(scope="module")
def two_floors() -> Mission:
    return inderst_hybrid_mission(4, OPTIONS)


def test_the_simulated_building_has_nodes_and_tags_on_both_floors(two_floors: Mission) -> None:
    m = two_floors
    assert set(m.node_floor.values()) == {0, 1}
    tags = {k: lm for s in m.agents.values() for k, lm in s.landmarks.items()}
    assert {lm.floor for lm in tags.values()} == {0, 1}
    for lm in tags.values():
        assert lm.position is not None
        assert lm.position[2] == pytest.approx(2.2 + (lm.floor or 0) * FLOOR_HEIGHT_M)
    for name, sim in m.simulations.items():
        s = m.agents[name]
        assert s.truth is not None
        z = s.truth.xyz[:, 2]
        if m.kinds[name] == "robot":
            assert np.all(z == 0.0)
            assert s.ranges is not None
            assert {m.node_floor[str(n)] for n in s.ranges.node} == {0}
            continue
        assert z.min() == 0.0 and z.max() == pytest.approx(FLOOR_HEIGHT_M)   # climbed
        assert s.pressure is not None and s.meta.floor_height_m == FLOOR_HEIGHT_M
        assert s.ranges is not None
        zr = np.interp(s.ranges.t, s.truth.t, z)                  # the slab blocks the radio
        floors = np.array([m.node_floor[str(n)] for n in s.ranges.node])
        np.testing.assert_array_equal(np.rint(zr / FLOOR_HEIGHT_M), floors)
        assert sim.motion is not None
    assert all(lm.kind != "node" for s in m.agents.values() for lm in s.landmarks.values())
    assert NODE_HEIGHT_M == 0.5


def _no_truth(m: Mission) -> dict[str, Session]:
    return {k: s.with_parts(truth=None, checkpoints=None) for k, s in m.agents.items()}


@pytest.fixture(scope="module", params=["off", "nodes", "feedback"])
def offline(request: pytest.FixtureRequest, two_floors: Mission
            ) -> tuple[MissionTracker, MissionResult]:
    """The mission tracked offline with the per-node estimator alone, or with the smoother."""
    mt = MissionTracker(_no_truth(two_floors), kinds=two_floors.kinds,
                        params=MissionParams(smoother=smoother_params(request.param)))
    return mt, mt.run()


def test_floor_1_nodes_localized_on_floor_1_from_its_readings_only(
        two_floors: Mission, offline: tuple[MissionTracker, MissionResult]) -> None:
    mt, res = offline
    m = two_floors
    owned = mt.smoother.owned if mt.smoother is not None else set()
    assert mt.smoother is None or owned, "the smoother localized no node"
    on1 = [n for n, e in res.nodes.items() if e.localized and m.node_floor[n] == 1]
    assert on1, "no floor-1 node localized"
    for n, e in res.nodes.items():
        if not e.localized:
            continue
        assert res.node_floor[n] == m.node_floor[n]
        if n in owned:          # the smoother's ranges: test_smoother_keeps_the_node_floor_s...
            continue
        floors = np.asarray(mt.readings[n].floor)[:mt.estimated_at[n]]   # those it had then
        assert len(e.used) == np.count_nonzero(floors == res.node_floor[n])
    assert {mt.floor_logs[k].now() for k in m.agents if m.kinds[k] == "rescuer"} <= {0, 1}
    assert any(1 in log.floor for log in mt.floor_logs.values())


def test_two_floor_node_errors_are_coarse(
        two_floors: Mission, offline: tuple[MissionTracker, MissionResult]) -> None:
    _, res = offline
    m = two_floors
    err = [np.hypot(*(e.position_m - m.node_truth_m[n])) for n, e in res.nodes.items()
           if e.localized]
    # coarse: two rescuers on 60 s walks give each node one or two passes
    assert np.median(err) < 4.0 and max(err) < 8.0


def test_the_smoothers_robot_path_stays_near_the_robots_rows(
        two_floors: Mission, monkeypatch: pytest.MonkeyPatch) -> None:
    """At every solve of mode ``feedback``, the robot's poses in the smoother against its own
    rows (odometry alone here): 6.8 m at most with the robot's chain model, 15 m before it."""
    mt = MissionTracker(_no_truth(two_floors), kinds=two_floors.kinds,
                        params=MissionParams(smoother=smoother_params("feedback")))
    robot = next(k for k in two_floors.kinds if two_floors.kinds[k] == "robot")
    gaps: list[float] = []
    solve = smoothing.solve

    def spy(mt_: MissionTracker, t_end: float, *, final: bool = False) -> list[str]:
        out = solve(mt_, t_end, final=final)
        assert mt_.smoother is not None
        w = mt_.smoother.warm
        if w is not None and robot in w.paths:
            tp, xp = (np.asarray(v) for v in w.paths[robot])
            est = mt_.trackers[robot].estimates_since(-np.inf)
            own = np.column_stack([np.interp(tp, est.t, est.xyz[:, k]) for k in (0, 1)])
            gaps.append(float(np.max(np.hypot(*(xp - own).T))))
        return out

    monkeypatch.setattr(smoothing, "solve", spy)
    mt.run()
    assert len(gaps) > 10
    assert max(gaps) < 8.0


def _live(m: Mission, params: MissionParams, *, snapshot_at: int | None = None
          ) -> MissionResult:
    sessions = _no_truth(m)
    mt = MissionTracker({k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()},
                        kinds=m.kinds, params=params)
    parts = sorted([(k, p) for k, s in sessions.items() for p in split_session(s, 2.0)],
                   key=lambda kp: kp[1].time_span()[1])
    for j, (name, part) in enumerate(parts):
        if j == snapshot_at:
            mt = MissionTracker.restore(mt.snapshot())
        assert mt.feed(name, part, now_s=float(j)) is None
        mt.advance(now_s=float(j))
    for k in sessions:
        mt.end(k)
    return mt.run()


def _same(a: MissionResult, b: MissionResult) -> None:
    assert a.node_floor == b.node_floor
    assert {n: e.localized for n, e in a.nodes.items()} == \
        {n: e.localized for n, e in b.nodes.items()}
    for n, e in a.nodes.items():
        if e.localized:
            np.testing.assert_array_equal(e.position_m, b.nodes[n].position_m)


def test_a_two_floor_mission_fed_live_gives_the_offline_run(
        two_floors: Mission, offline: tuple[MissionTracker, MissionResult]) -> None:
    mt, want = offline
    got = _live(two_floors, mt.params)
    _same(want, got)
    for k, r in want.agents.items():
        np.testing.assert_array_equal(r.trajectory.xyz, got.agents[k].trajectory.xyz)


def test_a_restored_two_floor_mission_continues_identically(
        two_floors: Mission, offline: tuple[MissionTracker, MissionResult]) -> None:
    mt, want = offline
    _same(want, _live(two_floors, mt.params, snapshot_at=150))


def test_a_version_3_snapshot_restores_on_floor_0() -> None:
    m = inderst_hybrid_mission(1, MissionOptions(walk_s=40.0, stagger_s=10.0, n_nodes=10,
                                                 n_robots=0))
    sessions = _no_truth(m)
    want = MissionTracker(sessions, kinds=m.kinds).run()
    half = MissionTracker(sessions, kinds=m.kinds)
    spans = [s.time_span() for s in sessions.values()]
    half.advance((min(a for a, _ in spans) + max(b for _, b in spans)) / 2)
    assert half.readings
    state = codec.unpack(half.snapshot())
    state["mission_version"] = 3
    for key in ("floor_logs", "node_floor"):
        state["nodes"].pop(key)
    state["nodes"]["readings"] = {n: r[:6] for n, r in state["nodes"]["readings"].items()}
    old = MissionTracker.restore(codec.pack(state))
    assert all(r.floor == [0] * len(r.t) for r in old.readings.values())
    _same(want, old.run())
