"""What a live tracker needs before it starts.

Shared by the service's per-agent runner (:mod:`hrtls.service.runner`) and the live mission
estimator (:mod:`hrtls.mission.tracker`). A tracker reads its nominal IMU rate from the first
``RATE_SAMPLES`` accelerometer samples (:meth:`hrtls.pipeline.Tracker.start_session`), so live
it starts once that many are in; a stream without an accelerometer starts once its data span
``START_WITHOUT_IMU_S``. Started that way, it gives the rows the offline tracker gives on the
whole recording.
"""

from __future__ import annotations

from hrtls.pipeline.build import RATE_SAMPLES

START_WITHOUT_IMU_S = 30.0
"""Without accelerometer samples the tracker starts once its first data span this long, s."""


def ready_to_start(*, accel_samples: int, span_s: float) -> bool:
    """Whether a live tracker can start on what arrived.

    It can with ``RATE_SAMPLES`` accelerometer samples, or with none and ``START_WITHOUT_IMU_S``
    of other data.
    """
    if accel_samples >= RATE_SAMPLES:
        return True
    return accel_samples == 0 and span_s >= START_WITHOUT_IMU_S
