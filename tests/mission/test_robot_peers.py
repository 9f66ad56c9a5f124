"""A robot's range to a peer by covariance intersection (``PeerRangeParams.rule``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.mission.peers import PeerRangeParams
from hrtls.mission.robot import RobotTracker, intersect_weight, robot_kernel
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission

NO_ODO = (np.zeros((0, 2)), np.zeros(0))


def _one_range(x: np.ndarray, p: np.ndarray, lm: tuple[float, float], r: float, s: float,
               v: float) -> bool:
    """One range update of ``(x, p)`` in place (no odometry); accepted or not."""
    _, _, acc, _ = robot_kernel(x, p, *NO_ODO, np.array([0.5]), np.array([lm]), np.array([r]),
                                np.array([s]), np.array([v]), 0.03, 1e-4, 4.0)
    return bool(acc[0])


def test_covariance_intersection_by_hand() -> None:
    """P = diag(4, 0.01, 0.1), peer at (10, 0) with v = 1, s = 0, range 9 (innovation -1).

    det(P+) / det(P) = w^-3 R_w / S_w = 1 / (w^2 (4 - 3 w)), least at w = 8/9; on the grid
    k / 50: 0.88 (0.9495) before 0.90 (0.9497). P_w = P / 0.88, R_w = 1 / 0.12, K_x = -(4 / 0.88)
    / (4 / 0.88 + 1 / 0.12) = -6 / 17, x = 6 / 17, P_xx = (4 / 0.88) (1 / 0.12) / (4 / 0.88 +
    1 / 0.12) = 50 / 17; the other axes only inflated by 1 / w.
    """
    p = np.diag([4.0, 0.01, 0.1])
    assert intersect_weight(p, np.array([-1.0, 0.0, 0.0]), 0.0, 1.0) == pytest.approx(0.88)
    x = np.zeros(3)
    assert _one_range(x, p, (10.0, 0.0), 9.0, 0.0, 1.0)
    np.testing.assert_allclose(x, [6 / 17, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p, np.diag([50 / 17, 0.01 / 0.88, 0.1 / 0.88]), atol=1e-12)


def test_a_peer_no_better_than_the_robot_gives_no_update() -> None:
    """Equal variances along the line of sight and no range noise: no ``w`` < 1 lowers det."""
    p = np.diag([1.0, 1.0, 0.1])
    assert intersect_weight(p, np.array([1.0, 0.0, 0.0]), 0.0, 1.0) == 1.0
    x = np.zeros(3)
    assert _one_range(x, p, (-10.0, 0.0), 10.5, 0.0, 1.0)
    np.testing.assert_array_equal(x, np.zeros(3))
    np.testing.assert_array_equal(p, np.diag([1.0, 1.0, 0.1]))


def _true_mse(p: np.ndarray, k: np.ndarray, h: np.ndarray, noise: float, c: np.ndarray
              ) -> np.ndarray:
    """Covariance of ``e+ = (I - K h^T) e + K (n + z)``: ``cov(e) = P``, ``var(n + z) =
    noise``, ``cov(e, z) = c``."""
    a = np.eye(3) - np.outer(k, h)
    return a @ p @ a.T + np.outer(k, k) * noise + a @ np.outer(c, k) + np.outer(k, c) @ a.T


def _update(p: np.ndarray, s: float, v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robot at the origin, the peer 10 m away along x, innovation 0.1 m: ``(P+, K, h)``."""
    x, pp = np.zeros(3), p.copy()
    assert _one_range(x, pp, (-10.0, 0.0), 10.1, s, v)
    return pp, x / 0.1, np.array([1.0, 0.0, 0.0])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=9, max_size=9),
       st.floats(0.01, 10.0), st.floats(0.01, 2.0), st.floats(-1.0, 1.0),
       st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))
def test_the_intersection_is_consistent_for_any_correlation_with_the_peer(
        a: list[float], v: float, s: float, rho: float, g: list[float]) -> None:
    """Whatever the correlation of the peer's error ``z`` (variance ``v`` along the line of
    sight) with the robot's state error (``cov(e, z) = rho sqrt(v) L g``, ``P = L L^T``, ``g`` a
    unit vector: every valid cross-covariance), the robot's claimed ``P+`` is at least the
    true covariance after the update."""
    gv = np.asarray(g)
    norm = float(np.linalg.norm(gv))
    if norm < 1e-3:
        return
    la = np.asarray(a).reshape(3, 3)
    p = la @ la.T + 0.01 * np.eye(3)
    pp, k, h = _update(p, s, v)
    c = rho * math.sqrt(v) * np.linalg.cholesky(p) @ (gv / norm)
    gap = pp - _true_mse(p, k, h, s * s + v, c)
    assert np.linalg.eigvalsh(gap).min() >= -1e-9 * max(1.0, float(np.trace(p)))


def test_the_plain_update_is_not_consistent_for_a_correlated_peer() -> None:
    """The check above can fail: the peer taken as independent (its variance added to the
    range's), its error fully correlated with the robot's along the line of sight."""
    p = np.diag([1.0, 1.0, 0.1])
    pp, k, h = _update(p, math.sqrt(0.01 + 1.0), math.nan)
    c = np.array([1.0, 0.0, 0.0])                   # rho = 1, g = h: cov(e, z) = sqrt(v P_xx)
    gap = pp - _true_mse(p, k, h, 0.01 + 1.0, c)
    assert np.linalg.eigvalsh(gap).min() < -0.1


def test_peers_survive_the_trackers_state() -> None:
    tr = RobotTracker()
    tr.peers = {"R1": (1.0, 2.0, 0.5)}
    tr.landmarks = {}
    tr._rows = []
    for k, val in (("x", np.zeros(3)), ("p", np.eye(3)), ("_last_odo", np.zeros(2)),
                   ("_last_t", 0.0), ("_accepted", 0), ("_rejected", 0), ("_started", True)):
        setattr(tr, k, val)
    back = RobotTracker.from_state(tr.state())
    assert back.peers == {"R1": (1.0, 2.0, 0.5)}


def test_the_rule_is_checked() -> None:
    with pytest.raises(InputError, match="rule"):
        PeerRangeParams(rule="ci")
    assert PeerRangeParams().rule == "intersect" and not PeerRangeParams().factors_only


def _robot_nees_with_peers(rule: str) -> float:
    """Mean NEES at 1 Hz of the robot of a short seeded mission with inter-agent ranges (the
    default ``feedback`` mode, seed 0: 90 s walks, 15 nodes), truth for scoring only."""
    m = inderst_hybrid_mission(0, MissionOptions(walk_s=90.0, stagger_s=10.0, n_nodes=15,
                                                 n_robots=1, peer_ranges=True))
    robot = next(n for n, k in m.kinds.items() if k == "robot")
    truth = m.simulations[robot].session.truth
    assert truth is not None
    res = MissionTracker(m.agents, kinds=m.kinds,
                         params=MissionParams(peer_ranges=PeerRangeParams(rule=rule))).run()
    tr = res.agents[robot].trajectory
    tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
    d = np.column_stack([np.interp(tq, tr.t, tr.xyz[:, k]) - np.interp(tq, truth.t,
                                                                     truth.xyz[:, k])
                         for k in (0, 1)])
    j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
    return float(np.mean(np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d)))


def test_seeded_the_robots_nees_with_peer_ranges_stays_inside() -> None:
    """Seed 0 of the short mission: the widening made the robot over-confident (mean NEES
    3.99), the intersection does not (1.73; expected 2)."""
    assert _robot_nees_with_peers("widen") > 3.0
    assert _robot_nees_with_peers("intersect") < 2.5
