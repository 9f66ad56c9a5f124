"""MissionTracker live: feed / advance in parts gives run()'s result; late data; silence;
snapshot and restore in another process."""

from __future__ import annotations

import concurrent.futures
import itertools
import math
import multiprocessing
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.data import Landmark, Session
from hrtls.errors import FormatError, InputError
from hrtls.mission.buffer import AgentBuffer, LateData, merge, split_at
from hrtls.mission.smoother_modes import smoother_params
from hrtls.mission.tracker import AgentHeader, MissionParams, MissionResult, MissionTracker
from hrtls.pipeline.chunks import session_window, split_session
from hrtls.pipeline.corrections import SMOOTHED
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

PART_S = 0.5


def _mission(seed: int) -> tuple[dict[str, Session], dict[str, str]]:
    """A short mission (seed 1 with a robot); sessions without ground truth."""
    m = inderst_hybrid_mission(seed, MissionOptions(walk_s=60.0, stagger_s=15.0, n_nodes=15,
                                                    n_robots=1 if seed == 1 else 0))
    return ({k: s.with_parts(truth=None, checkpoints=None) for k, s in m.agents.items()},
            dict(m.kinds))


def _headers(sessions: dict[str, Session]) -> dict[str, AgentHeader]:
    return {k: AgentHeader(s.meta, dict(s.landmarks)) for k, s in sessions.items()}


def _parts(sessions: dict[str, Session]) -> list[tuple[str, Session]]:
    """Every agent's parts of ``PART_S``, interleaved by their end time (as they arrive)."""
    out = [(k, p) for k, s in sessions.items() for p in split_session(s, PART_S)]
    return sorted(out, key=lambda kp: kp[1].time_span()[1])


def _live(sessions: dict[str, Session], kinds: dict[str, str], *, cut: int | None = None,
          params: MissionParams | None = None) -> tuple[MissionTracker, int]:
    """Feed the parts in arrival order, advancing after each; stop before part ``cut``."""
    mt = MissionTracker(_headers(sessions), kinds=kinds, params=params)
    parts = _parts(sessions)
    for j, (name, part) in enumerate(parts[:cut]):
        assert mt.feed(name, part, now_s=float(j)) is None
        mt.advance(now_s=float(j))
    return mt, len(parts)


def _restored_half_way(sessions: dict[str, Session], kinds: dict[str, str],
                       params: MissionParams) -> MissionTracker:
    """Half the parts fed live, a snapshot restored, the rest fed, every agent ended."""
    parts = _parts(sessions)
    half = len(parts) // 2
    mt, _ = _live(sessions, kinds, cut=half, params=params)
    mt = MissionTracker.restore(mt.snapshot())
    for j, (name, part) in enumerate(parts[half:], start=half):
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
    for k in sessions:
        mt.end(k)
    return mt


def _max_diff(a: MissionResult, b: MissionResult, *, tail: bool = False) -> float:
    """Largest difference of node estimates, node history and agent rows (``tail``: ``b``
    holds each agent's rows from some time on)."""
    assert {n: e.localized for n, e in a.nodes.items()} == \
        {n: e.localized for n, e in b.nodes.items()}
    d = 0.0
    for n, e in a.nodes.items():
        if e.localized:
            d = max(d, float(np.max(np.abs(e.position_m - b.nodes[n].position_m))),
                    float(np.max(np.abs(e.covariance_m2 - b.nodes[n].covariance_m2))))
    assert set(a.node_history) == set(b.node_history)
    for n, h in a.node_history.items():
        np.testing.assert_array_equal(h.t, b.node_history[n].t)
        d = max(d, float(np.max(np.abs(h.position_m - b.node_history[n].position_m))))
    for k, r in a.agents.items():
        ta, tb = r.trajectory, b.agents[k].trajectory
        i = int(np.searchsorted(ta.t, tb.t[0])) if tail else 0
        assert len(ta.t) - i == len(tb.t), k
        d = max(d, float(np.max(np.abs(ta.xyz[i:] - tb.xyz))),
                float(np.max(np.abs(ta.cov_xy[i:] - tb.cov_xy))))
    return d


@pytest.fixture(scope="module")
def seed1() -> tuple[dict[str, Session], dict[str, str]]:
    return _mission(1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_parts_fed_live_give_the_offline_run(seed: int) -> None:
    sessions, kinds = _mission(seed)
    want = MissionTracker(sessions, kinds=kinds).run()
    assert sum(e.localized for e in want.nodes.values()) >= 1
    mt, _ = _live(sessions, kinds)
    assert mt.horizon_s < max(s.time_span()[1] for s in sessions.values())
    for k in sessions:
        mt.end(k)
    got = mt.run()
    assert _max_diff(want, got) <= 1e-12


def test_a_window_waits_for_every_agent_and_no_longer_than_silent_after_s(seed1) -> None:  # type: ignore[no-untyped-def]
    sessions, kinds = seed1
    mt = MissionTracker(_headers(sessions), kinds=kinds, now_s=0.0)
    first, *others = list(sessions)
    for p in split_session(sessions[first], PART_S):
        mt.feed(first, p, now_s=1.0)
    assert mt.advance(now_s=1.0).windows == 0            # the others hold the windows back
    silent = mt.params.silent_after_s
    assert mt.advance(now_s=silent - 1.0).windows == 0
    done = mt.advance(now_s=silent + 2.0)                 # the others are silent now
    assert done.windows > 0 and done.horizon_s == mt.horizon_s
    late = mt.feed(others[0], sessions[others[0]], now_s=silent + 3.0)
    assert isinstance(late, LateData) and late.agent == others[0]
    assert late.horizon_s == mt.horizon_s and late.t_last_s < mt.horizon_s
    before, _ = split_at(sessions[others[0]], mt.horizon_s)
    assert before is not None and late.samples > 0
    assert late.samples == (len(before.imu.accel.t) if before.imu is not None else 0) + sum(
        len(getattr(before, k).t) for k in ("ranges", "tags", "fixes", "rss", "pressure")
        if getattr(before, k) is not None)


def test_feed_refuses_an_unknown_agent_and_merge_keeps_time_order(seed1) -> None:  # type: ignore[no-untyped-def]
    sessions, kinds = seed1
    mt = MissionTracker(_headers(sessions), kinds=kinds)
    with pytest.raises(InputError, match="unknown agent"):
        mt.feed("nobody", sessions["R1"])
    parts = list(split_session(sessions["R1"], 7.0))
    joined = merge(merge(parts[2], parts[0]), parts[1])
    want = split_session(sessions["R1"], 1e6).__next__()
    assert joined.imu is not None and want.imu is not None
    np.testing.assert_array_equal(joined.imu.accel.t, want.imu.accel.t[:len(joined.imu.accel.t)])
    assert joined.ranges is not None and np.all(np.diff(joined.ranges.t) >= 0)


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cuts=st.lists(st.floats(min_value=0.0, max_value=1.0), max_size=6),
       order=st.randoms(use_true_random=False))
def test_a_buffer_holds_the_same_data_whatever_the_parts_and_their_order(
        seed1, cuts: list[float], order: Any) -> None:  # type: ignore[no-untyped-def]
    sessions, _ = seed1
    s = sessions["R1"]
    a, b = s.time_span()
    edges = [-math.inf, *sorted(a + c * (b - a) for c in cuts), math.inf]
    parts = [p for lo, hi in itertools.pairwise(edges)
             if (p := session_window(s, lo, hi)) is not None]
    order.shuffle(parts)
    buf = AgentBuffer("R1")
    for p in parts:
        assert buf.add(p, horizon_s=-math.inf, now_s=0.0) is None
    assert (buf.t_first, buf.t_last) == (a, b)
    got, want = buf.window(a, b + 1.0), split_at(s, b + 1.0)[0]
    assert got is not None and want is not None
    assert got.imu is not None and want.imu is not None
    np.testing.assert_array_equal(got.imu.accel.t, want.imu.accel.t)
    np.testing.assert_array_equal(got.imu.accel.values, want.imu.accel.values)
    assert got.ranges is not None and want.ranges is not None
    np.testing.assert_array_equal(got.ranges.t, want.ranges.t)
    assert sorted(zip(got.ranges.t, got.ranges.node, got.ranges.range_m, strict=True)) == \
        sorted(zip(want.ranges.t, want.ranges.node, want.ranges.range_m, strict=True))


def test_landmark_versions_given_live_act_as_given_at_the_start(seed1) -> None:  # type: ignore[no-untyped-def]
    """A node known from the start (a range anchor of every agent) moved at 30 s."""
    m = inderst_hybrid_mission(1, MissionOptions(walk_s=60.0, stagger_s=15.0, n_nodes=15,
                                                 n_robots=1))
    base, kinds = seed1
    heard = np.concatenate([s.ranges.node[s.ranges.t > 30.0] for s in base.values()
                            if s.ranges is not None])
    names, counts = np.unique(heard, return_counts=True)
    node = str(names[np.argmax(counts)])
    x, y = m.node_truth_m[node]
    anchor = Landmark(id=node, kind="node", position=(float(x), float(y), 0.5))
    sessions = {k: s.with_parts(landmarks={**s.landmarks, node: anchor})
                for k, s in base.items()}
    moved = anchor.model_copy(update={"position": (float(x) + 3.0, float(y), 0.5),
                                      "updated": 30.0})
    want = MissionTracker(sessions, kinds=kinds, landmark_updates=[moved]).run()
    plain = MissionTracker(sessions, kinds=kinds).run()
    assert any(len(r.trajectory.t) != len(plain.agents[k].trajectory.t)   # the version
               or np.max(np.abs(r.trajectory.xyz - plain.agents[k].trajectory.xyz)) > 1e-3
               for k, r in want.agents.items())                          # changes the mission
    mt = MissionTracker(_headers(sessions), kinds=kinds)
    given = False
    for j, (name, part) in enumerate(_parts(sessions)):
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
        if not given and mt.horizon_s >= 10.0:
            assert mt.add_landmark_updates([moved]) == []
            given = True
    late = moved.model_copy(update={"updated": mt.horizon_s - 1.0})
    assert mt.add_landmark_updates([late]) == [late]
    for k in sessions:
        mt.end(k)
    assert _max_diff(want, mt.run(), tail=True) <= 1e-12      # rows made after the restore


def test_a_foreign_snapshot_is_refused() -> None:
    from hrtls.pipeline.snapshot import pack

    with pytest.raises(FormatError):
        MissionTracker.restore(b"not a snapshot")
    with pytest.raises(FormatError, match="format"):
        MissionTracker.restore(pack({"format": "other"}))


def continue_from(seed: int, state: bytes, cut: int) -> dict[str, Any]:
    """In a fresh process: restore, feed the parts from ``cut`` on, finish; plain results."""
    sessions, _ = _mission(seed)
    mt = MissionTracker.restore(state)
    for j, (name, part) in enumerate(_parts(sessions)[cut:], start=cut):
        assert mt.feed(name, part, now_s=float(j)) is None
        mt.advance(now_s=float(j))
    for k in sessions:
        mt.end(k)
    res = mt.run()
    return {"nodes": {n: (e.localized, e.position_m, e.covariance_m2)
                      for n, e in res.nodes.items()},
            "history": {n: (h.t, h.position_m) for n, h in res.node_history.items()},
            "agents": {k: (r.trajectory.t, r.trajectory.xyz) for k, r in res.agents.items()}}


@settings(max_examples=3, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(min_value=0.05, max_value=0.95))
def test_restored_in_a_new_process_the_mission_continues_identically(  # type: ignore[no-untyped-def]
        seed1, fraction: float) -> None:
    sessions, kinds = seed1
    want = MissionTracker(sessions, kinds=kinds).run()
    n_parts = len(_parts(sessions))
    cut = max(1, math.floor(fraction * n_parts))
    mt, _ = _live(sessions, kinds, cut=cut)
    state = mt.snapshot()
    assert state.startswith(b"HRTLSNAP")
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx) as pool:
        got = pool.submit(continue_from, 1, state, cut).result(timeout=600)
    for n, e in want.nodes.items():
        localized, pos, cov = got["nodes"][n]
        assert localized == e.localized
        if e.localized:
            np.testing.assert_array_equal(pos, e.position_m)
            np.testing.assert_array_equal(cov, e.covariance_m2)
    assert set(got["history"]) == set(want.node_history)
    for n, (t, pos) in got["history"].items():
        np.testing.assert_array_equal(t, want.node_history[n].t)
        np.testing.assert_array_equal(pos, want.node_history[n].position_m)
    for k, (t, xyz) in got["agents"].items():
        full = want.agents[k].trajectory
        if not len(t):   # every row of this agent was made before the snapshot
            assert full.t[-1] <= mt.horizon_s + mt.params.chunk_s
            continue
        i = int(np.searchsorted(full.t, t[0]))
        np.testing.assert_array_equal(t, full.t[i:])
        np.testing.assert_array_equal(xyz, full.xyz[i:])


def _ranges_to_unknown_nodes(sessions: dict[str, Session]) -> int:
    """Ranges of every agent to nodes without a position in its session."""
    n = 0
    for s in sessions.values():
        if s.ranges is not None:
            known = [k for k, lm in s.landmarks.items() if lm.position is not None]
            n += int(np.count_nonzero(~np.isin(s.ranges.node, known)))
    return n


def test_readings_later_than_the_agents_latest_row_are_kept(seed1) -> None:  # type: ignore[no-untyped-def]
    sessions, kinds = seed1
    mt = MissionTracker(_headers(sessions), kinds=kinds,
                        params=MissionParams(cooperate=False))
    held = 0
    for j, (name, part) in enumerate(_parts(sessions)):
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
        held = max(held, sum(len(r.t) for r in mt.pending.values() if r is not None))
    for k in sessions:
        mt.end(k)
    res = mt.run()
    assert held > 0           # some ranges waited for their agent's rows
    assert all(r is None for r in mt.pending.values())
    assert sum(res.readings.values()) == _ranges_to_unknown_nodes(sessions)


def test_snapshot_holds_the_pending_readings(seed1) -> None:  # type: ignore[no-untyped-def]
    sessions, kinds = seed1
    parts = _parts(sessions)
    mt = MissionTracker(_headers(sessions), kinds=kinds)
    j = 0
    while not any(r is not None for r in mt.pending.values()):
        mt.feed(parts[j][0], parts[j][1], now_s=float(j))
        mt.advance(now_s=float(j))
        j += 1
    back = MissionTracker.restore(mt.snapshot())
    for k, r in mt.pending.items():
        got = back.pending[k]
        assert (r is None) == (got is None)
        if r is not None and got is not None:
            np.testing.assert_array_equal(got.t, r.t)
            np.testing.assert_array_equal(got.node, r.node)
            np.testing.assert_array_equal(got.range_m, r.range_m)
            np.testing.assert_array_equal(got.sigma_m, r.sigma_m)
    for m in (mt, back):
        for i, (name, part) in enumerate(parts[j:], start=j):
            m.feed(name, part, now_s=float(i))
            m.advance(now_s=float(i))
        for k in sessions:
            m.end(k)
    assert _max_diff(mt.run(), back.run(), tail=True) == 0.0


def test_with_the_information_gate_live_and_restored_give_the_offline_run(seed1) -> None:  # type: ignore[no-untyped-def]
    """``use_variance_ratio`` 0.3 (the gate reads each agent's latest row): parts fed live, and
    a snapshot restored half-way then fed the rest, give the offline run."""
    sessions, kinds = seed1
    prm = MissionParams(use_variance_ratio=0.3)
    want = MissionTracker(sessions, kinds=kinds, params=prm).run()
    assert len(want.uses) < len(MissionTracker(sessions, kinds=kinds).run().uses)  # it gates
    mt = _restored_half_way(sessions, kinds, prm)
    assert mt.params.use_variance_ratio == 0.3
    assert _max_diff(want, mt.run(), tail=True) <= 1e-12      # rows made after the restore


def test_smoothed_readings_move_the_readings(seed1) -> None:  # type: ignore[no-untyped-def]
    """``smooth_readings_s`` 30 places some readings elsewhere than the filtered rows."""
    sessions, kinds = seed1
    alone = [MissionTracker(sessions, kinds=kinds, params=MissionParams(
        cooperate=False, smooth_readings_s=s)) for s in (0.0, 30.0)]
    for a in alone:
        a.run()
    assert any(not np.allclose(np.asarray(r.xy), np.asarray(alone[1].readings[n].xy))
               for n, r in alone[0].readings.items())


Offline = dict[tuple[float, str], tuple[MissionTracker, MissionResult]]


@pytest.fixture(scope="module")
def offline_runs() -> Offline:
    """Offline runs of seed 1 by (bridge lag, smoother mode), made once."""
    return {}


def _offline(runs: Offline, mission: tuple[dict[str, Session], dict[str, str]], smooth_s: float,
             mode: str) -> tuple[MissionTracker, MissionResult]:
    """The offline run of ``mission`` with the bridge's lag and the smoother's mode."""
    if (smooth_s, mode) not in runs:
        sessions, kinds = mission
        mt = MissionTracker(sessions, kinds=kinds, params=MissionParams(
            smooth_readings_s=smooth_s, smoother=smoother_params(mode)))
        runs[(smooth_s, mode)] = (mt, mt.run())
    return runs[(smooth_s, mode)]


def _same_as_offline(offline: tuple[MissionTracker, MissionResult], mt: MissionTracker) -> None:
    assert _max_diff(offline[1], mt.run(), tail=True) <= 1e-12      # rows after the restore
    assert set(mt.readings) == set(offline[0].readings)
    for n, r in offline[0].readings.items():
        np.testing.assert_allclose(np.asarray(mt.readings[n].xy), np.asarray(r.xy), atol=1e-12)
        np.testing.assert_allclose(np.asarray(mt.readings[n].cov), np.asarray(r.cov), atol=1e-12)


@pytest.mark.parametrize("mode", ["off", "nodes", "feedback"])
def test_with_smoothed_readings_live_and_restored_give_the_offline_run(  # type: ignore[no-untyped-def]
        seed1, offline_runs, mode: str) -> None:
    """``smooth_readings_s`` 30 (readings moved to the rescuers' smoothed rows) with each
    smoother mode: a snapshot restored half-way then fed the rest gives the offline run."""
    sessions, kinds = seed1
    offline = _offline(offline_runs, seed1, 30.0, mode)
    mt = _restored_half_way(sessions, kinds, offline[0].params)
    assert mt.params == offline[0].params and mt.bridge is not None
    _same_as_offline(offline, mt)


def _fed_back_now(mt: MissionTracker) -> bool:
    """The last window ended in a smoother solve that set a rescuer's latest row."""
    st = mt.smoother
    if st is None or not st.last_solve_s == mt.horizon_s > -math.inf:
        return False
    if mt.params.smoother is None or mt.params.smoother.feedback == "off":
        return True
    for name in sorted(mt.started & set(st.tail)):
        c = mt.trackers[name].corrections_since(0)
        if len(c) and c.kind[-1] == SMOOTHED and c.t[-1] == st.tail[name][0]:
            return True
    return False


@pytest.mark.parametrize(("smooth_s", "mode"), [(0.0, "nodes"), (0.0, "feedback"),
                                                (30.0, "nodes"), (30.0, "feedback")])
def test_restored_right_after_a_smoother_solve_the_mission_continues_identically(  # type: ignore[no-untyped-def]
        seed1, offline_runs, smooth_s: float, mode: str) -> None:
    """A snapshot taken just after a solve (with ``feedback``: one that set a rescuer's latest
    row, which the bridge and the smoother read again later), the first after the half-way
    point (the half-way test's restore point is another)."""
    sessions, kinds = seed1
    offline = _offline(offline_runs, seed1, smooth_s, mode)
    parts = _parts(sessions)
    mt = MissionTracker(_headers(sessions), kinds=kinds, params=offline[0].params)
    restored = False
    for j, (name, part) in enumerate(parts):
        if not restored and 2 * j > len(parts) and _fed_back_now(mt):
            mt, restored = MissionTracker.restore(mt.snapshot()), True
        mt.feed(name, part, now_s=float(j))
        mt.advance(now_s=float(j))
    assert restored
    for k in sessions:
        mt.end(k)
    _same_as_offline(offline, mt)
