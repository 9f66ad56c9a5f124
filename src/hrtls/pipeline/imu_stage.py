"""The tracker's per-sample front end: held samples, mounting, hard iron, attitude, compass.

Samples are held until the hand-held mounting window has elapsed (``[attitude] mounting =
"handheld"``); the hard iron in force at each sample (running fit, or the whole-recording fit
of ``[offline] two_pass``) is removed before the attitude filter; the compass correction of a
device orientation's yaw wander follows. The yaw variance of the recent samples is kept for
the events that still need it.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from hrtls.attitude.base import AttitudeFilter, AttitudeResult
from hrtls.attitude.device import DeviceOrientation
from hrtls.calibration.hard_iron import fit_hard_iron, hard_iron_samples
from hrtls.calibration.hard_iron_running import RunningHardIron
from hrtls.data import ImuStream, OrientationSeries, SessionMeta
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import quat_multiply
from hrtls.pipeline.build import Notes
from hrtls.pipeline.compass import CompassYaw
from hrtls.pipeline.config import AttitudeConfig
from hrtls.pipeline.mag_heading import MagBlocks
from hrtls.pipeline.mounting import declared_handheld, handheld_mounting_q_bd, looks_handheld

DEFAULT_VAR_YAW_RAD2 = 0.01
"""Yaw variance when the attitude filter gives none (rad^2)."""
YAW_VARIANCE_KEEP_S = 5.0
"""Yaw variances of samples this long before the filter state's time are dropped, s."""


class HeldImu:
    """IMU samples held until the hand-held mounting window has elapsed (aligned arrays)."""

    STATE = ("t", "acc", "gyr", "mag", "ot", "oq", "has_orientation")

    def __init__(self) -> None:
        self.t = np.zeros(0)
        self.acc = np.zeros((0, 3))
        self.gyr: np.ndarray | None = None
        self.mag: np.ndarray | None = None
        self.ot = np.zeros(0)
        self.oq = np.zeros((0, 4))
        self.has_orientation = False

    def add(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
            mag: np.ndarray | None, orientation: OrientationSeries | None) -> None:
        """Hold these samples (after those already held)."""
        first = not len(self.t)
        self.t = np.concatenate([self.t, t])
        self.acc = np.concatenate([self.acc, acc])
        if gyr is not None:
            self.gyr = gyr.copy() if first or self.gyr is None else np.concatenate([self.gyr, gyr])
        if mag is not None:
            self.mag = mag.copy() if first or self.mag is None else np.concatenate([self.mag, mag])
        if orientation is not None:
            self.has_orientation = True
            self.ot = np.concatenate([self.ot, orientation.t])
            self.oq = np.concatenate([self.oq, orientation.q])

    def orientation(self) -> OrientationSeries | None:
        """The held device orientation, or None."""
        return OrientationSeries(self.ot, self.oq) if self.has_orientation else None


def note_session_mounting(meta: SessionMeta, notes: Notes) -> None:
    """Report line of the session's own mounting (when it has one)."""
    if meta.mounting_q_bd is not None:
        notes.add("mounting: from the session (meta.mounting_q_bd = "
                  f"[{', '.join(f'{v:.4f}' for v in meta.mounting_q_bd)}])")


def resolve_mounting(meta: SessionMeta, acc_d: np.ndarray, notes: Notes,
                     cfg: AttitudeConfig) -> SessionMeta:
    """The session metadata with the hand-held mounting from these samples (noted).

    With ``auto`` mounting and no declared placement the samples first decide whether the
    device is a phone held in front (:func:`~hrtls.pipeline.mounting.looks_handheld`).
    """
    if len(acc_d) and cfg.mounting == "auto" and not declared_handheld(meta.placement):
        held, how = looks_handheld(acc_d, screen_tilt_deg=cfg.handheld_screen_tilt_deg)
        notes.add(f"placement not declared: {how} over the first {len(acc_d)} samples, "
                  + ("a phone held in front" if held else "not a phone held in front"))
        if not held:
            note_session_mounting(meta, notes)
            return meta
    if len(acc_d):
        try:
            q_bd = handheld_mounting_q_bd(acc_d)
        except InputError as exc:  # e.g. a phone held upright: top edge vertical
            notes.degrade(f"hand-held mounting not estimable ({exc}); using the session's "
                          "mounting")
            note_session_mounting(meta, notes)
            return meta
        notes.add("mounting: hand-held in front (device +y forward), tilt from the mean "
                  f"specific force of {len(acc_d)} samples: q_bd = "
                  f"[{', '.join(f'{v:.4f}' for v in q_bd)}]")
        return meta.model_copy(update={"mounting_q_bd": tuple(float(v) for v in q_bd)})
    notes.add("mounting 'handheld' asked but no accelerometer samples from the start pose on; "
              "using the session's mounting")
    note_session_mounting(meta, notes)
    return meta


class AttitudeStage:
    """Attitude of each sample with the hard iron removed and the compass applied.

    Parameters
    ----------
    filt: the attitude filter (or the device's own orientation).
    hard_iron: running hard-iron fit (None: none, or ``hard_iron_fixed_ut``).
    hard_iron_fixed_ut: whole-recording hard iron (``[offline] two_pass``), uT.
    compass: yaw correction of the device orientation, or None.
    use_mag: feed the magnetometer to the filter.
    keep_attitude: keep every per-sample result (for the track result).
    mag_blocks: per-block field in the (gyro-only) navigation frame for the magnetic heading
        measurement (``heading_source = "gyro+compass"``), or None; the completed blocks
        wait in :attr:`mag_rows` for the tracker to queue them.
    """

    COMPASS = ("n_tot", "y_tot", "n_cur", "y_cur", "cur_block", "c", "radius", "history",
               "s1", "s2", "n_ref", "t_first", "smooth", "last_error")

    def __init__(self, filt: AttitudeFilter | DeviceOrientation, *,
                 hard_iron: RunningHardIron | None, hard_iron_fixed_ut: np.ndarray | None,
                 compass: CompassYaw | None, use_mag: bool, keep_attitude: bool,
                 mag_blocks: MagBlocks | None = None) -> None:
        self.filter = filt
        self.mag_blocks = mag_blocks
        self.mag_rows = np.zeros((0, 9))
        self.hard_iron = hard_iron
        self.hard_iron_fixed_ut = hard_iron_fixed_ut
        self.compass = compass
        self.use_mag = use_mag
        self.keep_attitude = keep_attitude
        self.results: list[AttitudeResult] = []
        self.var_t = np.zeros(0)
        self.var_v = np.zeros(0)

    def _hard_iron_at(self, t: np.ndarray, acc: np.ndarray, mag: np.ndarray
                      ) -> np.ndarray | None:
        """Hard iron in force at each sample (N, 3; NaN rows: not known yet), or None."""
        if self.hard_iron_fixed_ut is not None:
            return np.broadcast_to(self.hard_iron_fixed_ut, mag.shape)
        if self.hard_iron is None:
            return None
        return self.hard_iron.update(t, mag, acc)

    def update(self, t: np.ndarray, acc: np.ndarray, gyr: np.ndarray | None,
               mag: np.ndarray | None, orientation: OrientationSeries | None, *,
               mounting_q_bd: tuple[float, ...] | None, state_t: float) -> np.ndarray:
        """Device->navigation quaternions of the samples (N, 4).

        ``state_t``: time of the position filter's state (older yaw variances are dropped).
        """
        filt = self.filter
        c_of = None if mag is None else self._hard_iron_at(t, acc, mag)
        if mag is not None and c_of is not None:
            mag = mag - np.nan_to_num(c_of, nan=0.0)
        if isinstance(filt, DeviceOrientation):
            assert orientation is not None
            res = filt.run(orientation, t)
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DegradedInputWarning)
                res = filt.update(t, acc, gyr, mag if self.use_mag else None)
        if self.keep_attitude:
            self.results.append(res)
        q = res.q
        if res.frame == "nb" and mounting_q_bd is not None:
            q = quat_multiply(q, np.asarray(mounting_q_bd, dtype=np.float64))
        if self.compass is not None and mag is not None and len(mag) == len(res.t):
            q = self.compass.correct(res.t, np.asarray(q), mag, c_of)
        if self.mag_blocks is not None and mag is not None and len(mag) == len(res.t):
            self.mag_rows = np.concatenate([self.mag_rows, self.mag_blocks.add(
                res.t, np.asarray(q), mag, c_of)])
        var = (res.var_rpy[:, 2] if res.var_rpy is not None
               else np.full(len(res.t), DEFAULT_VAR_YAW_RAD2))
        # keep the yaw variance of the samples later events may still need
        keep = self.var_t >= state_t - YAW_VARIANCE_KEEP_S
        self.var_t = np.concatenate([self.var_t[keep], res.t])
        self.var_v = np.concatenate([self.var_v[keep], var])
        return np.asarray(q)

    def var_yaw_at(self, t: np.ndarray) -> np.ndarray:
        """Yaw variance interpolated at ``t`` (NaN before any sample), rad^2."""
        if len(self.var_t) == 0:
            return np.full(np.shape(t), np.nan)
        return np.interp(t, self.var_t, self.var_v)

    def attitude(self) -> AttitudeResult | None:
        """The kept per-sample attitude (None when not kept)."""
        # one chunk (offline run): its result as is, no copy of the per-sample arrays
        r = self.results
        return None if not r else r[0] if len(r) == 1 else AttitudeResult.concatenate(r)

    def state(self) -> dict[str, Any]:
        """Plain state for a snapshot."""
        return {"var_t": self.var_t, "var_v": self.var_v,
                "filter": (self.filter.state if isinstance(self.filter, AttitudeFilter)
                           else None),
                "compass": None if self.compass is None else {
                    k: getattr(self.compass, k) for k in self.COMPASS},
                "hard_iron": None if self.hard_iron is None else self.hard_iron.state,
                "mag_blocks": None if self.mag_blocks is None else {
                    k: getattr(self.mag_blocks, k) for k in MagBlocks.STATE}}

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state`."""
        self.var_t, self.var_v = state["var_t"], state["var_v"]
        if isinstance(self.filter, AttitudeFilter):
            self.filter.restore(state["filter"])
        if self.compass is not None:
            for k, v in state["compass"].items():
                setattr(self.compass, k, v)
        if self.hard_iron is not None:
            self.hard_iron.state = state["hard_iron"]
        if self.mag_blocks is not None:
            for k, v in state["mag_blocks"].items():
                setattr(self.mag_blocks, k, v)


def fit_hard_iron_offline(imu: ImuStream, notes: list[tuple[bool, str]]) -> np.ndarray | None:
    """``[offline] two_pass``: the hard iron fitted on the whole recording (or None, noted).

    Blocks of ``rate_hz`` magnetometer samples are averaged before the fit: one second when
    the magnetometer runs at the accelerometer rate, longer when it is slower.
    """
    mag, up_d = hard_iron_samples(imu)
    if mag is None:
        return None
    try:
        fit = fit_hard_iron(mag, up_d=up_d, block_samples=max(1, round(imu.accel.rate_hz)))
    except InputError as exc:
        notes.append((True, f"magnetometer hard iron not fitted ({exc}); field used raw"))
        return None
    notes.append((False,
        "magnetometer hard iron fitted on the whole recording's turns ([offline] two_pass):"
        f" c = [{', '.join(f'{v:.2f}' for v in fit.hard_iron_ut)}] uT, horizontal field "
        f"{fit.field_ut:.1f} uT, residual {fit.residual_ut:.2f} uT, {fit.arc_deg:.0f} deg "
        f"of turning, {fit.n_used} samples"))
    return fit.hard_iron_ut
