"""Tracker configuration: which attitude filter, gait methods, prediction and corrections.

A configuration is a TOML file or one of the named presets (``presets/*.toml``). Every section
and key is optional; unknown keys are an error, so a typo never silently falls back to a default.

Defaults live in one place each: the fields below, or -- for the sub-tables that configure one
component (``[attitude.quat_ekf]``, ``[rss.channel]``, ``[prediction.random_walk]``,
``[prediction.step_scale]``, ...) -- the component's parameter dataclass, whose fields the
sub-table holds 1:1. ``TrackerConfig()`` is the ``default`` preset; ``hrtls config show`` prints
the complete effective configuration (every key with its value).
"""

from __future__ import annotations

import dataclasses
import functools
import tomllib
import warnings
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)

from hrtls.attitude.complementary import ComplementaryParams
from hrtls.attitude.euler_ekf import EulerEkfParams
from hrtls.attitude.inertial_lowpass import InertialLowpassParams
from hrtls.attitude.quat_ekf import QuatEkfParams
from hrtls.errors import FormatError, InputError
from hrtls.fusion.channel import ChannelEstimatorParams
from hrtls.fusion.floors import FlightParams
from hrtls.fusion.radio_map import RadioMapParams
from hrtls.fusion.random_walk import RandomWalkParams
from hrtls.fusion.rss_grid import GridParams
from hrtls.gait.stairs_climb import ClimbParams
from hrtls.pipeline.mag_heading import MagHeadingParams
from hrtls.pipeline.step_scale import StepScaleParams


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


@functools.cache
def _adapter(params_type: type) -> TypeAdapter[Any]:
    """The validator of a parameter dataclass (built once: building one costs milliseconds)."""
    return TypeAdapter(params_type)


_RENAMED_KEYS: dict[type, dict[str, str]] = {
    RandomWalkParams: {"sigma_speed_m_s": "sigma_speed_m_per_sqrt_s"},
    GridParams: {"sigma_speed_m_s": "sigma_speed_m_per_sqrt_s"},
}
"""Old key -> new key of each parameter table (the old key still read, with a warning)."""


def _renamed(params_type: type, value: dict[str, Any]) -> dict[str, Any]:
    """``value`` with its deprecated keys under their new names (warns about each)."""
    out = dict(value)
    for old, new in _RENAMED_KEYS.get(params_type, {}).items():
        if old not in out:
            continue
        if new in out:
            raise ValueError(f"both {old!r} and {new!r} given (keep {new!r})")
        warnings.warn(f"{params_type.__name__}: key {old!r} is deprecated, use {new!r}",
                      FutureWarning, stacklevel=2)
        out[new] = out.pop(old)
    return out


def _complete(params_type: type, value: object) -> dict[str, Any]:
    """Every field of ``params_type`` (defaults filled in), validated by the dataclass."""
    if not isinstance(value, dict):
        raise ValueError(f"a table of {params_type.__name__} keys expected")
    value = _renamed(params_type, value)
    names = [f.name for f in dataclasses.fields(params_type) if f.init]
    unknown = sorted(set(value) - set(names))
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r} (keys: {', '.join(names)})")
    try:
        params: Any = _adapter(params_type).validate_python(value)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ValueError(f"{'.'.join(str(p) for p in err['loc'])}: {err['msg']}") from None
    except InputError as exc:
        raise ValueError(str(exc)) from None
    return {n: getattr(params, n) for n in names}


def params_of(params_type: type[Any], table: dict[str, Any]) -> Any:
    """The parameter dataclass of a completed sub-table."""
    return params_type(**table)


def _table(params_type: type) -> Any:
    """A sub-table field holding the keys of ``params_type`` (defaults from the dataclass)."""
    return Field(default_factory=lambda: _complete(params_type, {}),
                 description=f"the fields of {params_type.__module__}.{params_type.__name__}")


class AttitudeConfig(_Section):
    """Orientation source."""

    method: Literal["auto", "euler-ekf", "quat-ekf", "complementary", "inertial-lp", "device",
                    "none"] = "auto"
    """``auto``: the device's own orientation when the session has one, else
    :data:`hrtls.attitude.registry.DEFAULT_FILTER` (``inertial-lp``)."""
    use_magnetometer: bool = True
    compass_yaw: bool = Field(
        default=True, description="remove the device orientation's slow yaw wander with the "
        "magnetometer (self-calibrated hard iron; our addition, see pipeline.compass); only "
        "with method device (our filters fuse the magnetometer themselves)")
    mounting: Literal["auto", "session", "handheld"] = "auto"
    """Device->body mounting: ``session`` uses ``meta.mounting_q_bd`` (unknown when unset);
    ``handheld`` estimates it for a phone held in front in portrait (top edge forward) from
    the mean specific force (:func:`hrtls.pipeline.mounting.handheld_mounting_q_bd`);
    ``auto`` is ``handheld`` when ``meta.placement`` says the device is held in the hand
    (e.g. IPIN logs) or when the placement is not declared and the first samples look like a
    phone held in front (``handheld_screen_tilt_deg``), else ``session``."""
    handheld_screen_tilt_deg: tuple[float, float] = Field(
        default=(14.0, 66.0), description="auto mounting, placement not declared: a mean "
        "screen-normal tilt from the vertical in this range (deg, portrait, top edge up) marks "
        "a phone held in front (pipeline.mounting.looks_handheld)")
    mounting_window_s: float = Field(
        default=10.0, gt=0.0, description="handheld mounting: seconds of accelerometer from "
        "the start pose over which the mean specific force gives the mounting; the gait stage "
        "starts once they have arrived (its steps are released then)")
    mag_hard_iron: Literal["off", "fit"] = "fit"
    """``fit``: estimate the magnetometer's hard-iron offset from the walk's own turns as the
    samples arrive (:mod:`hrtls.calibration.hard_iron_running`, our addition) and subtract it
    before the attitude stage from the time a fit is accepted (the field is used raw before);
    for devices never calibrated with a figure of eight (Inderst App. B)."""
    heading_source: Literal["filter", "gyro+compass"] = "filter"
    """``filter``: the step headings from the attitude filter (with the magnetometer when
    ``use_magnetometer``); ``gyro+compass``: the filter runs without the magnetometer and the
    magnetic heading is an absolute measurement of the state heading
    (:mod:`hrtls.pipeline.mag_heading`, needs ``[prediction] heading_mode = "state"``)."""
    mag_heading: dict[str, Any] = _table(MagHeadingParams)
    """The magnetic heading measurement (:class:`hrtls.pipeline.mag_heading.MagHeadingParams`)."""
    quat_ekf: dict[str, Any] = _table(QuatEkfParams)
    euler_ekf: dict[str, Any] = _table(EulerEkfParams)
    complementary: dict[str, Any] = _table(ComplementaryParams)
    inertial_lp: dict[str, Any] = _table(InertialLowpassParams)

    _complete_mag_heading = field_validator("mag_heading")(
        lambda v: _complete(MagHeadingParams, v))
    _complete_quat_ekf = field_validator("quat_ekf")(
        lambda v: _complete(QuatEkfParams, v))
    _complete_euler_ekf = field_validator("euler_ekf")(
        lambda v: _complete(EulerEkfParams, v))
    _complete_complementary = field_validator("complementary")(
        lambda v: _complete(ComplementaryParams, v))
    _complete_inertial_lp = field_validator("inertial_lp")(
        lambda v: _complete(InertialLowpassParams, v))

    def filter_params(self, method: str) -> Any:
        """The parameter dataclass of a sensor-fusion filter (``[attitude.<method>]``)."""
        kinds = {"quat-ekf": (QuatEkfParams, self.quat_ekf),
                 "euler-ekf": (EulerEkfParams, self.euler_ekf),
                 "complementary": (ComplementaryParams, self.complementary),
                 "inertial-lp": (InertialLowpassParams, self.inertial_lp)}
        params_type, table = kinds[method]
        return params_of(params_type, table)


class GaitConfig(_Section):
    """Steps, step length, walking direction, activity and walking velocity."""

    step_detector: Literal["peak", "pll"] = "peak"
    step_length: Literal["weinberg", "frequency", "pendulum"] = "weinberg"
    """weinberg (Tarrio eq. 3), frequency (Basso II-D) or pendulum (inverted pendulum, from the
    step's vertical excursion); the user's profile is used when it has the same kind."""
    weinberg_k: float | None = Field(default=None, gt=0.0,
                                     description="overrides the user's profile")
    heading: Literal["yaw", "fourier"] = "yaw"
    step_yaw: Literal["endpoints", "mean", "turns"] = "turns"
    """with heading = "yaw": circular mean of the yaw at step start and end, its time average
    over the step (follows a turn made during the step), or the average for turning steps only"""
    activity: Literal["lda", "tree", "motion"] = "motion"
    velocity_automaton: bool = False
    gate_steps_with_motion: bool = False
    walking_bouts: bool = False
    """drop steps outside walking bouts of >= 3 steps with gaps <= 2 s
    (:mod:`hrtls.gait.walking_bouts`); with activity = "motion" the bouts also decide walking
    vs standing. Adds up to about 4 s of step latency."""
    fill_missed_steps: bool = False
    """insert one step in a gap of 1.6-2.4 local step periods (:mod:`hrtls.gait.missed_steps`)"""
    drop_weak_walks: bool = True
    """with the peak detector: drop the steps of walks of fewer than 3 steps without a peak of
    0.8 m/s^2 (a shift of weight while standing) and a walk's last step under 0.6 of its
    peaks when 3 s of standing follow (the closing movement; :mod:`hrtls.gait.walk_steps`);
    such steps wait up to about 4 s for the decision"""
    climb_stairs: bool = True
    """with activity = "motion": label walking steps whose vertical climb is a stair's
    upstairs / downstairs (:mod:`hrtls.gait.stairs_climb`), when the device's placement is one
    of ``climb_placements``"""
    climb_placements: list[str] = ["belt", "waist", "lower back"]
    """placements fixed to the trunk: a phone in a hand, pocket or bag moves on its own, and
    its vertical motion labelled stairs on real flat walks (docs/real-data.md)"""
    climb: dict[str, Any] = _table(ClimbParams)
    """The climb detector (:class:`hrtls.gait.stairs_climb.ClimbParams`)."""

    _complete_climb = field_validator("climb")(lambda v: _complete(ClimbParams, v))


class PredictionConfig(_Section):
    """How the position is predicted between corrections."""

    model: Literal["step", "velocity"] = "step"
    heading_mode: Literal["input", "state"] = "state"
    q_along: float = Field(default=0.01, ge=0.0)
    q_across: float = Field(default=0.0025, ge=0.0)
    sigma_heading_increment_rad: float = Field(default=0.01, ge=0.0)
    stairs_from_model: bool = True
    learn_step_scale: bool = Field(
        default=True, description="learn a step-length scale from absolute corrections")
    step_scale: dict[str, Any] = _table(StepScaleParams)
    """How the step-length scale is learned (:class:`hrtls.pipeline.step_scale.StepScaleParams`)."""
    no_imu: Literal["grid", "random-walk"] = "grid"
    """Sessions with beacon RSS but no IMU: the grid filter (:mod:`hrtls.pipeline.grid_stage`)
    or the Kalman filter with a random-walk prediction"""
    random_walk: dict[str, Any] = _table(RandomWalkParams)
    """Prediction without an IMU (:class:`hrtls.fusion.random_walk.RandomWalkParams`)."""
    grid: dict[str, Any] = _table(GridParams)
    """The grid filter without an IMU (:class:`hrtls.fusion.rss_grid.GridParams`)."""
    radio_map: dict[str, Any] = _table(RadioMapParams)
    """The grid filter's radio map from a survey file (:mod:`hrtls.fusion.radio_map`)."""

    _complete_step_scale = field_validator("step_scale")(
        lambda v: _complete(StepScaleParams, v))
    _complete_random_walk = field_validator("random_walk")(
        lambda v: _complete(RandomWalkParams, v))
    _complete_grid = field_validator("grid")(lambda v: _complete(GridParams, v))
    _complete_radio_map = field_validator("radio_map")(lambda v: _complete(RadioMapParams, v))


class FixesConfig(_Section):
    """External position fixes (Colombo eq. 18-23) and the yaw stretching (eq. 24-28)."""

    enabled: bool = True
    period_s: float = Field(default=1.0, gt=0.0, description="update period Tp")
    require_motion: bool = False
    yaw_stretch: bool = True
    max_consecutive_rejections: int = Field(
        default=1, ge=0, description="after this many gated fixes in a row, apply the next one")
    yaw_feedback_gain: float = Field(
        default=1.0, ge=0.0, le=1.0,
        description="fraction of each stretching yaw correction fed back to later yaw inputs")
    gate: bool = Field(
        default=True, description="chi-square gate on fixes (the paper's eq. 20-22 have none)")
    drift_fraction: float = Field(
        default=0.1, ge=0.0, le=1.0,
        description="dead-reckoning drift per metre walked since the last fix, added as "
                    "position variance (f L)^2 before a fix's gate and update, and as shape "
                    "uncertainty to the stretching yaw's variance (our addition)")
    yaw_feedback: Literal["gain", "kalman"] = Field(
        default="kalman",
        description="gain: add yaw_feedback_gain x the stretching correction; kalman: weigh "
                    "it by the state heading variance against the pseudo-measurement's "
                    "(a scalar Kalman update of the heading, like eq. 8-9 with eta_z)")
    partial_step: bool = Field(
        default=True,
        description="step model: compare a fix with the state plus the part of the step in "
                    "progress at the fix time (our addition)")


class RssConfig(_Section):
    """Beacon RSS: off, WLS positions alone, Tarrio's Kalman fusion, or tight range updates."""

    mode: Literal["off", "wls", "kalman", "tight"] = "tight"
    window_s: float = Field(default=2.0, gt=0.0, description="scan grouping window")
    average_s: float = Field(
        default=0.0, ge=0.0, description="tight mode: mean RSS per beacon over windows of "
        "this length before the update (readings of one beacon share their shadowing); "
        "0 = every reading")
    shadowing_time_s: float = Field(
        default=1.0, ge=0.0, description="tight mode: correlation time of a beacon's shadowing "
        "error (AR(1)); a reading dt after the previous one of its beacon counts as "
        "(1 - rho) / (1 + rho) of an independent one, rho = exp(-dt / shadowing_time_s); "
        "0 = independent readings")
    estimate_channel: bool = True
    sensitivity_dbm: float = -100.0
    use_wls_covariance: bool = True
    sigma_position_m: float = Field(default=2.0, gt=0.0,
                                    description="Tarrio's sigma_p when not using the WLS cov.")
    min_distance_m: float = Field(
        default=0.5, ge=0.0, description="tight mode: no update when the estimate is nearer "
        "than this to the beacon")
    channel: dict[str, Any] = _table(ChannelEstimatorParams)
    """Online channel estimation (:class:`hrtls.fusion.channel.ChannelEstimatorParams`)."""

    _complete_channel = field_validator("channel")(
        lambda v: _complete(ChannelEstimatorParams, v))


class TagsConfig(_Section):
    """Passive tags (Inderst Sec. 4.3.2) and heading from their bearings (Sec. 4.2.3)."""

    enabled: bool = True
    strategy: Literal["paper", "kalman"] = "kalman"
    bearing_correction: bool = True
    sigma_per_accuracy: float = Field(default=0.5, gt=0.0,
                                      description="kappa: lobe 1-sigma per accuracy radius")
    repeat_interval_s: float = Field(default=2.0, ge=0.0)
    bearing_gate_deg: float = Field(default=45.0, gt=0.0, le=180.0)
    bearing_deadband_deg: float = Field(default=5.0, ge=0.0)
    bearing_mode: Literal["replace", "kalman"] = "kalman"
    bearing_confirm_s: float = Field(
        default=1.0, ge=0.0,
        description="wait this long after a read and skip its bearing if the user turned")
    bearing_max_turn_deg: float = Field(
        default=10.0, gt=0.0, description="no bearing correction while turning more than this")
    bearing_sigma_deg: float = Field(default=5.0, gt=0.0)


class RangesConfig(_Section):
    """Ranges to known radio nodes by EKF (Inderst Sec. 4.3.3)."""

    enabled: bool = True


class OfflineConfig(_Section):
    """Refinements that need the whole recording (offline only, never on the live path)."""

    two_pass: bool = Field(
        default=False, description="Tracker.run only: fit the hard iron and the hand-held "
        "mounting on the whole recording first, then track with them fixed")
    grid_smoother: bool = Field(
        default=False, description="Tracker.run only: RSS without an IMU (the grid filter): "
        "rows of the forward-backward smoother of the grid density "
        "(hrtls.fusion.rss_grid_smoother; each row uses the readings after it too)")

    @property
    def whole_recording(self) -> bool:
        """Whether an option needs the whole recording (:meth:`Tracker.run`, not chunks)."""
        return self.two_pass or self.grid_smoother


class TrackerConfig(_Section):
    """The whole tracker."""

    name: str = "default"
    description: str = ("device orientation when recorded else quaternion EKF with gates, peak "
                        "steps, Weinberg length, motion-gated activity, heading in the filter "
                        "state, every correction")
    attitude: AttitudeConfig = AttitudeConfig()
    gait: GaitConfig = GaitConfig()
    prediction: PredictionConfig = PredictionConfig()
    fixes: FixesConfig = FixesConfig()
    rss: RssConfig = RssConfig()
    tags: TagsConfig = TagsConfig()
    ranges: RangesConfig = RangesConfig()
    offline: OfflineConfig = OfflineConfig()
    gate_probability: float = Field(default=0.997, gt=0.5, lt=1.0)
    floor_snap: bool = True
    floor_sigma_m: float = Field(default=0.1, gt=0.0, description="1-sigma of the floor-level "
                                 "pseudo-measurement after a flat step")
    floor_flight: dict[str, Any] = _table(FlightParams)
    """When a stairs flight changes the floor (:class:`hrtls.fusion.floors.FlightParams`)."""
    barometer: bool = Field(default=True, description="heights and floors from the "
                            "recording's barometer when it has one (hrtls.pipeline.barometric)")

    @model_validator(mode="after")
    def _compass_needs_state_heading(self) -> TrackerConfig:
        if self.attitude.heading_source == "gyro+compass" and \
                self.prediction.heading_mode != "state":
            raise ValueError('attitude.heading_source = "gyro+compass" needs '
                             'prediction.heading_mode = "state"')
        return self


PRESETS = ("default", "colombo2014", "basso2017", "tarrio2011", "inderst-rfid", "inderst-range",
           "handheld-phone", "rescue-mission")
"""Named configurations shipped in ``hrtls/pipeline/presets``."""


def _validate(data: dict[str, object], *, where: str) -> TrackerConfig:
    try:
        return TrackerConfig.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        raise FormatError(f"{loc}: {err['msg']}", where=where,
                          expected="a tracker configuration (see the presets)") from None


def load_config(path: Path) -> TrackerConfig:
    """Read a TOML configuration file (a relative survey path: to the file's folder)."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("no such file", where=str(path), expected="a TOML file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise FormatError(str(exc), where=str(path), expected="valid TOML") from None
    cfg = _validate(data, where=str(path))
    radio_map = cfg.prediction.radio_map
    if radio_map["survey"] and not Path(radio_map["survey"]).is_absolute():
        radio_map["survey"] = str(Path(path).parent / radio_map["survey"])
    return cfg


def preset(name: str) -> TrackerConfig:
    """A named preset (``default``, ``colombo2014``, ``basso2017``, ``tarrio2011``, ...)."""
    if name not in PRESETS:
        raise InputError(f"unknown preset {name!r}", where="--preset",
                         expected=" | ".join(PRESETS))
    text = resources.files("hrtls.pipeline").joinpath("presets", f"{name}.toml").read_text(
        encoding="utf-8")
    return _validate(tomllib.loads(text), where=f"preset {name}")


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise InputError(f"a {type(value).__name__}", where="to_toml", expected="a TOML scalar")


def to_toml(config: TrackerConfig) -> str:
    """The complete effective configuration as TOML (``load_config`` reads it back).

    Every key is written with its value (unset optional keys, e.g. ``weinberg_k``, are written
    as comments: TOML has no null); sub-tables follow their table.
    """
    out: list[str] = []

    def table(path: str, values: dict[str, Any]) -> None:
        if path:
            out.append(f"[{path}]")
        for k, v in values.items():
            if not isinstance(v, dict):
                out.append(f"# {k} = (not set)" if v is None else f"{k} = {_toml_value(v)}")
        out.append("")
        for k, v in values.items():
            if isinstance(v, dict):
                table(f"{path}.{k}" if path else k, v)

    table("", config.model_dump(mode="json"))
    return "\n".join(out)
