import math

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.wsn.agents import (
    Landmarks,
    MobileAgent,
    RangeWorld,
    RescuerAgent,
    RescuerParams,
    RobotAgent,
    RobotParams,
    range_update,
    robot_leg_reference,
)

NODES = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 0.5]])


def _world(noise: float = 0.0) -> RangeWorld:
    return RangeWorld(true_positions_m=NODES, link_radius_m=0.6, radio_range_m=1.2,
                      range_noise_fraction=noise, rng=np.random.default_rng(0))


def test_agents_implement_the_protocol():
    w = _world()
    robot = RobotAgent(w, np.array([0.2, 0.2, 0.0]), params=RobotParams())
    rescuer = RescuerAgent(w, np.array([0.2, 0.2]), params=RescuerParams(),
                           rng=np.random.default_rng(0))
    agents: list[MobileAgent] = [robot, rescuer]
    for a in agents:
        est, cov = a.estimate()
        assert est.shape == (2,) and cov.shape == (2, 2)


def test_scan_links_and_ranges():
    sc = _world().scan_at(np.array([0.1, 0.0]))
    assert sc.node.tolist() == [0, 1, 2, 4]
    assert np.allclose(sc.range_m[:2], [0.1, 0.9])
    assert sc.linked.tolist() == [True, False, False, False]
    with pytest.raises(InputError):
        RangeWorld(true_positions_m=NODES, link_radius_m=2.0, radio_range_m=1.0)


@pytest.mark.parametrize("target", [(0.8, 0.6), (-0.5, 0.3), (0.2, -0.7)])
@pytest.mark.parametrize("heading", [0.0, 2.5, -1.7])
def test_robot_kernel_matches_reference_noise_free(target, heading):
    prm = RobotParams(arrival_radius_m=0.003)
    start = np.array([0.1, 0.2, heading])
    robot = RobotAgent(_world(), start, params=prm)
    leg = robot.go_to(np.array(target), Landmarks(node=np.zeros(0, np.int64),
                                                  position_m=np.zeros((0, 2))))
    ref, length = robot_leg_reference(start, np.array(target), prm)
    assert leg.reached
    assert leg.path_true_m.shape == ref.shape
    assert np.allclose(leg.path_true_m, ref, atol=1e-12)
    assert math.isclose(leg.length_m, length, rel_tol=1e-12)
    assert np.linalg.norm(leg.true_m - np.array(target)) <= prm.arrival_radius_m
    # no noise: the estimate is the truth
    assert np.allclose(leg.estimate_m, leg.true_m)


def test_controller_obeys_saturations():
    prm = RobotParams(max_speed_m_s=0.1, arrival_radius_m=0.002)
    robot = RobotAgent(_world(), np.array([0.0, 0.0, math.pi]), params=prm)
    leg = robot.go_to(np.array([0.5, 0.0]), Landmarks(node=np.zeros(0, np.int64),
                                                      position_m=np.zeros((0, 2))))
    steps = np.linalg.norm(np.diff(leg.path_true_m, axis=0), axis=1)
    assert steps.max() <= prm.max_speed_m_s * prm.dt_s + 1e-12


def test_range_ekf_bounds_odometry_drift():
    prm = RobotParams(speed_noise_fraction=0.05, turn_rate_noise_rad_s=0.3,
                      range_noise_fraction=0.01, arrival_radius_m=0.005)
    targets = [np.array(t) for t in [(0.9, 0.1), (0.9, 0.9), (0.1, 0.9), (0.1, 0.1)] * 3]
    errs = {}
    for use in (False, True):
        e = []
        for seed in range(5):
            robot = RobotAgent(_world(0.01), np.array([0.1, 0.1, 0.0]), params=prm,
                               start_sigma_m=0.0, seed=seed)
            lm = Landmarks(node=np.arange(5) if use else np.zeros(0, np.int64),
                           position_m=NODES if use else np.zeros((0, 2)))
            for t in targets:
                leg = robot.go_to(t, lm)
                e.append(np.linalg.norm(leg.estimate_m - leg.true_m))
                est, cov = robot.estimate()
                assert np.all(np.isfinite(est)) and np.all(np.linalg.eigvalsh(cov) >= -1e-15)
        errs[use] = float(np.mean(e))
    assert errs[True] < 0.5 * errs[False]
    assert errs[True] < 0.03


def test_range_update_hand_case():
    # one range along x from a landmark at the origin: only x is corrected
    x = np.array([1.0, 0.0])
    p = np.eye(2) * 0.04
    x1, p1, used = range_update(x, p, np.array([[0.0, 0.0]]), np.array([1.1]), np.array([0.2]))
    assert used == 1
    k = 0.04 / (0.04 + 0.04)
    assert np.allclose(x1, [1.0 + k * 0.1, 0.0])
    assert np.isclose(p1[0, 0], (1 - k) * 0.04)
    assert np.isclose(p1[1, 1], 0.04)
    # gated outlier
    _, _, used = range_update(x, p, np.array([[0.0, 0.0]]), np.array([5.0]), np.array([0.2]))
    assert used == 0


def test_rescuer_reaches_targets_exactly_without_noise():
    a = RescuerAgent(_world(), np.array([0.0, 0.0]), params=RescuerParams(step_length_m=0.07),
                     rng=np.random.default_rng(1))
    leg = a.go_to(np.array([0.33, -0.41]), Landmarks(node=np.zeros(0, np.int64),
                                                     position_m=np.zeros((0, 2))))
    assert leg.reached
    assert np.allclose(leg.true_m, [0.33, -0.41]) and np.allclose(leg.estimate_m, leg.true_m)
    assert math.isclose(leg.length_m, math.hypot(0.33, 0.41), rel_tol=1e-12)


def test_rescuer_drift_is_corrected_by_ranges():
    prm = RescuerParams(step_length_m=0.02, heading_noise_rad=0.02,
                        step_length_noise_fraction=0.05, correct_every_steps=5,
                        range_noise_fraction=0.01)
    errs = {}
    for use in (False, True):
        a = RescuerAgent(_world(0.01), np.array([0.1, 0.1]), params=prm,
                         rng=np.random.default_rng(3))
        a.cov = np.eye(2) * 1e-4
        lm = Landmarks(node=np.arange(5) if use else np.zeros(0, np.int64),
                       position_m=NODES if use else np.zeros((0, 2)))
        e = []
        for t in [(0.9, 0.1), (0.9, 0.9), (0.1, 0.9), (0.1, 0.1)] * 2:
            leg = a.go_to(np.array(t), lm)
            e.append(np.linalg.norm(leg.estimate_m - leg.true_m))
        errs[use] = float(np.mean(e))
    assert errs[True] < errs[False]


def test_robot_state_round_trip_reproduces_the_leg():
    import json

    from hrtls.wsn.agents import RobotState

    prm = RobotParams(speed_noise_fraction=0.05, turn_rate_noise_rad_s=0.2,
                      range_noise_fraction=0.01)
    lm = Landmarks(node=np.arange(5), position_m=NODES)
    robot = RobotAgent(_world(), np.array([0.1, 0.1, 0.0]), params=prm, seed=4)
    robot.go_to(np.array([0.8, 0.2]), lm)
    snap = RobotState.from_dict(json.loads(json.dumps(robot.state().to_dict())))
    a = robot.go_to(np.array([0.5, 0.9]), lm)
    robot.restore(snap)
    b = robot.go_to(np.array([0.5, 0.9]), lm)
    assert np.allclose(a.path_true_m, b.path_true_m) and np.allclose(a.estimate_m, b.estimate_m)
    with pytest.raises(InputError):
        RobotState.from_dict({"true_pose": [0, 0, 0]})
