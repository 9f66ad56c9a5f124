"""What follows the tracker for a recorded session: barometric floors, unobservable heading."""

from __future__ import annotations

from hrtls.data import Session
from hrtls.pipeline.barometric import with_baro_floors
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import TrackResult
from hrtls.pipeline.unobservable_heading import widen_unobservable_heading


def finish_track(result: TrackResult, session: Session, config: TrackerConfig) -> TrackResult:
    """Barometric floors, then the uncertainty of an unobservable heading.

    See :func:`~hrtls.pipeline.barometric.with_baro_floors` and
    :func:`~hrtls.pipeline.unobservable_heading.widen_unobservable_heading`.
    """
    return widen_unobservable_heading(with_baro_floors(result, session, config), session)
