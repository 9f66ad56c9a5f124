"""The smoother's feedback to the rescuers (hrtls.mission.feedback): hand-made cases, an
invariant, the mission loop."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.mission.feedback import implied_update, nis, position_update, replacement
from hrtls.mission.graph import SmootherParams
from hrtls.mission.smoothing import via_feedback
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline.corrections import SMOOTHED
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

from ._live import restored_half_way, short_mission

# tracker: position (0, 0), covariance diag(4, 1), heading correlated with x (0.5)
X = np.array([0.0, 0.0, 1.5, 0.2])
P = np.array([[4.0, 0.0, 0.0, 0.5],
              [0.0, 1.0, 0.0, 0.0],
              [0.0, 0.0, 0.3, 0.0],
              [0.5, 0.0, 0.0, 0.2]])
M_S = np.array([1.0, -0.5])
P_S = np.diag([1.0, 0.5])


def test_the_implied_update_reproduces_the_smoothers_marginal_by_hand() -> None:
    """R^-1 = diag(1 - 1/4, 2 - 1) = diag(0.75, 1); R^-1 z = P_s^-1 m_s = (1, -1), so
    z = (4/3, -1). The heading moves by P_hp P_pp^-1 (m_s - m_f) = 0.5 / 4 = 0.125 and its
    variance falls by P_hp P_f^-1 (P_f - P_s) P_f^-1 P_ph = 0.25 * 3 / 16."""
    z, w = implied_update(X[:2], P[:2, :2], M_S, P_S)
    np.testing.assert_allclose(w.T @ w, np.diag([0.75, 1.0]), atol=1e-12)
    np.testing.assert_allclose(z, [4.0 / 3.0, -1.0], atol=1e-12)
    x, p = position_update(X, P, z, w)
    np.testing.assert_allclose(x[:2], M_S, atol=1e-12)
    np.testing.assert_allclose(p[:2, :2], P_S, atol=1e-12)
    np.testing.assert_allclose(x[3], 0.2 + 0.125, atol=1e-12)
    np.testing.assert_allclose(p[3, 3], 0.2 - 0.25 * 3.0 / 16.0, atol=1e-12)
    assert x[2] == X[2] and p[2, 2] == P[2, 2]


def test_the_nis_of_the_implied_measurement_by_hand() -> None:
    """W = I, P_f = I, z - m_f = (2, 0): S = 2 I, NIS = 4 / 2."""
    assert nis(np.zeros(2), np.eye(2), np.array([2.0, 0.0]), np.eye(2)) == 2.0


def test_the_replacement_by_hand() -> None:
    """A = L_s L_f^-1 = diag(1/2, 1/sqrt(2)): the cross-covariance x-heading halves, the
    heading and its variance stay."""
    x, p = replacement(X, P, M_S, P_S)
    np.testing.assert_allclose(x, [1.0, -0.5, 1.5, 0.2])
    np.testing.assert_allclose(p[:2, :2], P_S, atol=1e-12)
    np.testing.assert_allclose(p[0, 3], 0.25, atol=1e-12)
    np.testing.assert_allclose(p[2:, 2:], P[2:, 2:], atol=1e-12)


def _spd(n: int, seed: int, scale: float) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(n, n)) * scale
    return a @ a.T + 1e-3 * np.eye(n)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), scale=st.floats(0.1, 3.0))
def test_the_implied_update_never_increases_the_covariance(seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed + 1)
    p = _spd(4, seed, 1.0)
    p_s = _spd(2, seed + 7, scale)
    z, w = implied_update(rng.normal(size=2), p[:2, :2], rng.normal(size=2), p_s)
    x, pn = position_update(rng.normal(size=4), p, z, w)
    assert np.all(np.isfinite(x))
    assert np.linalg.eigvalsh(p - pn)[0] > -1e-9 * max(1.0, float(np.max(np.abs(p))))
    assert np.linalg.eigvalsh(pn)[0] > -1e-9


def test_a_robot_takes_the_implied_update_on_its_odometry_frame_heading_by_hand() -> None:
    """Robot state [x, y, psi], P = [[1, 0, 0.1], [0, 1, 0], [0.1, 0, 0.04]], row at the
    state; smoother N((0.5, 0), 0.5 I): the position marginal becomes it, psi moves by
    0.1 * 0.5 = 0.05, its variance falls by 0.1 * 0.5 * 0.1 = 0.005. The robot records the
    jump as a SMOOTHED correction and its latest row takes the new state."""
    from hrtls.mission.feedback import feed_back
    from hrtls.mission.graph import SmootherResult
    from hrtls.mission.robot import RobotTracker
    from hrtls.mission.smoothing import SmootherState

    tr = RobotTracker()
    x0, p0 = np.zeros(3), np.array([[1.0, 0.0, 0.1], [0.0, 1.0, 0.0], [0.1, 0.0, 0.04]])
    tr.load_state({"robot": {"x": x0, "p": p0, "_last_odo": np.zeros(2), "_last_t": 5.0,
                             "_accepted": 0, "_rejected": 0, "_started": True},
                   "landmarks": {}, "rows": [np.array([5.0]), x0[None], p0[None]]})
    prm = SmootherParams(feedback="implied", feedback_cov_scale=1.0, robots="feedback")
    res = SmootherResult({}, {}, {}, {}, {}, 0.0, 1.0, 1,
                         last_pose={"B1": (5.0, np.array([0.5, 0.0]), 0.5 * np.eye(2))})
    mt = SimpleNamespace(params=MissionParams(smoother=prm), trackers={"B1": tr},
                         smoother=SmootherState(tail={"B1": [5.0, 0.0, 0.0, 1.0, 0.0, 0.0,
                                                             1.0]}))
    assert feed_back(mt, res) == ["B1"]         # type: ignore[arg-type]
    np.testing.assert_allclose(tr.x, [0.5, 0.0, 0.05], atol=1e-12)
    np.testing.assert_allclose(tr.p[:2, :2], 0.5 * np.eye(2), atol=1e-12)
    np.testing.assert_allclose(tr.p[2, 2], 0.04 - 0.005, atol=1e-12)
    est = tr.estimates_since(4.0)
    np.testing.assert_allclose(est.xyz[0, :2], [0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(est.heading_rad[0], 0.05, atol=1e-12)
    c = tr.corrections_since(0)
    assert list(c.kind) == [SMOOTHED] and c.t[0] == 5.0
    np.testing.assert_allclose(c.mean1_m[0] - c.mean0_m[0], [0.5, 0.0], atol=1e-12)
    for robots in ("nodes", "alone"):           # a robot keeps its own estimate
        mt.params = MissionParams(smoother=replace(prm, robots=robots))
        assert feed_back(mt, res) == []         # type: ignore[arg-type]


def test_robot_feedback_needs_the_feedback() -> None:
    from hrtls.errors import InputError

    with pytest.raises(InputError, match="robots = 'feedback' without feedback"):
        SmootherParams(robots="feedback")
    with pytest.raises(InputError, match="robots"):
        SmootherParams(robots="some")


@pytest.mark.parametrize(("mode", "robots", "ranges"), [
    ("implied", False, "both"), ("replace", False, "both"), ("implied", True, "both"),
    ("implied", False, "smoother")])
def test_the_loop_with_feedback_restores_and_runs_live_like_offline(mode: str, robots: bool,
                                                                    ranges: str) -> None:
    params = MissionParams(smoother=SmootherParams(every_s=10.0, feedback=mode,
                                                   robots="feedback" if robots else "nodes",
                                                   feedback_ranges=ranges))
    sessions, kinds = short_mission(2)
    offline = MissionTracker(sessions, kinds=kinds, params=params)
    want = offline.run()
    fed = [n for n, tr in offline.trackers.items()
           if np.any(tr.corrections_since(0).kind == SMOOTHED)]
    assert fed
    assert any(kinds[n] == "robot" for n in fed) == robots
    mt = restored_half_way(sessions, kinds, params)
    got = mt.run()
    for n, e in want.nodes.items():
        assert got.nodes[n].localized == e.localized
        if e.localized:
            np.testing.assert_array_equal(got.nodes[n].position_m, e.position_m)
    for name, r in want.agents.items():     # a restored rescuer: its rows after the restore
        g = got.agents[name].trajectory
        assert 0 < len(g.t) <= len(r.trajectory.t)
        np.testing.assert_array_equal(g.xyz, r.trajectory.xyz[-len(g.t):])
        np.testing.assert_array_equal(g.cov_xy, r.trajectory.cov_xy[-len(g.t):])


def test_who_takes_a_fed_back_rescuers_ranges_to_the_smoothers_nodes() -> None:
    """``feedback_ranges="smoother"``: a rescuer takes no range to a node the smoother owns; a
    robot (not fed back) does, as every agent with ``"both"`` or without feedback."""
    sessions, kinds = short_mission(2)
    rescuer = next(k for k, v in kinds.items() if v == "rescuer")
    robot = next(k for k, v in kinds.items() if v == "robot")

    def kept_out(name: str, node: str, **kw: object) -> bool:
        mt = MissionTracker(sessions, kinds=kinds, params=MissionParams(
            smoother=SmootherParams(**kw)))     # type: ignore[arg-type]
        assert mt.smoother is not None
        mt.smoother.owned.add("n1")
        return via_feedback(mt, mt.names.index(name), node)

    fed = {"feedback": "implied", "feedback_ranges": "smoother"}
    assert kept_out(rescuer, "n1", **fed)
    assert not kept_out(rescuer, "n2", **fed)            # not the smoother's node
    assert not kept_out(robot, "n1", **fed)
    assert not kept_out(rescuer, "n1", feedback="implied", feedback_ranges="both")
    assert not kept_out(rescuer, "n1", feedback="off", feedback_ranges="smoother")
    with pytest.raises(InputError, match="feedback_ranges"):
        SmootherParams(feedback_ranges="tracker")


def _rescuer_p90(seed: int, smoother: SmootherParams | None, kind: str = "rescuer", *,
                 cooperate: bool = True) -> float:
    """The benchmark's rescuers (benchmarks/mission.py defaults), 2 % range noise: the
    90th-percentile horizontal error at 1 Hz of the agents of ``kind``, m."""
    from hrtls.pipeline import preset
    from hrtls.pipeline.config import TrackerConfig

    r = preset("rescue-mission")
    cfg = TrackerConfig.model_validate({
        "prediction": {"q_along": r.prediction.q_along,
                       "sigma_heading_increment_rad": r.prediction.sigma_heading_increment_rad},
        "attitude": {"heading_source": "gyro+compass",
                     "mag_heading": {"offset_model": r.attitude.mag_heading["offset_model"]}},
        "tags": {"sigma_per_accuracy": r.tags.sigma_per_accuracy}})
    m = inderst_hybrid_mission(seed, MissionOptions(range_sigma_fraction=0.02))
    res = MissionTracker(m.agents, kinds=m.kinds, config=cfg,
                         params=MissionParams(smoother=smoother, cooperate=cooperate)).run()
    errs = []
    for name, a in res.agents.items():
        if m.kinds.get(name, "rescuer") != kind:
            continue
        truth = m.simulations[name].session.truth
        assert truth is not None
        tr = a.trajectory
        tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
        errs.append(np.hypot(*(np.interp(tq, tr.t, tr.xyz[:, k])
                               - np.interp(tq, truth.t, truth.xyz[:, k]) for k in (0, 1))))
    return float(np.percentile(np.concatenate(errs), 90))


def test_on_a_dev_mission_the_feedback_lowers_the_rescuers_p90() -> None:
    """Seeded regression (dev seed 4, cooperation on, 2 % range noise): the rescuers' p90 error
    with the implied feedback every 10 s below 2.8 m; the smoother without it gives 3.09 m
    (cooperation off 3.55 m; benchmarks/mission.py at 38b661f)."""
    p90 = _rescuer_p90(4, SmootherParams(every_s=10.0, feedback="implied"))
    assert p90 < 2.8



def test_on_a_short_dev_mission_the_robot_with_feedback_is_no_worse_than_alone() -> None:
    """Seeded regression (dev seed 0, 60 s walks, 15 nodes, 2 % range noise): with the mode
    ``feedback`` the robot's track equals its own alone (cooperation off; tolerance 0: it
    takes nothing from the mission, ``robots = "alone"``), while its ranges still reach the
    smoother; with the nodes as range anchors (``robots = "nodes"``, the mode before) it
    differs."""
    from hrtls.mission.smoother_modes import smoother_params

    m = inderst_hybrid_mission(0, MissionOptions(walk_s=60.0, stagger_s=15.0, n_nodes=15,
                                                 range_sigma_fraction=0.02))
    robot = next(n for n, k in m.kinds.items() if k == "robot")
    fb = smoother_params("feedback")
    assert fb is not None
    tracks = {}
    for key, prm in (("off", MissionParams(cooperate=False)),
                     ("alone", MissionParams(smoother=fb)),
                     ("nodes", MissionParams(smoother=replace(fb, robots="nodes")))):
        tracks[key] = MissionTracker(m.agents, kinds=m.kinds, params=prm).run(
            ).agents[robot].trajectory
    np.testing.assert_array_equal(tracks["alone"].xyz, tracks["off"].xyz)
    np.testing.assert_array_equal(tracks["alone"].cov_xy, tracks["off"].cov_xy)
    assert not np.array_equal(tracks["nodes"].xyz, tracks["off"].xyz)
