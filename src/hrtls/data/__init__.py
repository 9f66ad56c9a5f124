"""Core containers, validated at construction (see :mod:`hrtls.data.validation`)."""

from hrtls.data.landmarks import Landmark, Wgs84
from hrtls.data.observations import (
    Checkpoints,
    GroundTruth,
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    TagDetections,
)
from hrtls.data.results import Activity, StepEvents, Trajectory, activity_codes, activity_labels
from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.data.session import (
    ChannelModel,
    GeoreferenceModel,
    Session,
    SessionMeta,
    StartPose,
    UserProfile,
)

__all__ = [
    "Activity",
    "ChannelModel",
    "Checkpoints",
    "GeoreferenceModel",
    "GroundTruth",
    "ImuStream",
    "Landmark",
    "OrientationSeries",
    "PositionFixes",
    "RangeMeasurements",
    "RssReadings",
    "SensorSeries",
    "Session",
    "SessionMeta",
    "StartPose",
    "StepEvents",
    "TagDetections",
    "Trajectory",
    "UserProfile",
    "Wgs84",
    "activity_codes",
    "activity_labels",
]
