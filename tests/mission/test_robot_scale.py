"""The robot's odometry scale error as a state (``RobotTrackerParams.odometry_scale_sigma``)."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.mission.robot import RobotTracker, RobotTrackerParams, robot_kernel
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

NO_RANGES = (np.zeros(0), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0))


def test_a_displacement_with_the_scale_state_by_hand() -> None:
    """psi = 0, k = 0, d = (1, 0), f = 0.03, q = 1e-4 per m: F = I + e_y e_psi^T + e_x e_k^T,
    so P_xx = 0.01 + 1e-4 (the scale) + 0.0009, P_xk = 1e-4, the rest as without the scale."""
    x = np.zeros(4)
    p = np.diag([0.01, 0.01, 0.0004, 1e-4])
    xs, ps, _, _ = robot_kernel(x, p, np.array([[1.0, 0.0]]), np.array([1.0]), *NO_RANGES,
                                0.03, 1e-4, 4.0)
    np.testing.assert_allclose(xs[0], [1.0, 0.0, 0.0, 0.0])
    want = np.array([[0.011, 0, 0, 1e-4], [0, 0.0113, 0.0004, 0], [0, 0.0004, 0.0005, 0],
                     [1e-4, 0, 0, 1e-4]])
    np.testing.assert_allclose(ps[0], want, atol=1e-9)


def test_a_scale_error_is_carried_in_the_prediction() -> None:
    """k = 0.02: the displacement is taken 2 % longer."""
    x = np.array([0.0, 0.0, 0.0, 0.02])
    robot_kernel(x, np.eye(4) * 1e-4, np.array([[10.0, 0.0]]), np.array([1.0]), *NO_RANGES,
                 0.03, 1e-4, 4.0)
    np.testing.assert_allclose(x, [10.2, 0.0, 0.0, 0.02])


def test_the_scale_sigma_is_checked() -> None:
    with pytest.raises(InputError, match="odometry_scale_sigma"):
        RobotTrackerParams(odometry_scale_sigma=-0.01)
    assert RobotTrackerParams().odometry_scale_sigma == 0.0


def _robot_nees(seed: int, params: RobotTrackerParams) -> tuple[np.ndarray, float]:
    """The robot of the hybrid mission alone (odometry only): its positions and mean NEES at
    1 Hz against the truth."""
    m = inderst_hybrid_mission(seed, MissionOptions())
    name = next(n for n, k in m.kinds.items() if k == "robot")
    truth = m.simulations[name].session.truth
    assert truth is not None
    tr = RobotTracker(params)
    tr.start_session(m.agents[name])
    tr.update(m.agents[name])
    est = tr.estimates_since()
    tq = np.arange(float(est.t[0]), float(est.t[-1]), 1.0)
    d = np.column_stack([np.interp(tq, est.t, est.xyz[:, k]) - np.interp(tq, truth.t,
                                                                       truth.xyz[:, k])
                         for k in (0, 1)])
    j = np.clip(np.searchsorted(est.t, tq), 0, len(est.t) - 1)
    nees = np.einsum("ki,kij,kj->k", d, np.linalg.inv(est.cov_xy[j]), d)
    return est.xyz, float(np.mean(nees))


def test_seeded_the_scale_state_brings_the_robots_nees_tail_in() -> None:
    """Seed 8 (development): the simulated wheels' scale error (one per run) is not white; the
    robot alone is over-confident without the state (mean NEES 7.3), inside with it (0.9), on
    the same positions (no range: ``k`` stays 0)."""
    xy0, nees0 = _robot_nees(8, RobotTrackerParams())
    xy1, nees1 = _robot_nees(8, RobotTrackerParams(odometry_scale_sigma=0.01))
    np.testing.assert_array_equal(xy0, xy1)
    assert nees0 > 5.0
    assert nees1 < 2.0
