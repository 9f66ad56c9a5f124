"""Accelerometer-only tracks carry the uncertainty of an unknown heading (not a confident path)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from hrtls.cli.app import app
from hrtls.data import ImuStream, SensorSeries, Session, StepEvents, Trajectory
from hrtls.io.tables import read_trajectory
from hrtls.pipeline.tracker import TrackResult
from hrtls.pipeline.unobservable_heading import (
    UNIFORM_ANGLE_VAR_RAD2,
    heading_observable,
    widen_unobservable_heading,
)

runner = CliRunner()


def test_hand_computed_straight_walk() -> None:
    t = np.arange(11.0)
    xyz = np.column_stack([t, np.zeros(11), np.zeros(11)])  # 1 m per row, 10 m in all
    tr = Trajectory.build(t=t, xyz=xyz, cov_xy=np.tile(np.eye(2) * 0.01, (11, 1, 1)),
                          var_heading=np.full(11, 0.001))
    acc_only = Session(imu=ImuStream(SensorSeries(t, np.tile([0, 0, 9.81], (11, 1)), "acc")))
    out = widen_unobservable_heading(TrackResult(tr, StepEvents.empty(), None, [], {}),
                                     acc_only)
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 0, 0], 0.01 + t**2 / 2)
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 1, 1], 0.01 + t**2 / 2)
    np.testing.assert_allclose(out.trajectory.var_heading, math.pi**2 / 3)
    assert out.report["heading"]["observable"] is False
    assert out.report["heading"]["position_sigma_at_end_m"] == pytest.approx(math.sqrt(0.01 + 50))
    gyro = SensorSeries(t, np.zeros((11, 3)), "gyro")
    with_gyro = acc_only.with_parts(imu=ImuStream(acc_only.imu.accel, gyro))
    with_mag = acc_only.with_parts(imu=ImuStream(acc_only.imu.accel, gyro, gyro))
    assert heading_observable(with_mag) and not heading_observable(acc_only)
    assert not heading_observable(with_gyro)   # the start heading is unknown


def test_oxford_accelerometer_only_track(shared_data: Path, tmp_path: Path) -> None:
    path = shared_data / "oxford_step" / "user1_frontpocket_1506422223341.csv"
    if not path.exists():
        pytest.skip("oxford recordings not available")
    out = tmp_path / "ox"
    res = runner.invoke(app, ["track", str(path), "-o", str(out), "--plot"])
    assert res.exit_code == 0, res.output
    tr = read_trajectory(out / "trajectory.csv")
    np.testing.assert_allclose(tr.var_heading, UNIFORM_ANGLE_VAR_RAD2)
    walked = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(tr.xyz[:, :2], axis=0).T))])
    assert tr.cov_xy[-1, 0, 0] >= walked[-1] ** 2 / 2 - 1e-6
    report = json.loads((out / "report.json").read_text())
    assert report["heading"]["observable"] is False
