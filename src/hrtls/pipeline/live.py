"""What a live tracker needs before it starts.

Shared by the service's per-agent runner (:mod:`hrtls.service.runner`) and the live mission
estimator (:mod:`hrtls.mission.tracker`). A tracker reads its nominal IMU rate from the first
``RATE_SAMPLES`` accelerometer samples (:meth:`hrtls.pipeline.Tracker.start_session`), so live
it starts once that many are in; a stream without an accelerometer starts once its data span
``START_WITHOUT_IMU_S`` (an IMU may still join), a robot's on its first ``ROBOT_START_POSES``
odometry poses (a robot streams odometry, not an IMU). Started that way, it gives the rows the
offline tracker gives on the whole recording.
"""

from __future__ import annotations

from hrtls.pipeline.build import RATE_SAMPLES

START_WITHOUT_IMU_S = 30.0
"""Without accelerometer samples the tracker starts once its first data span this long, s."""
ROBOT_START_POSES = 2
"""A robot's tracker starts on this many odometry poses (module doc)."""


def ready_to_start(*, accel_samples: int, span_s: float, robot_poses: int | None = None
                   ) -> bool:
    """Whether a live tracker can start on what arrived.

    It can with ``RATE_SAMPLES`` accelerometer samples, or with none and ``START_WITHOUT_IMU_S``
    of other data, or, for a robot (``robot_poses``: its odometry poses so far), with none and
    ``ROBOT_START_POSES`` poses.
    """
    if accel_samples >= RATE_SAMPLES:
        return True
    if accel_samples:
        return False
    if robot_poses is not None and robot_poses >= ROBOT_START_POSES:
        return True
    return span_s >= START_WITHOUT_IMU_S
