"""Which sessions have an unobservable heading, and how the track says so."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.data import ImuStream, SensorSeries, Session, StartPose, StepEvents, Trajectory
from hrtls.data.observations import RssReadings
from hrtls.data.session import SessionMeta
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.pipeline.tracker import TrackResult
from hrtls.pipeline.unobservable_heading import (
    heading_observable,
    heading_unobservable_reason,
    widen_unobservable_heading,
)

T = np.arange(5.0)


def _track() -> TrackResult:
    # out 3 m east, then 4 m north: distance from the start 0, 1, 2, 3, 5 m
    xyz = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [3, 4, 0]], dtype=float)
    tr = Trajectory.build(t=T, xyz=xyz, cov_xy=np.tile(np.eye(2) * 0.04, (5, 1, 1)),
                          var_heading=np.full(5, 0.001))
    return TrackResult(tr, StepEvents.empty(), None, [], {})


def _imu(gyro: bool, mag: bool) -> ImuStream:
    acc = SensorSeries(T, np.tile([0.0, 0.0, 9.81], (5, 1)), "acc")
    g = SensorSeries(T, np.zeros((5, 3)), "gyro") if gyro else None
    m = SensorSeries(T, np.tile([20.0, 0.0, -40.0], (5, 1)), "mag") if mag else None
    return ImuStream(acc, g, m)


def test_gyroscope_without_magnetometer_widens_by_the_distance_from_the_start() -> None:
    s = Session(imu=_imu(gyro=True, mag=False))
    out = widen_unobservable_heading(_track(), s)
    r = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 0, 0], 0.04 + r**2 / 2)
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 1, 1], 0.04 + r**2 / 2)
    np.testing.assert_allclose(out.trajectory.cov_xy[:, 0, 1], 0.0)
    np.testing.assert_allclose(out.trajectory.var_heading, UNIFORM_ANGLE_VAR_RAD2)
    h = out.report["heading"]
    assert h["observable"] is False and "start heading" in h["why"]
    assert h["position_sigma_at_end_m"] == pytest.approx(math.sqrt(0.04 + 12.5))
    assert "rotation" in h["plot_note"]
    # the uncertainty grows along the walk away from the start
    assert np.all(np.diff(np.trace(out.trajectory.cov_xy, axis1=1, axis2=2)) > 0)


def test_a_start_heading_or_a_magnetometer_makes_it_observable() -> None:
    pose = SessionMeta(start_pose=StartPose(x=0.0, y=0.0, heading=0.3))
    assert heading_observable(Session(meta=pose, imu=_imu(gyro=True, mag=False)))
    assert heading_observable(Session(imu=_imu(gyro=True, mag=True)))
    assert not heading_observable(Session(imu=_imu(gyro=False, mag=False)))
    out = widen_unobservable_heading(_track(), Session(imu=_imu(gyro=True, mag=True)))
    np.testing.assert_allclose(out.trajectory.cov_xy, _track().trajectory.cov_xy)
    assert out.report["heading"] == {"observable": True}


def test_no_imu_keeps_the_positions_and_reports_the_heading_unknown() -> None:
    s = Session(rss=RssReadings(T, np.array(["a"] * 5), np.full(5, -70.0)))
    assert heading_unobservable_reason(s) is not None
    out = widen_unobservable_heading(_track(), s)
    np.testing.assert_allclose(out.trajectory.cov_xy, _track().trajectory.cov_xy)
    np.testing.assert_allclose(out.trajectory.var_heading, UNIFORM_ANGLE_VAR_RAD2)
    assert out.report["heading"]["observable"] is False
    assert out.report["heading"]["plot_note"].startswith("no IMU")


def test_simulated_gyroscope_only_walk_through_the_tracker() -> None:
    from hrtls.pipeline import Tracker
    from hrtls.pipeline.finish import finish_track
    from hrtls.sim.scenarios import run_scenario

    s = run_scenario("colombo_circle", seed=0, laps=1).session
    assert s.imu is not None and s.meta.start_pose is not None
    pose = s.meta.start_pose
    gyro_only = s.with_parts(
        imu=ImuStream(s.imu.accel, s.imu.gyro), orientation=None, fixes=None, rss=None,
        tags=None, ranges=None, pressure=None,
        meta=s.meta.model_copy(update={"start_pose": StartPose(x=pose.x, y=pose.y)}))
    tracker = Tracker()
    res = finish_track(tracker.run(gyro_only), gyro_only, tracker.config)
    assert res.report["heading"]["observable"] is False
    tr = res.trajectory
    r = np.linalg.norm(tr.xyz[:, :2] - tr.xyz[:1, :2], axis=1)
    assert r.max() > 5.0
    np.testing.assert_array_less(r**2 / 2 - 1e-9, tr.cov_xy[:, 0, 0])
    # with its start heading the same walk is observable and left as the filter made it
    with_heading = gyro_only.with_parts(meta=s.meta)
    assert heading_observable(with_heading)
