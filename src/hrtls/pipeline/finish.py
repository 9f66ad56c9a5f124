"""What follows the tracker for a recorded session: unobservable heading, IMU gaps."""

from __future__ import annotations

from hrtls.data import Session
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.gap_uncertainty import widen_over_gaps
from hrtls.pipeline.tracker import TrackResult
from hrtls.pipeline.unobservable_heading import widen_unobservable_heading


def finish_track(result: TrackResult, session: Session, config: TrackerConfig) -> TrackResult:
    """The uncertainty of an unobservable heading and of IMU gaps (floors: in the tracker).

    See :func:`~hrtls.pipeline.unobservable_heading.widen_unobservable_heading` and
    :func:`~hrtls.pipeline.gap_uncertainty.widen_over_gaps`.
    """
    del config   # the tracker's configuration already shaped the result
    return widen_over_gaps(widen_unobservable_heading(result, session), session)
