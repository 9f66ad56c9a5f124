"""Components of the tracker built from its configuration and the session's sensors.

Nothing here looks at samples: what is built depends only on the configuration, the session
metadata (user profile, channel, mounting) and which sensors the session has.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from hrtls.attitude.base import AttitudeFilter
from hrtls.attitude.device import DeviceOrientation
from hrtls.attitude.registry import DEFAULT_FILTER, make_filter
from hrtls.data import Session, SessionMeta
from hrtls.data.landmarks import Landmark
from hrtls.data.session import StartPose
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.fusion.channel import ChannelEstimator, ChannelEstimatorParams
from hrtls.fusion.fixes import FixCorrector, FixParams
from hrtls.fusion.floors import FlightParams
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.random_walk import RandomWalkParams
from hrtls.fusion.ranges import RangeParams
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import TagCorrector, TagParams
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.missed_steps import MissedStepParams
from hrtls.gait.peak_steps import PeakStepDetector
from hrtls.gait.pll import PllStepDetector
from hrtls.gait.stairs_climb import ClimbParams
from hrtls.gait.step_length import FrequencyLawModel, StepModel, WeinbergModel, step_model_from_dict
from hrtls.gait.step_length_pendulum import PendulumModel
from hrtls.gait.velocity_automaton import VelocityAutomaton
from hrtls.gait.walk_steps import WalkStepParams
from hrtls.gait.walking_bouts import WalkingBoutParams
from hrtls.pipeline import _events as ev
from hrtls.pipeline.config import GaitConfig, TrackerConfig, params_of
from hrtls.pipeline.mag_heading import MagBlocks, MagHeading, MagHeadingParams


class Notes:
    """The report's notes; ``degrade`` also warns (:class:`~hrtls.errors.DegradedInputWarning`)."""

    def __init__(self, items: list[str] | None = None) -> None:
        self.items: list[str] = [] if items is None else items

    def add(self, message: str) -> None:
        """A note."""
        self.items.append(message)

    def degrade(self, message: str) -> None:
        """A note on a degraded mode, also warned."""
        self.items.append(message)
        warnings.warn(message, DegradedInputWarning, stacklevel=3)


@dataclass(frozen=True, slots=True)
class Sensors:
    """Which sensors a recording has, its nominal IMU rate and start time."""

    has_imu: bool
    has_gyro: bool
    has_mag: bool
    has_orientation: bool
    rate_hz: float
    t0: float

    @classmethod
    def of_session(cls, session: Session) -> Sensors:
        """The sensors of a whole session (rate from its leading accelerometer times)."""
        imu = session.imu
        return cls(has_imu=imu is not None, has_gyro=imu is not None and imu.gyro is not None,
                   has_mag=imu is not None and imu.mag is not None,
                   has_orientation=session.orientation is not None,
                   rate_hz=leading_rate_hz(imu.accel.t) if imu is not None else 0.0,
                   t0=session.time_span()[0])


RATE_SAMPLES = 512
"""Leading accelerometer samples whose median spacing gives the nominal rate (start_session)."""


def leading_rate_hz(t: np.ndarray) -> float:
    """Nominal rate from the median spacing of the first ``RATE_SAMPLES`` times, Hz."""
    head = t[:RATE_SAMPLES]
    return float(1.0 / np.median(np.diff(head))) if len(head) >= 2 else 0.0


def attitude_method(config: TrackerConfig, sensors: Sensors, notes: Notes) -> str:
    """The attitude method to run with these sensors (degraded modes noted)."""
    method: str = config.attitude.method
    s = sensors
    if method == "auto":
        method = "device" if s.has_orientation else DEFAULT_FILTER
    if s.has_imu and method == "device" and not s.has_orientation:
        notes.degrade("attitude 'device' asked but the session has no device orientation; "
                      f"using {DEFAULT_FILTER!r}")
        method = DEFAULT_FILTER
    if s.has_imu and method not in ("device", "none") and not s.has_gyro and not s.has_mag:
        notes.degrade("no gyroscope and no magnetometer: heading is unobservable, "
                      "using accelerometer-only levelling and relative walking directions")
        method = "none"
    if s.has_imu and method not in ("device", "none") and not s.has_gyro:
        notes.degrade("no gyroscope: attitude from accelerometer and magnetometer only")
    return method if s.has_imu else "none"


def attitude_filter(config: TrackerConfig, method: str
                    ) -> AttitudeFilter | DeviceOrientation | None:
    """The attitude stage of a method (None: no attitude), ``[attitude.<method>]`` parameters."""
    if method == "device":
        return DeviceOrientation()
    if method == "none":
        return None
    return make_filter(method, config.attitude.filter_params(method))


def compass_heading(config: TrackerConfig, *, has_mag: bool) -> MagBlocks | None:
    """The field blocks of the magnetic heading measurement (``heading_source``), or None."""
    att = config.attitude
    if att.heading_source != "gyro+compass" or not (has_mag and att.use_magnetometer):
        return None
    return MagBlocks(params_of(MagHeadingParams, att.mag_heading).block_s)


def mag_heading(config: TrackerConfig) -> MagHeading | None:
    """The engine's magnetic heading measurement (``heading_source = "gyro+compass"``)."""
    att = config.attitude
    return (MagHeading(params_of(MagHeadingParams, att.mag_heading))
            if att.heading_source == "gyro+compass" else None)


def yaw_relative(config: TrackerConfig, *, has_mag: bool) -> bool:
    """The attitude yaw has an arbitrary zero (no magnetometer in the attitude filter)."""
    return not (config.attitude.use_magnetometer and has_mag) or \
        compass_heading(config, has_mag=has_mag) is not None


def step_model(config: GaitConfig, meta: SessionMeta) -> tuple[StepModel, float]:
    """The step-length model and the running steps' factor from the user's profile.

    A profile may carry the running steps' own factor (our addition: calibration walks at
    walking and running pace): ``k_running`` with a Weinberg K, ``running_factor`` else.
    """
    profile = dict(meta.user.step_model)
    k_run = profile.pop("k_running", None)
    run_factor = profile.pop("running_factor", None)
    running_factor = 1.0
    if profile.get("kind") == config.step_length:
        if k_run is not None and profile.get("k"):
            running_factor = float(k_run) / float(profile["k"])
        elif run_factor is not None:
            running_factor = float(run_factor)
        if not (0.5 <= running_factor <= 2.0):
            raise InputError(f"running step factor {running_factor:.3g}",
                             where="user.step_model", expected="between 0.5 and 2")
    model: StepModel
    if config.step_length == "weinberg":
        if config.weinberg_k is not None:
            model = WeinbergModel(k=config.weinberg_k)
        elif profile and profile.get("kind") == "weinberg":
            model = step_model_from_dict(profile)
        else:
            model = WeinbergModel()
    elif config.step_length == "pendulum":
        model = (step_model_from_dict(profile) if profile and profile.get("kind") == "pendulum"
                 else PendulumModel())
    elif profile and profile.get("kind") == "frequency":
        model = step_model_from_dict(profile)
    else:
        model = FrequencyLawModel()
    return model, running_factor


def activity_model(kind: str) -> LdaModel | TreeThresholds | None:
    """The activity classifier (None: from the motion level alone)."""
    if kind == "lda":
        return LdaModel.default()
    if kind == "tree":
        return TreeThresholds()
    return None


def gait_analyzer(config: TrackerConfig, *, rate_hz: float, model: StepModel,
                  attitude: str, meta: SessionMeta, notes: Notes) -> GaitAnalyzer:
    """The gait stage for the mounting now known (``meta.mounting_q_bd``)."""
    g = config.gait
    gait = GaitAnalyzer(
        rate_hz=rate_hz,
        step_detector=PllStepDetector() if g.step_detector == "pll" else PeakStepDetector(),
        step_model=model,
        activity=activity_model(g.activity),
        heading=g.heading if attitude != "none" else "fourier",
        velocity=VelocityAutomaton() if (g.velocity_automaton
                                         or config.prediction.model == "velocity") else None,
        mounting_q_bd=None if meta.mounting_q_bd is None
        else np.asarray(meta.mounting_q_bd, dtype=np.float64),
        gate_steps_with_motion=g.gate_steps_with_motion,
        walking_bouts=WalkingBoutParams() if g.walking_bouts else None,
        missed_steps=MissedStepParams() if g.fill_missed_steps else None,
        walk_steps=(WalkStepParams() if g.drop_weak_walks and g.step_detector == "peak"
                    else None),
        step_yaw=g.step_yaw,
        window_features=g.activity != "motion",
        climb=(params_of(ClimbParams, g.climb) if g.climb_stairs
               and meta.placement in g.climb_placements else None),
    )
    if meta.mounting_q_bd is None and g.heading == "yaw":
        notes.add("device mounting unknown: step headings are the yaw of a level device axis "
                  "plus the walking direction found from the walking motion (none for the "
                  "first steps)")
    return gait


@dataclass(slots=True)
class Corrections:
    """The position filter's prediction and correction parts."""

    step_predictor: StepPredictor
    velocity_predictor: VelocityPredictor
    random_walk: RandomWalkParams
    fix_corrector: FixCorrector
    tag_corrector: TagCorrector
    tag_fallback: TagCorrector | None
    range_params: RangeParams
    path_loss: PathLossModel
    channel_estimator: ChannelEstimator | None


def corrections(config: TrackerConfig, meta: SessionMeta, *, has_imu: bool,
                notes: Notes) -> Corrections:
    """The position filter's parts for this configuration and session."""
    cfg = config
    tags = TagCorrector(TagParams(
        strategy=cfg.tags.strategy, gate_probability=cfg.gate_probability,
        sigma_per_accuracy=cfg.tags.sigma_per_accuracy,
        repeat_interval_s=cfg.tags.repeat_interval_s))
    channel = meta.channel
    path_loss = (PathLossModel.from_channel(channel) if channel is not None
                 else PathLossModel(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
    # without an IMU the position comes from the RSS itself: estimating A and eta from the
    # same readings is circular (they drift together with the position), so keep the prior
    if cfg.rss.estimate_channel and not has_imu:
        notes.add("no IMU: the RSS channel (A, eta) is not re-estimated online "
                  "(positions and channel would come from the same readings)")
    return Corrections(
        step_predictor=StepPredictor(StepPredictionParams(
            q_along=cfg.prediction.q_along, q_across=cfg.prediction.q_across,
            heading_mode=cfg.prediction.heading_mode,
            stairs_from_model=cfg.prediction.stairs_from_model,
            sigma_heading_increment_rad=cfg.prediction.sigma_heading_increment_rad)),
        velocity_predictor=VelocityPredictor(VelocityPredictionParams(
            heading_mode=cfg.prediction.heading_mode)),
        random_walk=params_of(RandomWalkParams, cfg.prediction.random_walk),
        fix_corrector=FixCorrector(FixParams(
            period_s=cfg.fixes.period_s, require_motion=cfg.fixes.require_motion,
            gate_probability=cfg.gate_probability if cfg.fixes.gate else None,
            max_consecutive_rejections=cfg.fixes.max_consecutive_rejections)),
        tag_corrector=tags,
        tag_fallback=(TagCorrector(replace(tags.params, strategy="paper"))
                      if cfg.tags.strategy == "kalman" else None),
        range_params=RangeParams(gate_probability=cfg.gate_probability),
        path_loss=path_loss,
        channel_estimator=(ChannelEstimator(params_of(ChannelEstimatorParams, cfg.rss.channel))
                           if cfg.rss.estimate_channel and has_imu else None),
    )


GRID_MIN_ANCHORS = 3
"""Fewest positioned anchors the grid stage (:mod:`hrtls.pipeline.grid_stage`) runs with."""


def grid_anchors(config: TrackerConfig, landmarks: dict[str, Landmark], *, has_imu: bool
                 ) -> dict[str, Landmark]:
    """The anchors of the grid stage; empty when the stage does not run for this session."""
    anchors = {k: lm for k, lm in landmarks.items()
               if lm.kind in ("anchor", "beacon") and lm.position is not None}
    on = not has_imu and config.prediction.no_imu == "grid" and \
        config.rss.mode != "off" and len(anchors) >= GRID_MIN_ANCHORS
    return anchors if on else {}


def unknown_start(config: TrackerConfig, landmarks: dict[str, Landmark], notes: Notes, *,
                  has_imu: bool = True) -> StartPose:
    """The prior of a session without a start pose.

    With positioned anchors for an enabled RSS or range correction, the agent is somewhere
    among them: their centroid with a 1-sigma of their RMS spread (at least 1 m), so the
    infrastructure places it and the early rows show how little is known. Otherwise the
    origin of the local frame with :class:`StartPose`'s default uncertainty. ``has_imu``: when
    False the grid stage may publish the rows instead (the note says which start is used).
    """
    kinds = (("anchor", "beacon") if config.rss.mode != "off" else ()) + \
        (("node",) if config.ranges.enabled else ())
    xy = np.array([lm.position[:2] for lm in landmarks.values()
                   if lm.kind in kinds and lm.position is not None], dtype=np.float64)
    if len(xy) < 3:
        return StartPose()
    centre = xy.mean(axis=0)
    spread = max(float(np.sqrt(np.mean(np.sum((xy - centre) ** 2, axis=1)))), 1.0)
    prior = (f"the centroid of {len(xy)} anchors ({centre[0]:.1f}, {centre[1]:.1f}) m with "
             f"1-sigma {spread:.1f} m")
    if grid_anchors(config, landmarks, has_imu=has_imu):
        notes.add(f"no start pose: the grid filter starts from the first scan's likelihood; "
                  f"{prior} is the prior of the Kalman track, used only if the grid filter "
                  "steps aside")
    else:
        notes.add(f"no start pose: starting at {prior}, until the infrastructure places the "
                  "agent")
    return StartPose(x=float(centre[0]), y=float(centre[1]), sigma_xy_m=spread)


def kernel_params(config: TrackerConfig, parts: Corrections, *, floor_height_m: float,
                  heading_known: bool, yaw_relative: bool, has_imu: bool) -> np.ndarray:
    """Parameter record of the compiled event loop (see :mod:`hrtls.pipeline._events`)."""
    cfg = config
    return ev.loop_params(
        step=parts.step_predictor.params, path_loss=parts.path_loss,
        range_params=parts.range_params,
        channel=None if parts.channel_estimator is None else parts.channel_estimator.params,
        random_walk=parts.random_walk, floor_snap=cfg.floor_snap,
        floor_height_m=floor_height_m, floor_sigma_m=cfg.floor_sigma_m,
        flight=params_of(FlightParams, cfg.floor_flight),
        gate_probability=cfg.gate_probability, heading_known=heading_known,
        yaw_relative=yaw_relative, has_imu=has_imu, rss_min_distance_m=cfg.rss.min_distance_m,
        scan_jump=cfg.rss.mode == "wls", scan_wls_covariance=cfg.rss.use_wls_covariance,
        scan_sigma_position_m=cfg.rss.sigma_position_m)
