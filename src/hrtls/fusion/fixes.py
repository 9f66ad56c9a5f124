"""External position fixes while moving, at the update period Tp (Colombo eq. 18-23).

The measurement is the planar position, ``c = V p`` with ``V = I_2`` when a fix is *due* and
``V = 0`` otherwise (eq. 18-19). A fix is due when the user moves (the standard deviation of the
forward acceleration exceeds ``sigma_a_min``, decided by the caller) and the time is a multiple
of the period ``Tp``. With ``V = I_2`` the gain, state and covariance follow eq. 20-22 (here in
Joseph form, :func:`hrtls.fusion.gating.kalman_update`); otherwise the filter keeps its
prediction (eq. 23).

Reading of eq. 19 for a stream of fixes: the platform queries the infrastructure at ``i Tp``; we
use the first fix in ``[i Tp, i Tp + slot_tolerance_s]`` taken while moving, once per slot ``i``.
``period_s=None`` uses every fix taken while moving (``require_motion=False``: every fix).

The tracker (:mod:`hrtls.pipeline.observations`) runs Colombo's second EKF: velocity or step
prediction, these fixes, and the yaw stretching of eq. 24-28 (:mod:`hrtls.fusion.yaw_stretch`)
between two accepted fixes, kept across chunks in :class:`StretchMemory`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.fusion._checks import (
    FloatArray,
    finite_matrix,
    finite_scalar,
    finite_vector,
    probability,
)
from hrtls.fusion.gating import UpdateDiagnostics, kalman_update, skipped
from hrtls.fusion.state import IH, N_STATE, FilterState
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True)
class FixParams:
    """Parameters of the position-fix correction.

    Attributes
    ----------
    period_s:
        Update period ``Tp``, s (Colombo used 1-16 s); None: every fix.
    slot_tolerance_s:
        A fix counts for slot ``i`` when it is at most this late after ``i Tp``.
    require_motion:
        Use fixes only while moving (eq. 19).
    sigma_m:
        Overrides the fixes' own 1-sigma (``Q_c = sigma^2 I``; Colombo: 0.05 m).
    use_z:
        Also correct z when the fix measured it.
    gate_probability:
        Chi-square gate on the NIS; None disables it.
    phase_s:
        Time of slot 0: slots are ``floor((t - phase_s) / Tp)``. A tracker that does not know
        when the infrastructure was queried first anchors the slots at the first fix.
    max_consecutive_rejections:
        After this many fixes in a row failed the gate, the next due fix is applied without
        the gate (the prediction, not the infrastructure, is then the likely outlier: the
        velocity model of eq. 17 treats yaw errors as white and underestimates the drift).
    """

    period_s: float | None = 10.0
    slot_tolerance_s: float = 0.5
    require_motion: bool = True
    sigma_m: float | None = None
    use_z: bool = False
    gate_probability: float | None = 0.999
    max_consecutive_rejections: int = 3
    phase_s: float = 0.0

    def __post_init__(self) -> None:
        if self.period_s is not None:
            finite_scalar(self.period_s, where="FixParams.period_s", positive=True)
        finite_scalar(self.slot_tolerance_s, where="FixParams.slot_tolerance_s",
                      non_negative=True)
        if self.sigma_m is not None:
            finite_scalar(self.sigma_m, where="FixParams.sigma_m", positive=True)
        if self.gate_probability is not None:
            probability(self.gate_probability, where="FixParams.gate_probability")
        if self.max_consecutive_rejections < 0:
            raise InputError(f"{self.max_consecutive_rejections}",
                             where="FixParams.max_consecutive_rejections", expected=">= 0")


@dataclass(frozen=True, slots=True)
class FixSchedule:
    """Causal state of the fix policy: last served period slot, rejections in a row."""

    last_slot: int | None = None
    rejections: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"last_slot": self.last_slot, "rejections": self.rejections}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FixSchedule:
        """Inverse of :meth:`to_dict`."""
        slot = data.get("last_slot")
        return cls(None if slot is None else int(slot), int(data.get("rejections", 0)))


@dataclass(frozen=True, slots=True, eq=False)
class FixUpdate:
    """Result of one fix: new state, new schedule, diagnostics."""

    state: FilterState
    schedule: FixSchedule
    diagnostics: UpdateDiagnostics


class FixCorrector:
    """Colombo eq. 18-23: planar position update with the Tp / motion policy and a gate."""

    def __init__(self, params: FixParams | None = None) -> None:
        self.params = params or FixParams()

    def due(self, schedule: FixSchedule, t: float, moving: bool) -> tuple[bool, str]:
        """Eq. 19: whether a fix at ``t`` is used, and why not."""
        prm = self.params
        if prm.require_motion and not moving:
            return False, "user not moving"
        if prm.period_s is None:
            return True, ""
        slot = math.floor((t - prm.phase_s) / prm.period_s)
        if schedule.last_slot is not None and slot <= schedule.last_slot:
            return False, "period slot already served"
        if t - prm.phase_s - slot * prm.period_s > prm.slot_tolerance_s:
            return False, "not at a multiple of the period"
        return True, ""

    def update(self, state: FilterState, schedule: FixSchedule, *, t: float, xyz: ArrayLike,
               sigma_m: float, moving: bool = True, has_z: bool = False,
               cov_xy: ArrayLike | None = None, drift_var_m2: float = 0.0) -> FixUpdate:
        """Correct ``state`` (predicted to ``t`` by the caller) with one fix, if due.

        Parameters
        ----------
        state, schedule:
            Filter state at ``t`` and the policy state.
        t:
            Fix time, s.
        xyz:
            Fixed position, m (3,) (z ignored unless ``has_z`` and ``use_z``).
        sigma_m:
            1-sigma of the fix, m (overridden by ``params.sigma_m``).
        moving:
            Whether the user moves at ``t`` (``sigma_a > sigma_a_min`` in the paper).
        has_z:
            Whether z was measured.
        cov_xy:
            Full 2x2 covariance of a planar fix (e.g. from
            :func:`hrtls.fusion.rss_scans.hyperbolic_wls`);
            replaces ``sigma_m^2 I`` when given and z is not used.
        drift_var_m2:
            Variance added to the predicted east and north position before the gate and the
            update (our addition): dead-reckoning drift the prediction's covariance does not
            model, e.g. ``(f L)^2`` for a drift of a fraction ``f`` of the path ``L`` walked
            since the last fix. Without it a good fix after a long open-loop stretch can fail
            the gate (the paper's eq. 20-22 have no gate).
        """
        prm = self.params
        t = finite_scalar(t, where="fix t")
        c = finite_vector(xyz, where="fix xyz", length=3)
        sigma = prm.sigma_m if prm.sigma_m is not None else finite_scalar(
            sigma_m, where="fix sigma_m", positive=True)
        ok, why = self.due(schedule, t, moving)
        if not ok:
            return FixUpdate(state, schedule, skipped("fix", t, why))   # eq. 23
        dims = [0, 1, 2] if (has_z and prm.use_z) else [0, 1]
        h = np.zeros((len(dims), N_STATE))
        for row, col in enumerate(dims):
            h[row, col] = 1.0                                            # V = I (eq. 18-19)
        r = np.eye(len(dims)) * sigma**2                                  # Q_c
        if cov_xy is not None and len(dims) == 2:
            r = finite_matrix(cov_xy, where="fix cov_xy", shape=(2, 2))
        drift = finite_scalar(drift_var_m2, where="fix drift_var_m2", non_negative=True)
        p_prior = state.P
        if drift > 0.0:
            p_prior = state.P.copy()
            p_prior[0, 0] += drift
            p_prior[1, 1] += drift
        nu = c[dims] - state.x[dims]
        recover = (prm.gate_probability is not None
                   and schedule.rejections >= prm.max_consecutive_rejections)
        gate = None if recover else prm.gate_probability
        res = kalman_update(state.x, p_prior, h, r, nu, gate_probability=gate,
                            kind="fix", t=t, angle_index=IH)              # eq. 20-22
        if not res.diagnostics.accepted:
            new_schedule = FixSchedule(schedule.last_slot, schedule.rejections + 1)
            return FixUpdate(state, new_schedule, res.diagnostics)
        slot = (math.floor((t - prm.phase_s) / prm.period_s) if prm.period_s is not None
                else schedule.last_slot)
        new_schedule = FixSchedule(slot, 0)
        diag = res.diagnostics
        if recover:
            diag = replace(diag, reason=f"applied without gate after {schedule.rejections} "
                           "rejections in a row")
        # the compiled Joseph update keeps P symmetric PSD and wraps the heading
        new_state = FilterState.from_kernel(state.t, res.x, res.P, state.input_heading_rad,
                                            state.has_input_heading,
                                            state.reference_pending)
        return FixUpdate(new_state, new_schedule, diag)


DRIFT_MIN_PATH_M = 3.0
"""Shortest path for the drift term of a fix gate (our addition): right after the start the
dead reckoning is already off by about a step (gait initiation, a step in progress), m."""


def step_in_progress(t: float, t_start: ArrayLike, t_end: ArrayLike) -> int:
    """Index of the step with ``t_start <= t < t_end`` (starts non-decreasing), or -1."""
    t0 = finite_vector(t_start, where="step t_start")
    t1 = finite_vector(t_end, where="step t_end", length=t0.shape[0])
    k = int(np.searchsorted(t0, t, side="right")) - 1       # last step starting at or before t
    return k if k >= 0 and t < t1[k] else -1


def partial_step(t: float, *, t_start: float, t_end: float, length_m: float,
                 heading_rad: float) -> FloatArray:
    """Planar displacement made by ``t`` within a step, linear in time, m (2,).

    A step-driven prediction stands at the end of the last finished step; a fix taken during
    the next step measures a position up to one step further (our addition: at 1.5-2 m/s on
    Colombo's 1 m circle that is up to 0.7 m and 40 deg of arc). The fix is compared with
    the state plus this displacement (:func:`partial_step_xy`).
    """
    return np.array(partial_step_xy(float(t), float(t_start), float(t_end), float(length_m),
                                    float(heading_rad)))


@njit(cache=True, error_model="numpy")
def partial_step_xy(t: float, t_start: float, t_end: float, length_m: float,
                    heading_rad: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """:func:`partial_step` as two floats (east, north), callable from compiled code."""
    dur = t_end - t_start
    if not (dur > 0.0 and t_start <= t <= t_end):
        return 0.0, 0.0
    a = (t - t_start) / dur * length_m
    return a * math.cos(heading_rad), a * math.sin(heading_rad)


@dataclass(frozen=True, slots=True)
class YawPseudoMeasurement:
    """A yaw value for the attitude filter (Colombo eq. 28 at ``j = 0``)."""

    t: float
    yaw_rad: float
    var_yaw_rad2: float
    correction_rad: float


@dataclass(frozen=True, slots=True, eq=False)
class StretchMemory:
    """What the yaw stretching keeps between chunks: the last accepted fix and the inputs since.

    Attributes
    ----------
    t_fix: time of the last accepted fix, s.
    post_xy: estimated position right after that update, m (2,).
    fix_xy: that fix, m (2,).
    sigma_m: its 1-sigma, m.
    t, speed_m_s, yaw_rad: prediction inputs since then (yaw as used, offset included).
    """

    t_fix: float
    post_xy: FloatArray
    fix_xy: FloatArray
    sigma_m: float
    t: FloatArray
    speed_m_s: FloatArray
    yaw_rad: FloatArray

    def extended(self, t: FloatArray, speed: FloatArray, yaw: FloatArray) -> StretchMemory:
        """With more samples appended."""
        return StretchMemory(self.t_fix, self.post_xy, self.fix_xy, self.sigma_m,
                             np.concatenate([self.t, t]), np.concatenate([self.speed_m_s, speed]),
                             np.concatenate([self.yaw_rad, yaw]))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able form."""
        return {"t_fix": self.t_fix, "post_xy": self.post_xy.tolist(),
                "fix_xy": self.fix_xy.tolist(), "sigma_m": self.sigma_m, "t": self.t.tolist(),
                "speed_m_s": self.speed_m_s.tolist(), "yaw_rad": self.yaw_rad.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StretchMemory:
        """Inverse of :meth:`to_dict`."""
        return cls(float(data["t_fix"]), np.asarray(data["post_xy"], dtype=np.float64),
                   np.asarray(data["fix_xy"], dtype=np.float64), float(data["sigma_m"]),
                   np.asarray(data["t"], dtype=np.float64),
                   np.asarray(data["speed_m_s"], dtype=np.float64),
                   np.asarray(data["yaw_rad"], dtype=np.float64))
