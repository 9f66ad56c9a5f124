"""Honest uncertainty of a track whose heading cannot be observed (accelerometer only).

Without a gyroscope, a magnetometer and a device orientation, the walking direction relative
to north is unknown: the step lengths are measured, the turns are not. The track is then only
known to lie within the distance walked of the start. :func:`widen_unobservable_heading` says
so in the numbers: the heading variance becomes that of a uniform angle, ``pi^2 / 3`` rad^2,
and the horizontal covariance grows by ``d(t)^2 / 2`` per axis, ``d(t)`` the distance walked
since the first row (a point at distance ``d`` in a uniformly unknown direction has
``E[x^2] = E[y^2] = d^2 / 2``). ``report["heading"]`` records it; the plot marks it.
Absolute position corrections (fixes, tags, RSS, ranges) are not undone: with any of them in
the recording the track is left as the filter made it.
"""

from __future__ import annotations

import math

import numpy as np

from hrtls.data import Session, Trajectory
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.pipeline.tracker import TrackResult



def heading_observable(session: Session) -> bool:
    """True when some sensor or observation fixes the heading."""
    imu = session.imu
    sensors = imu is not None and (imu.gyro is not None or imu.mag is not None)
    absolute = any(p is not None for p in (session.orientation, session.fixes, session.rss,
                                           session.tags, session.ranges))
    return imu is None or sensors or absolute


def widen_unobservable_heading(result: TrackResult, session: Session) -> TrackResult:
    """``result`` with the uncertainty of an unobservable heading (unchanged otherwise)."""
    report = dict(result.report)
    if heading_observable(session):
        report["heading"] = {"observable": True}
        return result if result.report.get("heading") == report["heading"] else \
            TrackResult(result.trajectory, result.steps, result.attitude, result.diagnostics,
                        report)
    tr = result.trajectory
    step = np.linalg.norm(np.diff(tr.xyz[:, :2], axis=0), axis=1)
    walked = np.concatenate([[0.0], np.cumsum(step)])
    cov = tr.cov_xy.copy()
    cov[:, 0, 0] += walked**2 / 2.0
    cov[:, 1, 1] += walked**2 / 2.0
    var_heading = np.full(len(tr), UNIFORM_ANGLE_VAR_RAD2)
    trajectory = Trajectory(tr.t, tr.xyz, tr.heading_rad, cov, var_heading, tr.activity)
    report["heading"] = {
        "observable": False,
        "why": "no gyroscope, magnetometer, device orientation or absolute position",
        "var_heading_rad2": UNIFORM_ANGLE_VAR_RAD2,
        "position_sigma_at_end_m": float(walked[-1] / math.sqrt(2.0)) if len(walked) else 0.0,
    }
    return TrackResult(trajectory, result.steps, result.attitude, result.diagnostics, report)
