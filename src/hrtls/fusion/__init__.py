"""Rescuer position/heading filter: predictions and corrections (the papers' fusion parts).

* :mod:`~hrtls.fusion.state` -- ``[x, y, z, heading]`` state with covariance, save/restore.
* :mod:`~hrtls.fusion.gating` -- Joseph-form Kalman update with chi-square NIS gate, diagnostics.
* :mod:`~hrtls.fusion.step_prediction` -- Inderst eq. 4.23-4.25 (3-D steps, stairs).
* :mod:`~hrtls.fusion.velocity_prediction` -- Colombo eq. 15-17 (numba kernel).
* :mod:`~hrtls.fusion.fixes` -- Colombo eq. 18-23 (fixes while moving, period Tp) and the loop.
* :mod:`~hrtls.fusion.yaw_stretch` -- Colombo eq. 24-28 (yaw pseudo-measurement).
* :mod:`~hrtls.fusion.path_loss` -- Tarrio eq. 1 (log-normal path loss).
* :mod:`~hrtls.fusion.rss_scans` -- RSS scans and their positions (Tarrio eq. 2, hyperbolic WLS).
* :mod:`~hrtls.fusion.rss` -- the tight RSS EKF (Tarrio eq. 5-13 are the tracker's WLS fixes).
* :mod:`~hrtls.fusion.channel` -- online re-estimation of the channel ``A``, ``eta``.
* :mod:`~hrtls.fusion.tags` -- Inderst eq. 4.26-4.33 (four tag strategies), 4.21-4.22 (bearings).
* :mod:`~hrtls.fusion.ranges` -- Inderst eq. 4.34-4.35 (range EKF).
* :mod:`~hrtls.fusion.floors` -- floor index and level constraint.
* :mod:`~hrtls.fusion.random_walk` -- prediction without motion sensors (infrastructure only).

The frequent predictions and corrections (steps, random walk, floor level, RSS reading, range,
scan position, channel, the scalar and 2-D Joseph updates) are numba functions on plain arrays
and parameter records (``*_DTYPE``), called by the Python API here and by the tracker's compiled
event loop (:mod:`hrtls.pipeline._events`): each is written once.
"""

from hrtls.fusion.channel import ChannelEstimator, ChannelEstimatorParams, ChannelState
from hrtls.fusion.fixes import (
    FixCorrector,
    FixParams,
    FixSchedule,
    StretchMemory,
    YawPseudoMeasurement,
)
from hrtls.fusion.floors import floor_index, floor_level, floor_level_update
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    UpdateResult,
    chi2_threshold,
    kalman_update,
    summarize,
)
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.random_walk import RandomWalkParams, predict_random_walk
from hrtls.fusion.ranges import RangeParams, range_update, update_ranges
from hrtls.fusion.rss import (
    rss_update,
    update_rss_readings,
)
from hrtls.fusion.rss_scans import RssScan, group_scans, hyperbolic_wls, scan_position
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import (
    TagCorrector,
    TagMemory,
    TagParams,
    bearing_heading_correction,
    group_detections,
    lobe_centre,
)
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor
from hrtls.fusion.yaw_stretch import YawStretchParams, stretch_yaw

__all__ = [
    "ChannelEstimator",
    "ChannelEstimatorParams",
    "ChannelState",
    "FilterState",
    "FixCorrector",
    "FixParams",
    "FixSchedule",
    "PathLossModel",
    "RandomWalkParams",
    "RangeParams",
    "RssScan",
    "StepPredictionParams",
    "StepPredictor",
    "StretchMemory",
    "TagCorrector",
    "TagMemory",
    "TagParams",
    "UpdateDiagnostics",
    "UpdateResult",
    "VelocityPredictionParams",
    "VelocityPredictor",
    "YawPseudoMeasurement",
    "YawStretchParams",
    "bearing_heading_correction",
    "chi2_threshold",
    "floor_index",
    "floor_level",
    "floor_level_update",
    "group_detections",
    "group_scans",
    "hyperbolic_wls",
    "kalman_update",
    "lobe_centre",
    "predict_random_walk",
    "range_update",
    "rss_update",
    "scan_position",
    "stretch_yaw",
    "summarize",
    "update_ranges",
    "update_rss_readings",
]
