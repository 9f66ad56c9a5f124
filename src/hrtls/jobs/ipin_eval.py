"""IPIN 2023 track 3 (hand-held phone): set-up, landmark errors and the configurations compared.

The competition gives, per logfile, the start position (first ``POSI``, heading unknown), later
``POSI`` landmarks as ground truth, and beacon positions. What a competitor may also know and
this module uses:

* the phone is held in front of the body in portrait (the competition's annex), so the walking
  direction is the top edge of the phone (device +y) made horizontal. :func:`handheld_mounting_q_bd`
  builds the fixed device->body rotation from the *mean* gravity direction in the device frame
  over the recording (no ground truth involved). With it, an attitude filter that uses the
  magnetometer (or the phone's own AHRS, which does) gives an absolute walking heading, and the
  tracker's ``state`` heading mode adopts the first step's heading as the unknown start heading;
* the floor of the start (first ``POSI``): BLE readings of beacons listed on other floors can be
  dropped (:func:`prepare_session` ``rss_floors="same"``), since the slab between floors breaks
  any single path-loss law;
* a step-length constant and a path-loss law may be calibrated on one file and used on
  another (:func:`calibrate_weinberg_k`, :func:`calibrate_channel`,
  :func:`run_cross_validated`);
* consecutive readings of one beacon share their shadowing error, so they may be averaged per
  beacon over a few seconds before they reach the filter (:func:`average_rss`).

Errors are horizontal distances at the landmark times (:func:`landmark_errors`); the
trajectory is interpolated, and held at its ends for landmarks outside its time span, so every
landmark counts. Floors are scored as hits (``round(z / floor_height)`` equal to the landmark's
floor). The competition's figure is the 75th percentile of the errors (IPIN adds 15 m per
missed floor; with every floor hit the two agree).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from hrtls.calibration.channel import survey_path_loss
from hrtls.data import (
    ChannelModel,
    Checkpoints,
    OrientationSeries,
    RssReadings,
    Session,
    Trajectory,
)
from hrtls.errors import InputError
from hrtls.evaluate.metrics import ErrorStats, checkpoint_errors, error_stats, estimate_at
from hrtls.frames import quat_multiply
from hrtls.fusion.rss_scans import average_rss_per_anchor
from hrtls.gait.step_length import WeinbergModel
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.finish import finish_track
from hrtls.pipeline.mounting import handheld_mounting_q_bd
from hrtls.pipeline.tracker import Tracker, TrackResult

FloatArray = NDArray[np.float64]

REFERENCE_P75_M = 4.43
"""75th-percentile error of the best IPIN 2021 smartphone-track entry, m."""
TARGET_P75_M = 4.0
"""Our aim for the 75th-percentile landmark error, m."""
FLOOR_PENALTY_M = 15.0
"""IPIN competition penalty per missed floor, m."""
DECLINATION_DEG = 4.0
"""Approximate magnetic declination at Nuremberg in 2023, deg east (not applied by default)."""

Mounting = Literal["handheld", "unknown"]
RssFloors = Literal["same", "all"]


def start_floor(session: Session) -> int:
    """Floor number of the start pose (``round(z / floor_height_m)``)."""
    pose = session.meta.start_pose
    if pose is None:
        raise InputError("no start pose", where="session.meta.start_pose",
                         expected="an IPIN logfile with a first POSI")
    return round(pose.z / session.meta.floor_height_m)


def average_rss(rss: RssReadings, window_s: float) -> RssReadings:
    """One reading per anchor and window: the mean (dBm) of its readings in that window.

    Windows are ``[t0 + i w, t0 + (i + 1) w)`` from the first reading; each averaged reading is
    stamped with the time of the last reading it contains (it is known by then). Averaging
    tames the shadowing errors of consecutive readings, which are strongly correlated and
    would otherwise enter the filter as independent measurements.
    """
    return average_rss_per_anchor(rss, window_s)


def calibrate_channel(session: Session, *, rss_window_s: float = 0.0,
                      eta_bounds: tuple[float, float] = (1.0, 6.0)) -> ChannelModel:
    """Path-loss law fitted on a *training* file: ``rss = A - 10 eta log10(d)`` (Tarrio eq. 1).

    The positions at the reading times are interpolated linearly in time along start ->
    landmark 1 -> landmark 2 ... (readings outside that span are not used); ``d`` is the
    horizontal distance to the beacon. Only beacons on the start floor are used. Least squares
    for ``(A, eta)``; an ``eta`` outside ``eta_bounds`` is clamped and ``A`` refitted for it;
    ``sigma`` is the residual standard deviation. Use the result on other files only.
    """
    prepared = prepare_session(session, mounting="unknown", rss_floors="same",
                               rss_window_s=rss_window_s)
    rss, cps, pose = prepared.rss, session.checkpoints, session.meta.start_pose
    if rss is None or cps is None or pose is None:
        raise InputError("no RSS on the start floor, no landmarks or no start pose",
                         where="calibration session", expected="an IPIN session with BLE4")
    t_ref = np.concatenate([[float(session.meta.source.get("start_pose_t_s", cps.t[0]))],
                            cps.t])
    xy_ref = np.vstack([[pose.x, pose.y], cps.xyz[:, :2]])
    keep = (rss.t >= t_ref[0]) & (rss.t <= t_ref[-1])
    if int(keep.sum()) < 3:
        raise InputError(f"{int(keep.sum())} readings within the landmarks' time span",
                         where="calibration session", expected="at least 3")
    xy = np.column_stack([np.interp(rss.t[keep], t_ref, xy_ref[:, i]) for i in range(2)])
    return survey_path_loss(receiver_xy=xy, anchors=rss.anchor[keep].tolist(),
                            rss_dbm=rss.rss_dbm[keep], landmarks=session.landmarks,
                            eta_bounds=eta_bounds)


def prepare_session(session: Session, *, mounting: Mounting = "handheld",
                    rss_floors: RssFloors = "same", declination_rad: float = 0.0,
                    rss_window_s: float = 0.0, channel: ChannelModel | None = None
                    ) -> Session:
    """The session with the hand-held mounting and the RSS readings a competitor would use.

    Parameters
    ----------
    session:
        An IPIN session (``read_ipin(..., trim_to_start=True)``: the start pose holds at its
        first sample).
    mounting:
        ``"handheld"``: set ``meta.mounting_q_bd`` from :func:`handheld_mounting_q_bd`;
        ``"unknown"``: leave it unset (headings then come from the walking motion,
        :mod:`hrtls.gait.walking_direction`).
    rss_floors:
        ``"same"``: keep only readings of beacons on the start floor; ``"all"``: keep all.
    declination_rad:
        Magnetic declination (east positive). The device orientation (Android rotation
        vector: magnetic north) is turned onto true north: ``q_nd <- q_z(-D) q_nd`` (a magnetic
        bearing ``b`` is the true bearing ``b + D``; ENU yaw is ``90 deg - bearing``).
    rss_window_s:
        When > 0, average the RSS per beacon over windows of this length
        (:func:`average_rss`).
    channel:
        Path-loss model to put in ``meta.channel`` (e.g. :func:`calibrate_channel` on another
        file); None keeps the session's.
    """
    if mounting not in ("handheld", "unknown"):
        raise InputError(f"mounting {mounting!r}", where="mounting",
                         expected="'handheld' | 'unknown'")
    if rss_floors not in ("same", "all"):
        raise InputError(f"rss_floors {rss_floors!r}", where="rss_floors",
                         expected="'same' | 'all'")
    if not math.isfinite(declination_rad):
        raise InputError(f"{declination_rad}", where="declination_rad", expected="finite rad")
    if not (math.isfinite(rss_window_s) and rss_window_s >= 0):
        raise InputError(f"{rss_window_s}", where="rss_window_s", expected=">= 0 s")
    orientation = session.orientation
    if orientation is not None and declination_rad != 0.0:
        half = -0.5 * declination_rad
        q_z = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
        orientation = OrientationSeries(
            orientation.t, quat_multiply(np.broadcast_to(q_z, orientation.q.shape),
                                         orientation.q), orientation.name)
    meta = session.meta
    if mounting == "handheld":
        if session.imu is None:
            raise InputError("no IMU", where="session", expected="an accelerometer stream")
        q_bd = handheld_mounting_q_bd(session.imu.accel.values)
        meta = meta.model_copy(update={"mounting_q_bd": tuple(float(v) for v in q_bd)})
    else:
        meta = meta.model_copy(update={"mounting_q_bd": None})
    rss = session.rss
    if rss is not None and rss_floors == "same":
        floor = start_floor(session)
        keep = np.array([a in session.landmarks and session.landmarks[a].floor == floor
                         for a in rss.anchor.tolist()], dtype=bool)
        rss = (RssReadings(rss.t[keep], rss.anchor[keep], rss.rss_dbm[keep], rss.name)
               if keep.any() else None)
    if rss is not None and rss_window_s > 0:
        rss = average_rss(rss, rss_window_s)
    if channel is not None:
        meta = meta.model_copy(update={"channel": channel})
    return dataclasses.replace(session, meta=meta, rss=rss, orientation=orientation)


@dataclass(frozen=True, slots=True, eq=False)
class LandmarkErrors:
    """Errors at the ground-truth landmarks.

    Attributes
    ----------
    t: landmark times, s.
    label: landmark labels (POSI counters).
    horizontal_m: horizontal distance estimate - landmark, m.
    floor_estimated: ``round(z / floor_height)`` of the estimate.
    floor_true: floor of the landmark.
    """

    t: FloatArray
    label: NDArray[np.str_]
    horizontal_m: FloatArray
    floor_estimated: NDArray[np.int64]
    floor_true: NDArray[np.int64]

    @property
    def stats(self) -> ErrorStats:
        """Mean, median, 75th percentile, ... of the horizontal errors."""
        return error_stats(self.horizontal_m)

    @property
    def floor_hits(self) -> int:
        """Landmarks whose floor was estimated right."""
        return int(np.sum(self.floor_estimated == self.floor_true))

    @property
    def ipin_errors_m(self) -> FloatArray:
        """Competition errors: horizontal + 15 m per missed floor."""
        return self.horizontal_m + FLOOR_PENALTY_M * np.abs(
            self.floor_estimated - self.floor_true)


def landmark_errors(trajectory: Trajectory, checkpoints: Checkpoints, *,
                    floor_height_m: float) -> LandmarkErrors:
    """Errors of a trajectory at every landmark (held at the ends of the trajectory)."""
    if len(trajectory) == 0:
        raise InputError("empty trajectory", where="trajectory", expected="at least one row")
    if not (math.isfinite(floor_height_m) and floor_height_m > 0):
        raise InputError(f"{floor_height_m}", where="floor_height_m", expected="> 0 (m)")
    est = estimate_at(trajectory, checkpoints.t)
    t, horizontal_m, label = checkpoint_errors(trajectory, checkpoints)
    return LandmarkErrors(
        t=np.asarray(t, dtype=np.float64), label=np.asarray(label, dtype=np.str_),
        horizontal_m=horizontal_m,
        floor_estimated=np.rint(est[:, 2] / floor_height_m).astype(np.int64),
        floor_true=np.rint(checkpoints.xyz[:, 2] / floor_height_m).astype(np.int64))


def landmark_path_length_m(session: Session) -> float:
    """Length of the polyline start -> landmark 1 -> landmark 2 ... (horizontal), m.

    A lower bound of the walked distance (the path between landmarks need not be straight).
    """
    if session.checkpoints is None or session.meta.start_pose is None:
        raise InputError("no landmarks or no start pose", where="session",
                         expected="an IPIN session with POSI records")
    pose = session.meta.start_pose
    xy = np.vstack([[pose.x, pose.y], session.checkpoints.xyz[:, :2]])
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))


def weinberg_k_of(config: TrackerConfig) -> float:
    """The Weinberg constant a configuration uses (its override, else the model default)."""
    k = config.gait.weinberg_k
    return float(k) if k is not None else WeinbergModel().k


def calibrate_weinberg_k(session: Session, config: TrackerConfig) -> float:
    """Weinberg constant that makes the walked distance equal the landmark path length.

    Calibration on a *training* file: ``k * L_landmarks / L_walked``. Use the result on other
    files only.
    """
    if config.gait.step_length != "weinberg":
        raise InputError(f"step_length {config.gait.step_length!r}", where="config.gait",
                         expected="'weinberg'")
    result = Tracker(config).run(session)
    walked = float(result.steps.distance_m)
    if not walked > 0:
        raise InputError("no steps detected", where="calibration session",
                         expected="a walk with detected steps")
    return weinberg_k_of(config) * landmark_path_length_m(session) / walked


@dataclass(frozen=True, slots=True)
class IpinCase:
    """One configuration compared in the benchmark."""

    name: str
    config: TrackerConfig
    mounting: Mounting = "handheld"
    rss_floors: RssFloors = "same"
    declination_rad: float = 0.0
    rss_window_s: float = 0.0
    channel_from_other: bool = False


def make_config(*, attitude: str = "device", rss: str = "off", heading_mode: str = "state",
                estimate_channel: bool = True, weinberg_k: float | None = None,
                activity: str = "tree", heading: str = "yaw",
                name: str = "ipin") -> TrackerConfig:
    """A tracker configuration for a hand-held phone (no fixes, tags or ranges)."""
    gait: dict[str, Any] = {"heading": heading, "activity": activity}
    if weinberg_k is not None:
        gait["weinberg_k"] = weinberg_k
    return TrackerConfig.model_validate({
        # the mounting is the case's (prepare_session), not the reader's placement
        "name": name, "attitude": {"method": attitude, "mounting": "session"}, "gait": gait,
        "prediction": {"heading_mode": heading_mode},
        "rss": {"mode": rss, "estimate_channel": estimate_channel},
        "fixes": {"enabled": False}, "tags": {"enabled": False}, "ranges": {"enabled": False}})


def standard_cases(weinberg_k: float | None = None) -> list[IpinCase]:
    """The configurations of the benchmark table (PDR, + device AHRS, + BLE RSS)."""
    def cfg(name: str, **kw: Any) -> TrackerConfig:
        return make_config(name=name, weinberg_k=weinberg_k, **kw)

    return [
        IpinCase("PDR quat-EKF, mounting unknown",
                 cfg("pdr-qekf-unknown", attitude="quat-ekf"), mounting="unknown"),
        IpinCase("PDR device AHRS, mounting unknown", cfg("pdr-device-unknown"),
                 mounting="unknown"),
        IpinCase("PDR device + Fourier heading, mounting unknown",
                 cfg("pdr-device-fourier", heading="fourier"), mounting="unknown"),
        IpinCase("PDR device + Fourier + RSS tight, mounting unknown",
                 cfg("tight-device-fourier", heading="fourier", rss="tight"),
                 mounting="unknown"),
        IpinCase("PDR quat-EKF, hand-held", cfg("pdr-qekf", attitude="quat-ekf")),
        IpinCase("PDR device AHRS, hand-held, LDA activity",
                 cfg("pdr-device-lda", activity="lda")),
        IpinCase("PDR device AHRS, hand-held", cfg("pdr-device")),
        IpinCase("PDR device AHRS, hand-held, declination 4 deg E",
                 cfg("pdr-device-declination"), declination_rad=math.radians(DECLINATION_DEG)),
        IpinCase("PDR device + RSS tight (online A, eta)", cfg("tight-device", rss="tight")),
        IpinCase("PDR device + RSS tight, fixed A, eta",
                 cfg("tight-device-fixed", rss="tight", estimate_channel=False)),
        IpinCase("PDR device + RSS tight, other file's channel",
                 cfg("tight-device-xcal", rss="tight", estimate_channel=False),
                 channel_from_other=True),
        IpinCase("PDR device + RSS tight, other's channel, 4 s mean",
                 cfg("tight-device-xcal-avg", rss="tight", estimate_channel=False),
                 channel_from_other=True, rss_window_s=4.0),
        IpinCase("PDR device + RSS tight, all floors' beacons",
                 cfg("tight-device-allfloors", rss="tight"), rss_floors="all"),
        IpinCase("PDR device + RSS Kalman (WLS)", cfg("kalman-device", rss="kalman")),
        IpinCase("PDR quat-EKF + RSS tight, mounting unknown",
                 cfg("tight-qekf-unknown", attitude="quat-ekf", rss="tight"),
                 mounting="unknown"),
    ]


@dataclass(frozen=True, slots=True, eq=False)
class CaseResult:
    """One file tracked with one case (``error`` set when the tracker failed)."""

    file: str
    case: str
    errors: LandmarkErrors | None
    result: TrackResult | None
    error: str | None = None
    weinberg_k: float | None = None
    channel: ChannelModel | None = None


def run_case(session: Session, case: IpinCase, *, file: str = "",
             channel: ChannelModel | None = None) -> CaseResult:
    """Prepare the session for the case, track it, score it at the landmarks.

    ``channel`` (e.g. calibrated on another file) goes into ``meta.channel``.
    """
    if session.checkpoints is None:
        raise InputError("no landmarks", where=file or "session",
                         expected="an IPIN session with POSI checkpoints")
    # a configuration that averages RSS itself ([rss] average_s) gets the raw readings
    window = 0.0 if case.config.rss.average_s > 0 else case.rss_window_s
    prepared = prepare_session(session, mounting=case.mounting, rss_floors=case.rss_floors,
                               declination_rad=case.declination_rad,
                               rss_window_s=window, channel=channel)
    try:
        result = finish_track(Tracker(case.config).run(prepared), prepared, case.config)
    except (InputError, ArithmeticError, ValueError) as exc:
        return CaseResult(file, case.name, None, None, f"{type(exc).__name__}: {exc}")
    errors = landmark_errors(result.trajectory, session.checkpoints,
                             floor_height_m=session.meta.floor_height_m)
    return CaseResult(file, case.name, errors, result, weinberg_k=weinberg_k_of(case.config),
                      channel=channel)


def with_weinberg_k(config: TrackerConfig, k: float | None) -> TrackerConfig:
    """The configuration with its Weinberg constant replaced (None: unchanged)."""
    if k is None:
        return config
    if not (math.isfinite(k) and k > 0):
        raise InputError(f"{k}", where="weinberg_k", expected="a positive constant")
    return config.model_copy(update={"gait": config.gait.model_copy(
        update={"weinberg_k": float(k)})})


def run_cross_validated(sessions: dict[str, Session], case: IpinCase) -> list[CaseResult]:
    """Track every file with the Weinberg constant calibrated on the *other* files.

    The constant is calibrated with the case's own configuration and session preparation
    (:func:`calibrate_weinberg_k`) on each other file and averaged; with one file the case's
    own constant is used. With ``case.channel_from_other`` the path-loss law is likewise
    calibrated on the other files (:func:`calibrate_channel`; A, eta, sigma averaged).
    """
    prepared = {n: prepare_session(s, mounting=case.mounting, rss_floors=case.rss_floors,
                                   declination_rad=case.declination_rad)
                for n, s in sessions.items()}
    channels: dict[str, ChannelModel] = {}
    if case.channel_from_other and len(sessions) > 1:
        channels = {n: calibrate_channel(s, rss_window_s=case.rss_window_s)
                    for n, s in sessions.items()}
    own: dict[str, float] = {}
    if case.config.gait.step_length == "weinberg" and len(sessions) > 1:
        own = {n: calibrate_weinberg_k(p, case.config) for n, p in prepared.items()}
    out = []
    for n, s in sessions.items():
        others = [k for m, k in own.items() if m != n]
        k = float(np.mean(others)) if others else None
        chans = [c for m, c in channels.items() if m != n]
        channel = None if not chans else ChannelModel(
            a_dbm=float(np.mean([c.a_dbm for c in chans])),
            eta=float(np.mean([c.eta for c in chans])),
            sigma_db=float(np.mean([c.sigma_db for c in chans])))
        out.append(run_case(s, dataclasses.replace(
            case, config=with_weinberg_k(case.config, k)), file=n, channel=channel))
    return out
