"""A robot's live tracker starts on its first odometry poses and gives the offline rows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.live import START_WITHOUT_IMU_S, ready_to_start
from hrtls.service.batches import parse_batch
from hrtls.service.client import session_batches
from hrtls.service.runner import AgentSpec, InProcessRunner, Rows
from hrtls.sim.team import TeamMember, team_mission


def test_start_rule_by_hand() -> None:
    assert ready_to_start(accel_samples=0, span_s=0.5, robot_poses=2)
    assert not ready_to_start(accel_samples=0, span_s=0.5, robot_poses=1)
    assert not ready_to_start(accel_samples=10, span_s=0.5, robot_poses=5)  # an IMU joins
    assert not ready_to_start(accel_samples=0, span_s=0.5)                  # not a robot
    assert ready_to_start(accel_samples=0, span_s=START_WITHOUT_IMU_S)


@pytest.fixture(scope="module")
def robot() -> TeamMember:
    mission = team_mission(0, stop_s=0.0, waypoints=3)
    return next(m for m in mission.members if m.kind == "robot")


def _feed(member: TeamMember, kind: str) -> list[Rows]:
    session = member.session.with_parts(truth=None)
    runner = InProcessRunner()
    runner.open(AgentSpec(1, member.preset, session.meta.model_dump(mode="json"), kind=kind),
                None, -math.inf)
    return [runner.feed(1, [parse_batch({**b, "seq": i})])
            for i, (_, b) in enumerate(session_batches(session, chunk_s=0.5, blocks=True))]


def _rows(out: Rows) -> bool:
    return out.final is not None or out.provisional is not None


def test_robot_tracked_from_its_first_batch_as_offline(robot: TeamMember) -> None:
    out = _feed(robot, "robot")
    assert _rows(out[0]), "a robot is tracked from its first half second of odometry"
    finals = [r.final for r in out if r.final is not None]
    t = np.concatenate([f.t for f in finals])
    xy = np.concatenate([f.xyz[:, :2] for f in finals])
    cov = np.concatenate([f.cov_xy for f in finals])
    ref = Tracker(preset(robot.preset)).run(robot.session.with_parts(truth=None)).trajectory
    n = len(t)
    assert n > 20 and ref.t[0] == t[0]
    np.testing.assert_allclose(t, ref.t[:n], atol=1e-9)
    np.testing.assert_allclose(xy, ref.xyz[:n, :2], atol=1e-9)
    np.testing.assert_allclose(cov, ref.cov_xy[:n], atol=1e-9)


def test_same_stream_as_a_rescuer_waits_for_an_imu(robot: TeamMember) -> None:
    out = _feed(robot, "rescuer")
    first = next(i for i, r in enumerate(out) if _rows(r))
    assert first * 0.5 >= START_WITHOUT_IMU_S - 1.0
