"""Mobilise-D lab recordings from mobgap: a lower-back IMU with gait references.

Source: the ``example_data/data/lab/`` folder of https://github.com/mobilise-d/mobgap (Apache
2.0). The folder layout is ``<cohort>/<id>/data.mat`` + ``infoForAlgo.mat`` (+
``test_list.json``), e.g. ``HA/001``. Nothing is downloaded here: pass the local folder.

What the loader does (all facts below are in ``shared/data/README.md``):

* Signals of ``data.TimeMeasure1.<Test>.<Trial>.SU.LowerBack`` are converted to SI: ``Acc`` from
  g to m/s^2 (x 9.80665), ``Gyr`` from deg/s to rad/s, ``Bar`` from hPa to Pa. They stay in the
  sensor's own frame (x up, y right, z forward); :data:`MOBGAP_Q_BD` rotates it into the hrtls
  body frame (x forward, y left, z up) and is stored as ``meta.mounting_q_bd``.
* ``Mag`` has no documented unit (its mean norm is 21, 67 and 255 for the three participants),
  so it is *not* put into the :class:`~hrtls.data.ImuStream` (which requires microtesla); the
  raw values are on :attr:`MobgapTrial.mag_unknown_unit` and ``meta.notes`` says so.
* Time: sample ``k`` is at ``k / Fs`` s from the trial start, the clock of the references. The
  loader checks that ``Timestamp - Timestamp[0]`` agrees within half a sample and stores
  ``Timestamp[0]`` (Unix s) as ``meta.time_origin_unix_s``.
* References (INDIP and Stereophoto) are flattened per system into a :class:`GaitReference`.
  ``Stride_InitialContacts`` is in samples for INDIP and in seconds for Stereophoto; both are
  returned in seconds. NaN in a reference array means the reference did not provide the value
  (a missed contact); it is kept so that indices still match the source.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy.io
from numpy.typing import NDArray

from hrtls.data import ImuStream, SensorSeries, Session, SessionMeta, UserProfile
from hrtls.datasets._common import FloatArray, dataset_dir, require_file
from hrtls.errors import FormatError, InputError
from hrtls.units import DEG, G_TO_M_S2, HPA_TO_PA

IntArray = NDArray[np.int64]

MOBGAP_Q_BD: tuple[float, float, float, float] = (0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5))
"""Mounting rotation ``q_bd`` from mobgap's sensor frame to the hrtls body frame.

Sensor axes: x up, y right, z forward. Body axes: x forward, y left, z up. Hence
``b_x = s_z``, ``b_y = -s_y``, ``b_z = s_x``, i.e. ``R_bd = [[0, 0, 1], [0, -1, 0], [1, 0, 0]]``:
a half turn about ``(1, 0, 1) / sqrt(2)``, quaternion ``[0, 1/sqrt(2), 0, 1/sqrt(2)]``.
"""

REFERENCE_SYSTEMS = ("INDIP", "Stereophoto")
"""Reference systems a mobgap lab trial may hold."""

BoutLevel = Literal["MicroWB", "ContinuousWalkingPeriod"]


@dataclass(frozen=True, slots=True, order=True)
class MobgapTrialId:
    """One trial: participant ``"HA/001"``, test ``"Test5"``, trial ``"Trial1"``."""

    participant: str
    test: str
    trial: str


@dataclass(frozen=True, slots=True, eq=False)
class GaitReference:
    """Gait reference of one system, flattened over its walking bouts.

    Every per-event array has a matching ``*_bout`` array with the bout index (0-based). Times
    are seconds from the trial start. NaN marks a value the reference did not provide.

    Attributes
    ----------
    system:
        ``"INDIP"`` or ``"Stereophoto"``.
    level:
        Which bout list was read: ``"MicroWB"`` (default) or ``"ContinuousWalkingPeriod"``.
    bout_start_s, bout_end_s:
        Bout limits, s, shape (K,).
    bout_cadence_spm:
        Cadence of each bout, steps per minute.
    bout_walking_speed_m_s, bout_length_m, bout_n_strides:
        Mean speed (m/s), walked distance (m) and stride count of each bout.
    initial_contacts_s, initial_contact_left, initial_contact_bout:
        Initial contacts (heel strikes), s; True for the left foot, False for the right;
        the bout of each contact.
    stride_start_s, stride_end_s, stride_length_m, stride_speed_m_s, stride_bout:
        Strides between two initial contacts of the same foot, s; length in m, speed in m/s.
    step_length_m, step_bout:
        Step lengths in m (Stereophoto only; INDIP does not report them, so they are empty).
    turn_start_s, turn_end_s, turn_angle_deg, turn_bout:
        Turns, s; the angle in degrees is signed. Stereophoto: positive is counter-clockwise
        seen from above (a left turn, like hrtls yaw), checked against the sensor's rotation
        about the vertical over the turn (29 of 30 Test11 turns agree; the exception is a
        61 deg turn of HA/002 where the sensor rotates 22 deg the other way). INDIP turns come
        from a lower-back IMU algorithm (mobgap documentation), not from an independent
        reference, and agree in sign for only 14 of 21. Turns are cut at the bout limits;
        mobgap scores only turns of at least 45 deg.
    """

    system: str
    level: str
    bout_start_s: FloatArray
    bout_end_s: FloatArray
    bout_cadence_spm: FloatArray
    bout_walking_speed_m_s: FloatArray
    bout_length_m: FloatArray
    bout_n_strides: IntArray
    initial_contacts_s: FloatArray
    initial_contact_left: NDArray[np.bool_]
    initial_contact_bout: IntArray
    stride_start_s: FloatArray
    stride_end_s: FloatArray
    stride_length_m: FloatArray
    stride_speed_m_s: FloatArray
    stride_bout: IntArray
    step_length_m: FloatArray
    step_bout: IntArray
    turn_start_s: FloatArray
    turn_end_s: FloatArray
    turn_angle_deg: FloatArray
    turn_bout: IntArray

    @property
    def n_bouts(self) -> int:
        """Number of walking bouts."""
        return len(self.bout_start_s)

    @property
    def is_empty(self) -> bool:
        """True when the system found no walking bout in this trial."""
        return self.n_bouts == 0

    @property
    def bouts_s(self) -> FloatArray:
        """Bout limits as (K, 2) ``[start_s, end_s]``."""
        return np.column_stack([self.bout_start_s, self.bout_end_s]).reshape(-1, 2)

    @property
    def strides(self) -> FloatArray:
        """Strides as (S, 4) ``[start_s, end_s, length_m, speed_m_s]``."""
        return np.column_stack([self.stride_start_s, self.stride_end_s, self.stride_length_m,
                                self.stride_speed_m_s]).reshape(-1, 4)

    @property
    def turns(self) -> FloatArray:
        """Turns as (T, 3) ``[start_s, end_s, angle_deg]`` (sign: see the class)."""
        return np.column_stack([self.turn_start_s, self.turn_end_s,
                                self.turn_angle_deg]).reshape(-1, 3)


@dataclass(frozen=True, slots=True)
class MobgapReference:
    """References of a trial; a system is None when the trial does not hold it at all."""

    indip: GaitReference | None
    stereophoto: GaitReference | None

    def get(self, system: str) -> GaitReference | None:
        """The reference of ``system`` (``"INDIP"`` or ``"Stereophoto"``, case-insensitive)."""
        key = system.lower()
        if key == "indip":
            return self.indip
        if key == "stereophoto":
            return self.stereophoto
        raise InputError(f"unknown reference system {system!r}", where="mobgap reference",
                         expected="INDIP or Stereophoto")


@dataclass(frozen=True, slots=True, eq=False)
class MobgapTrial:
    """One mobgap lab trial.

    Attributes
    ----------
    id:
        Participant, test and trial.
    session:
        IMU (accelerometer m/s^2, gyroscope rad/s, sensor frame) and pressure (Pa), metadata.
    reference:
        Gait references (INDIP, Stereophoto).
    mag_unknown_unit:
        Raw magnetometer samples (N, 3), sensor frame, unit unknown: not microtesla.
    sampling_rate_hz:
        Nominal sampling rate of the IMU, Hz.
    """

    id: MobgapTrialId
    session: Session
    reference: MobgapReference
    mag_unknown_unit: FloatArray
    sampling_rate_hz: float


# --------------------------------------------------------------------------------------------
# listing
# --------------------------------------------------------------------------------------------
def _participants(folder: Path) -> list[str]:
    found = sorted(p.parent.relative_to(folder).as_posix() for p in folder.glob("*/*/data.mat"))
    return found


def list_trials(root: str | Path) -> list[MobgapTrialId]:
    """All trials under ``root`` (the ``mobgap_lab`` folder, or a folder that contains it).

    Uses each participant's ``test_list.json`` when present, else opens ``data.mat``.
    """
    folder = dataset_dir(root, "mobgap_lab")
    out: list[MobgapTrialId] = []
    for participant in _participants(folder):
        listing = folder / participant / "test_list.json"
        if listing.is_file():
            try:
                content = json.loads(listing.read_text(encoding="utf-8"))
                keys = [entry["key"] for entry in content["data"]]
            except (ValueError, KeyError, TypeError) as exc:
                raise FormatError(f"unexpected content ({exc})", where=str(listing),
                                  expected='{"data": [{"key": [measure, test, trial]}, ...]}'
                                  ) from None
            out.extend(MobgapTrialId(participant, str(k[1]), str(k[2])) for k in keys)
        else:
            measure = _load_measure(folder / participant / "data.mat")
            for test in measure._fieldnames:
                out.extend(MobgapTrialId(participant, test, trial)
                           for trial in getattr(measure, test)._fieldnames)
    return out


# --------------------------------------------------------------------------------------------
# .mat helpers
# --------------------------------------------------------------------------------------------
def _load_measure(path: Path) -> Any:
    require_file(path, "a mobgap data.mat file")
    try:
        content = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
        return content["data"].TimeMeasure1
    except (KeyError, AttributeError, ValueError) as exc:
        raise FormatError(f"not a mobgap data file ({exc})", where=str(path),
                          expected="data.TimeMeasure1.<Test>.<Trial>") from None


def _field(node: Any, name: str, where: str) -> Any:
    if not hasattr(node, name):
        fields = getattr(node, "_fieldnames", [])
        raise FormatError(f"missing field {name!r}", where=where,
                          expected=f"one of {', '.join(fields)}" if fields else "a struct")
    return getattr(node, name)


def _vec(node: Any, name: str) -> FloatArray:
    """A numeric field as a 1-D float array (empty when the field is missing or empty)."""
    if not hasattr(node, name):
        return np.zeros(0)
    value = np.atleast_1d(np.asarray(getattr(node, name)))
    if value.size == 0:
        return np.zeros(0)
    try:
        return np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise FormatError(f"field {name!r} is not numeric", where="mobgap struct",
                          expected="numbers") from None


def _scalar(node: Any, name: str) -> float:
    value = _vec(node, name)
    return float(value[0]) if len(value) == 1 else math.nan


def _bout_list(node: Any) -> list[Any]:
    """A struct or an array of structs (one per bout), or an empty array, as a list."""
    if hasattr(node, "_fieldnames"):
        return [node]
    arr = np.asarray(node)
    if arr.size == 0:
        return []
    if arr.dtype == object:
        return list(arr.ravel())
    raise FormatError(f"bout list of dtype {arr.dtype}", where="mobgap reference",
                      expected="a struct or an array of structs")


def _sides(node: Any, count: int, where: str) -> NDArray[np.bool_]:
    if not hasattr(node, "InitialContact_LeftRight"):
        raise FormatError("missing InitialContact_LeftRight", where=where,
                          expected="Left/Right per initial contact")
    labels = [str(v).strip().lower() for v in
              np.atleast_1d(np.asarray(node.InitialContact_LeftRight, dtype=object)).ravel()]
    if len(labels) != count:
        raise FormatError(f"{len(labels)} side labels for {count} initial contacts", where=where,
                          expected="one Left/Right label per contact")
    bad = [s for s in labels if s not in ("left", "right")]
    if bad:
        raise FormatError(f"side label {bad[0]!r}", where=where, expected="'Left' or 'Right'")
    return np.array([s == "left" for s in labels], dtype=bool)


def _parse_reference(node: Any, system: str, level: str, fs_ref: float, where: str
                     ) -> GaitReference:
    bouts = _bout_list(_field(node, level, where))
    cols: dict[str, list[Any]] = {k: [] for k in (
        "bs", "be", "cad", "ws", "len", "ns", "ic", "icl", "icb", "ss", "se", "sl", "sv", "sb",
        "stl", "stb", "ts", "te", "ta", "tb")}
    for k, bout in enumerate(bouts):
        here = f"{where}.{level}[{k}]"
        start, end = _scalar(bout, "Start"), _scalar(bout, "End")
        if not (math.isfinite(start) and math.isfinite(end) and end >= start):
            raise FormatError(f"bout limits {start}..{end}", where=here,
                              expected="finite Start <= End in s")
        cols["bs"].append(start)
        cols["be"].append(end)
        cols["cad"].append(_scalar(bout, "Cadence"))
        cols["ws"].append(_scalar(bout, "WalkingSpeed"))
        cols["len"].append(_scalar(bout, "Length"))
        n_strides = _scalar(bout, "NumberStrides")
        cols["ns"].append(int(n_strides) if math.isfinite(n_strides) else -1)
        ic = _vec(bout, "InitialContact_Event")
        cols["ic"].append(ic)
        cols["icl"].append(_sides(bout, len(ic), here))
        cols["icb"].append(np.full(len(ic), k))
        # Stride_InitialContacts: samples for INDIP, seconds for Stereophoto (data README).
        sic = _vec(bout, "Stride_InitialContacts").reshape(-1, 2)
        if system == "INDIP":
            sic = sic / fs_ref
        finite = sic[np.isfinite(sic)]
        if finite.size and (finite.min() < start - 1.0 or finite.max() > end + 1.0):
            raise FormatError(
                f"stride contacts {finite.min():.3f}..{finite.max():.3f} s lie outside the bout "
                f"{start:.3f}..{end:.3f} s", where=f"{here}.Stride_InitialContacts",
                expected="samples for INDIP, seconds for Stereophoto")
        length = _vec(bout, "Stride_Length")
        speed = _vec(bout, "Stride_Speed")
        if len(length) != len(sic) or len(speed) not in (0, len(sic)):
            raise FormatError(f"{len(sic)} strides but {len(length)} lengths, {len(speed)} speeds",
                              where=here, expected="one length and speed per stride")
        cols["ss"].append(sic[:, 0])
        cols["se"].append(sic[:, 1])
        cols["sl"].append(length)
        cols["sv"].append(speed if len(speed) else np.full(len(sic), np.nan))
        cols["sb"].append(np.full(len(sic), k))
        step_length = _vec(bout, "Step_Length")
        cols["stl"].append(step_length)
        cols["stb"].append(np.full(len(step_length), k))
        ts, te, ta = _vec(bout, "Turn_Start"), _vec(bout, "Turn_End"), _vec(bout, "Turn_Angle")
        if not len(ts) == len(te) == len(ta):
            raise FormatError(f"{len(ts)} turn starts, {len(te)} ends, {len(ta)} angles",
                              where=here, expected="equal counts")
        cols["ts"].append(ts)
        cols["te"].append(te)
        cols["ta"].append(ta)
        cols["tb"].append(np.full(len(ts), k))

    def flat(key: str, dtype: type = np.float64) -> Any:
        parts = cols[key]
        if not parts:
            return np.zeros(0, dtype=dtype)
        if np.ndim(parts[0]) == 0:
            return np.asarray(parts, dtype=dtype)
        return np.concatenate(parts).astype(dtype)

    return GaitReference(
        system=system, level=level,
        bout_start_s=flat("bs"), bout_end_s=flat("be"), bout_cadence_spm=flat("cad"),
        bout_walking_speed_m_s=flat("ws"), bout_length_m=flat("len"),
        bout_n_strides=flat("ns", np.int64),
        initial_contacts_s=flat("ic"), initial_contact_left=flat("icl", np.bool_),
        initial_contact_bout=flat("icb", np.int64),
        stride_start_s=flat("ss"), stride_end_s=flat("se"), stride_length_m=flat("sl"),
        stride_speed_m_s=flat("sv"), stride_bout=flat("sb", np.int64),
        step_length_m=flat("stl"), step_bout=flat("stb", np.int64),
        turn_start_s=flat("ts"), turn_end_s=flat("te"), turn_angle_deg=flat("ta"),
        turn_bout=flat("tb", np.int64),
    )


def _user_profile(path: Path) -> tuple[UserProfile, dict[str, Any]]:
    if not path.is_file():
        return UserProfile(), {}
    try:
        info = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["infoForAlgo"]
        node = info.TimeMeasure1
    except (KeyError, AttributeError, ValueError) as exc:
        raise FormatError(f"not a mobgap infoForAlgo file ({exc})", where=str(path),
                          expected="infoForAlgo.TimeMeasure1") from None
    raw: dict[str, Any] = {}
    for name in ("Height", "Weight", "SensorHeight", "Handedness", "FootSize",
                 "SensorType_SU", "SensorAttachment_SU"):
        if hasattr(node, name):
            value = getattr(node, name)
            raw[name] = value.item() if isinstance(value, np.generic) else value
    height_cm = raw.get("Height")
    extra: dict[str, Any] = {}
    if isinstance(raw.get("Weight"), int | float):
        extra["weight_kg"] = float(raw["Weight"])
    if isinstance(raw.get("SensorHeight"), int | float):
        extra["sensor_height_m"] = float(raw["SensorHeight"]) / 100.0
    if isinstance(raw.get("FootSize"), int | float):
        extra["foot_length_m"] = float(raw["FootSize"]) / 100.0
    if isinstance(raw.get("Handedness"), str):
        extra["handedness"] = raw["Handedness"]
    height_m = float(height_cm) / 100.0 if isinstance(height_cm, int | float) else None
    return UserProfile(height_m=height_m, **extra), {k: str(v) for k, v in raw.items()}


# --------------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------------
def load_trial(root: str | Path, participant: str, test: str, trial: str, *,
               level: BoutLevel = "MicroWB") -> MobgapTrial:
    """Load one trial as a session plus its gait references.

    Parameters
    ----------
    root:
        The ``mobgap_lab`` folder (or a folder containing it).
    participant:
        ``"HA/001"``, ``"HA/002"``, ``"MS/001"`` ...
    test, trial:
        ``"Test5"`` / ``"Test11"`` and ``"Trial1"`` / ``"Trial2"``.
    level:
        Bout list of the references: ``"MicroWB"`` (mobgap's default) or
        ``"ContinuousWalkingPeriod"``.

    Raises
    ------
    InputError
        Unknown participant, test or trial (the message lists what exists).
    FormatError
        The file does not have the expected structure.
    """
    if level not in ("MicroWB", "ContinuousWalkingPeriod"):
        raise InputError(f"level {level!r}", where="mobgap load_trial",
                         expected="'MicroWB' or 'ContinuousWalkingPeriod'")
    folder = dataset_dir(root, "mobgap_lab")
    data_path = folder / participant / "data.mat"
    node = _trial_node(folder, data_path, participant, test, trial)
    where = f"{data_path} {test}.{trial}"
    unit = _field(_field(node, "SU", where), "LowerBack", where)
    fs, acc_g, gyr_deg_s, bar_hpa, stamp = _lower_back_signals(unit, where)
    n = len(acc_g)
    t = np.arange(n, dtype=np.float64) / fs
    imu = ImuStream(
        accel=SensorSeries(t, acc_g * G_TO_M_S2, "mobgap Acc (converted from g)"),
        gyro=SensorSeries(t, gyr_deg_s * DEG, "mobgap Gyr (converted from deg/s)"),
    )
    pressure = SensorSeries(t, bar_hpa * HPA_TO_PA, "mobgap Bar (converted from hPa)")
    user, info_raw = _user_profile(folder / participant / "infoForAlgo.mat")
    notes = [
        "Acc converted from g (x 9.80665), Gyr from deg/s, Bar from hPa to Pa.",
        "Axes are the sensor frame (x up, y right, z forward); mounting_q_bd maps them to the "
        "body frame (x forward, y left, z up).",
        "Mag left out: its unit is not documented and its norm (21-255 per participant) is not "
        "microtesla; raw values are in MobgapTrial.mag_unknown_unit.",
        "t = sample index / Fs from the trial start (the references' clock).",
    ]
    meta = SessionMeta(
        placement="lower back",
        mounting_q_bd=MOBGAP_Q_BD,
        user=user,
        time_origin_unix_s=float(stamp[0]),
        source={
            "dataset": "mobgap_lab",
            "repository": "https://github.com/mobilise-d/mobgap",
            "file": str(data_path),
            "participant": participant,
            "test": test,
            "trial": trial,
            "start_datetime": str(getattr(node, "StartDateTime", "")),
            "timezone": str(getattr(node, "TimeZone", "")),
            "info_for_algo": info_raw,
        },
        notes=notes,
    )
    session = Session(meta=meta, imu=imu, pressure=pressure)
    mag = np.asarray(getattr(unit, "Mag", np.zeros((0, 3))), dtype=np.float64)
    mag_raw = mag if mag.shape == (n, 3) else np.zeros((0, 3))
    return MobgapTrial(id=MobgapTrialId(participant, test, trial), session=session,
                       reference=_references(node, level, fs, where),
                       mag_unknown_unit=mag_raw, sampling_rate_hz=fs)


def _trial_node(folder: Path, data_path: Path, participant: str, test: str, trial: str) -> Any:
    """The MATLAB node of one trial (InputError listing what exists when it is not there)."""
    if not data_path.is_file():
        raise InputError(f"participant {participant!r} not found", where=str(folder),
                         expected=f"one of {', '.join(_participants(folder)) or '(none)'}")
    measure = _load_measure(data_path)
    if test not in measure._fieldnames:
        raise InputError(f"test {test!r} not found", where=str(data_path),
                         expected=f"one of {', '.join(measure._fieldnames)}")
    test_node = getattr(measure, test)
    if trial not in test_node._fieldnames:
        raise InputError(f"trial {trial!r} not found", where=f"{data_path} {test}",
                         expected=f"one of {', '.join(test_node._fieldnames)}")
    return getattr(test_node, trial)


def _lower_back_signals(unit: Any, where: str) -> tuple[float, FloatArray, FloatArray,
                                                         FloatArray, FloatArray]:
    """Rate (Hz), Acc (g), Gyr (deg/s), Bar (hPa) and Timestamp of the lower-back unit.

    Checks one common rate, equal lengths and a timestamp clock of ``k / Fs``.
    """
    fs_node = _field(unit, "Fs", where)
    rates = {name: float(_field(fs_node, name, f"{where}.Fs")) for name in ("Acc", "Gyr", "Bar")}
    if len(set(rates.values())) != 1 or rates["Acc"] <= 0:
        raise FormatError(f"sampling rates {rates}", where=f"{where}.Fs",
                          expected="one common positive rate for Acc, Gyr and Bar")
    fs = rates["Acc"]
    acc_g = np.asarray(_field(unit, "Acc", where), dtype=np.float64)
    gyr_deg_s = np.asarray(_field(unit, "Gyr", where), dtype=np.float64)
    bar_hpa = np.asarray(_field(unit, "Bar", where), dtype=np.float64).ravel()
    stamp = np.asarray(_field(unit, "Timestamp", where), dtype=np.float64).ravel()
    n = len(acc_g)
    for label, arr in (("Gyr", gyr_deg_s), ("Bar", bar_hpa), ("Timestamp", stamp)):
        if len(arr) != n:
            raise FormatError(f"{len(arr)} samples of {label} but {n} of Acc", where=where,
                              expected="equal lengths")
    if n < 2:
        raise FormatError(f"{n} samples", where=where, expected="at least 2 samples")
    drift = np.abs((stamp - stamp[0]) - np.arange(n, dtype=np.float64) / fs)
    if not np.all(np.isfinite(drift)) or float(drift.max()) > 0.5 / fs:
        idx = int(np.argmax(np.where(np.isfinite(drift), drift, np.inf)))
        raise FormatError(f"Timestamp departs from k/Fs by {drift[idx]:.4g} s at sample {idx}",
                          where=f"{where}.Timestamp", expected=f"a uniform {fs:g} Hz clock")
    return fs, acc_g, gyr_deg_s, bar_hpa, stamp


def _references(node: Any, level: BoutLevel, fs: float, where: str) -> MobgapReference:
    """The INDIP and Stereophoto references of a trial (None where a system is missing)."""
    standards = getattr(node, "Standards", None)
    systems: dict[str, GaitReference | None] = {}
    for system in REFERENCE_SYSTEMS:
        ref_node = None if standards is None else getattr(standards, system, None)
        if ref_node is None:
            systems[system] = None
            continue
        fs_ref_raw = _vec(ref_node, "Fs")
        fs_ref = float(fs_ref_raw[0]) if len(fs_ref_raw) == 1 else fs
        systems[system] = _parse_reference(ref_node, system, level, fs_ref,
                                           f"{where}.Standards.{system}")
    return MobgapReference(indip=systems["INDIP"], stereophoto=systems["Stereophoto"])
