"""Honest uncertainty of a track whose heading cannot be observed.

The heading relative to east is unobservable when nothing measures it absolutely:

* **accelerometer only** (no gyroscope, magnetometer or device orientation): the step lengths
  are measured, the turns are not, and the track is only known to lie within the distance walked
  of the start. The horizontal covariance grows by ``L(t)^2 / 2`` per axis, ``L(t)`` the
  distance walked since the first row (a point at distance ``L`` in a uniformly unknown
  direction has ``E[x^2] = E[y^2] = L^2 / 2``);
* **gyroscope without magnetometer** (and no device orientation and no start heading): the
  turns are measured, the start heading is not, so the drawn path is right up to a rotation about
  the start. The covariance grows by ``r(t)^2 / 2`` per axis, ``r(t)`` the distance of the row
  from the first row (a rotation by a uniform angle);
* **no IMU**: the positions come from the infrastructure and are left as the filter made them;
  nothing says which way the agent faces.

In all three the heading variance becomes that of a uniform angle, ``pi^2 / 3`` rad^2. With
absolute position corrections (fixes, tags, RSS, ranges) and an IMU the track is left as the
filter made it (the corrections bound the position; the filter's heading variance stands).
``report["heading"]`` records the verdict, its reason and the position sigma at the end; the
plot's title marks it (``plot_note``).
"""

from __future__ import annotations

import numpy as np

from hrtls.data import Session, Trajectory
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.pipeline.tracker import TrackResult


def heading_unobservable_reason(session: Session) -> str | None:
    """Why the heading is unobservable (see the module docstring), None when it is observable."""
    imu = session.imu
    pose = session.meta.start_pose
    if imu is None:
        return "no IMU: no sensor measures the heading"
    absolute = any(p is not None for p in (session.orientation, session.fixes, session.rss,
                                           session.tags, session.ranges))
    if absolute or imu.mag is not None:
        return None
    if imu.gyro is None:
        return "no gyroscope, magnetometer, device orientation or absolute position"
    if pose is not None and pose.heading is not None:
        return None
    return ("gyroscope without magnetometer, device orientation, start heading or absolute "
            "position: heading changes only, the start heading is unknown")


def heading_observable(session: Session) -> bool:
    """True when some sensor, observation or the start pose fixes the heading."""
    return heading_unobservable_reason(session) is None


def widen_unobservable_heading(result: TrackResult, session: Session) -> TrackResult:
    """``result`` with the uncertainty of an unobservable heading (unchanged otherwise)."""
    report = dict(result.report)
    why = heading_unobservable_reason(session)
    if why is None:
        report["heading"] = {"observable": True}
        return result if result.report.get("heading") == report["heading"] else \
            TrackResult(result.trajectory, result.steps, result.attitude, result.diagnostics,
                        report)
    tr = result.trajectory
    xy = tr.xyz[:, :2]
    cov = tr.cov_xy.copy()
    grow = np.zeros(len(tr))
    imu = session.imu
    if imu is not None and imu.gyro is None:          # accelerometer only: distance walked
        grow = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        note = "heading unobservable: shape only"
    elif imu is not None:                             # gyroscope only: rotation about the start
        grow = np.linalg.norm(xy - xy[:1], axis=1) if len(xy) else grow
        note = "start heading unobservable: path up to a rotation about the start"
    else:
        note = "no IMU: heading not observed"
    cov[:, 0, 0] += grow**2 / 2.0
    cov[:, 1, 1] += grow**2 / 2.0
    var_heading = np.full(len(tr), UNIFORM_ANGLE_VAR_RAD2)
    trajectory = Trajectory(tr.t, tr.xyz, tr.heading_rad, cov, var_heading, tr.activity)
    report["heading"] = {
        "observable": False,
        "why": why,
        "var_heading_rad2": UNIFORM_ANGLE_VAR_RAD2,
        "position_sigma_at_end_m": float(np.sqrt(np.trace(cov[-1]) / 2.0)) if len(tr) else 0.0,
        "plot_note": note,
    }
    return TrackResult(trajectory, result.steps, result.attitude, result.diagnostics, report)
