"""Position uncertainty across gaps of the IMU (a recording paused, a stream lost).

A step-driven tracker sees no steps in a gap and continues from where it was, as if the person
had stood still. Over a gap of ``g`` seconds a walker may have gone up to ``speed_m_s * g``
anywhere: :func:`widen_over_gaps` adds the variance of a uniform disc of that radius,
``R^2 / 4`` per axis, to every row after the gap (dead reckoning never shrinks it again).
With absolute position observations in the recording (fixes, RSS, tags, ranges) the track is
left as the filter made it: they re-anchor it after the gap. ``report["gaps"]`` lists the gaps.
"""

from __future__ import annotations

import numpy as np

from hrtls.data import Session, Trajectory
from hrtls.data.clocks import ClockParams, find_jumps
from hrtls.pipeline.tracker import TrackResult

WALK_SPEED_BOUND_M_S = 1.5
"""Fastest walking assumed inside a gap, m/s."""


def widen_over_gaps(result: TrackResult, session: Session, *,
                    speed_m_s: float = WALK_SPEED_BOUND_M_S,
                    params: ClockParams | None = None,
                    imu_t: np.ndarray | None = None) -> TrackResult:
    """``result`` with the uncertainty of the IMU's gaps (unchanged without gaps).

    ``imu_t``: the accelerometer's times when ``session`` holds only part of the IMU (a
    streamed recording).
    """
    t = imu_t if imu_t is not None else None if session.imu is None else session.imu.accel.t
    if t is None or len(result.trajectory) == 0:
        return result
    gaps = [j for j in find_jumps(t, params=params) if j.forward]
    if not gaps:
        return result
    anchored = any(p is not None for p in (session.fixes, session.rss, session.tags,
                                           session.ranges))
    report = dict(result.report)
    report["gaps"] = [{"t_start_s": j.t_before_s, "duration_s": j.step_s,
                       "radius_m": speed_m_s * j.step_s} for j in gaps]
    if anchored:
        report["gaps_note"] = "absolute observations re-anchor the track after the gaps"
        return TrackResult(result.trajectory, result.steps, result.attitude,
                           result.diagnostics, report)
    tr = result.trajectory
    extra = np.zeros(len(tr))
    for j in gaps:
        extra[tr.t >= j.t_before_s + j.step_s] += (speed_m_s * j.step_s) ** 2 / 4.0
    cov = tr.cov_xy.copy()
    cov[:, 0, 0] += extra
    cov[:, 1, 1] += extra
    trajectory = Trajectory(tr.t, tr.xyz, tr.heading_rad, cov, tr.var_heading, tr.activity)
    return TrackResult(trajectory, result.steps, result.attitude, result.diagnostics, report)
