"""RobotTracker: hand-computed prediction and range update, chunking, robots in a mission."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.errors import InputError
from hrtls.io.tables import read_trajectory
from hrtls.mission.robot import RobotTracker, RobotTrackerParams, robot_kernel
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline.chunks import session_window
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission, write_mission_result

OPTIONS = MissionOptions(walk_s=60.0, stagger_s=10.0, n_nodes=10, n_robots=1)


@pytest.fixture(scope="module")
def mission():  # type: ignore[no-untyped-def]
    return inderst_hybrid_mission(2, OPTIONS)


def _empty_ranges() -> tuple[np.ndarray, ...]:
    return np.zeros(0), np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0)


def test_two_straight_displacements_by_hand() -> None:
    """psi = 0, d = (1, 0) twice, f = 0.03, q = 1e-4 per m (values worked out in the comments)."""
    x = np.zeros(3)
    p = np.diag([0.01, 0.01, 0.0004])
    xs, ps, _, _ = robot_kernel(x, p, np.array([[1.0, 0.0], [1.0, 0.0]]), np.array([1.0, 2.0]),
                             *_empty_ranges(), 0.03, 1e-4, 4.0)
    np.testing.assert_allclose(xs[-1], [2.0, 0.0, 0.0])
    # F = [[1, 0, 0], [0, 1, 1], [0, 0, 1]]; Q = diag(0.0009, 0.0009, 0.0001)
    p1 = np.array([[0.0109, 0, 0], [0, 0.0113, 0.0004], [0, 0.0004, 0.0005]])
    p2 = np.array([[0.0118, 0, 0], [0, 0.0135, 0.0009], [0, 0.0009, 0.0006]])
    np.testing.assert_allclose(ps[0], p1, atol=1e-9)
    np.testing.assert_allclose(ps[1], p2, atol=1e-9)
    np.testing.assert_allclose(p, p2, atol=1e-9)


def test_range_update_by_hand_and_gate() -> None:
    """P = diag(1, 1, 0.1), landmark (10, 0), range 9, sigma 1: K = (-0.5, 0, 0), x = (0.5, 0),
    P_xx = 0.5; a range of 100 fails the 4-sigma gate."""
    x = np.zeros(3)
    p = np.diag([1.0, 1.0, 0.1])
    _, _, acc, _ = robot_kernel(x, p, np.zeros((0, 2)), np.zeros(0), np.array([0.5, 0.6]),
                             np.array([[10.0, 0.0], [10.0, 0.0]]), np.array([9.0, 100.0]),
                             np.array([1.0, 1.0]), np.full(2, np.nan), 0.03, 1e-4, 4.0)
    np.testing.assert_array_equal(acc, [True, False])
    np.testing.assert_allclose(x, [0.5, 0.0, 0.0])
    np.testing.assert_allclose(p, np.diag([0.5, 1.0, 0.1]), atol=1e-12)


@pytest.mark.parametrize("chunk_s", [2.0, 7.5])
def test_rows_do_not_depend_on_the_chunking(mission, chunk_s: float) -> None:  # type: ignore[no-untyped-def]
    s = mission.agents["B1"]
    whole = RobotTracker()
    whole.start_session(s)
    whole.update(s)
    chunked = RobotTracker()
    chunked.start_session(s)
    t0, t1 = s.time_span()
    k = 0
    while t0 + k * chunk_s <= t1:
        part = session_window(s, t0 + k * chunk_s, t0 + (k + 1) * chunk_s)
        if part is not None:
            chunked.update(part)
        k += 1
    a, b = whole.estimates_since(), chunked.estimates_since()
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_allclose(a.xyz, b.xyz, atol=1e-12)
    np.testing.assert_allclose(a.cov_xy, b.cov_xy, atol=1e-12)


def test_robot_is_a_mission_agent(mission) -> None:  # type: ignore[no-untyped-def]
    assert mission.kinds["B1"] == "robot" and mission.agents["B1"].imu is None
    for coop in (False, True):
        res = MissionTracker(mission.agents, params=MissionParams(cooperate=coop),
                             kinds=mission.kinds).run()
        tr, truth = res.agents["B1"].trajectory, mission.simulations["B1"].session.truth
        err = np.hypot(*(tr.xyz[:, :2] - np.column_stack(
            [np.interp(tr.t, truth.t, truth.xyz[:, i]) for i in (0, 1)])).T)
        assert np.percentile(err, 90) < 2.0, (coop, np.percentile(err, 90))
        assert any("B1" in who for who in res.contributors.values())
        if not coop:
            assert res.agents["B1"].report["corrections"]["range"]["accepted"] == 0
        cov = tr.cov_xy
        assert np.all(np.linalg.eigvalsh(cov)[:, 0] > 0)


def test_robot_mission_folder_offline_equals_in_memory(mission, tmp_path: Path
                                                        ) -> None:  # type: ignore[no-untyped-def]
    root = write_mission_result(mission, tmp_path / "m")
    assert json.loads((root / "mission.json").read_text())["agents"][-1]["kind"] == "robot"
    res = CliRunner().invoke(app, ["mission", "track", str(root), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    want = MissionTracker(mission.agents, kinds=mission.kinds).run().agents["B1"].trajectory
    got = read_trajectory(tmp_path / "out" / "agents" / "B1" / "trajectory.csv")
    np.testing.assert_allclose(got.xyz, want.xyz, atol=1e-6)


def test_bad_params_are_refused() -> None:
    with pytest.raises(InputError, match="odometry_fraction"):
        RobotTrackerParams(odometry_fraction=0.0)
