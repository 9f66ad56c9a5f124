"""What follows the tracker for a recorded session: floors, unobservable heading, IMU gaps."""

from __future__ import annotations

from hrtls.data import Session
from hrtls.pipeline.barometric import with_baro_floors
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.gap_uncertainty import widen_over_gaps
from hrtls.pipeline.tracker import TrackResult
from hrtls.pipeline.unobservable_heading import widen_unobservable_heading


def finish_track(result: TrackResult, session: Session, config: TrackerConfig) -> TrackResult:
    """Barometric floors, then the uncertainty of an unobservable heading and of IMU gaps.

    See :func:`~hrtls.pipeline.barometric.with_baro_floors`,
    :func:`~hrtls.pipeline.unobservable_heading.widen_unobservable_heading` and
    :func:`~hrtls.pipeline.gap_uncertainty.widen_over_gaps`.
    """
    floors = with_baro_floors(result, session, config)
    return widen_over_gaps(widen_unobservable_heading(floors, session), session)
