"""Magnetic heading as an absolute measurement of the state heading (our addition, issue 18).

With ``[attitude] heading_source = "gyro+compass"`` the attitude filter runs without the
magnetometer, so the step headings (and with ``heading_mode = "state"`` the turns added to the
state heading) come from the gyro alone and a magnetic error no longer turns the walker. The
magnetometer instead feeds a scalar EKF update of the state heading.

Per block of ``block_s`` of samples the (hard-iron corrected) field is rotated into the
gyro-only navigation frame, ``m_n = R(q) m_d``; ``a`` is the angle of the horizontal part of
the block's mean ``m_n``. With ``e`` the gyro yaw drift, ``alpha`` the map angle of magnetic
north, ``mu`` the offset of the walking direction from the device yaw and ``d`` a disturbance:
``psi_in = psi + e + mu`` (the last step heading input) and ``a = alpha + e + d``, so

    z = psi_in - a + b,   b = alpha - mu   ->   z = psi - d                       (1)

measures the walking heading ``psi`` whatever the drift. ``b`` (declination, map rotation and
mounting together) is not known: it is learned as the circular mean of
``x_h - psi_in + a`` over the first ``learn_blocks`` clean walking blocks (the state heading
then holds the start pose heading plus gyro turns), with variance ``P_hh`` at that time plus
the spread of the mean; it is learned again when the hard iron in force moves by more than
``relearn_hard_iron_ut``. While a running hard-iron fit has not been accepted yet the blocks
are skipped: an uncalibrated magnetometer's heading error changes with the heading (a U-turn
after learning ``b`` would read as a heading error of up to twice its deflection), unless
``unfitted = "use"``, which adds ``sigma_unfitted_deg`` to their 1-sigma and learns ``b`` again
once the fit is accepted. ``offset_floor``: every update shares the offset's error, so none
may bring ``P_hh`` below ``var_b`` (``R`` raised to ``var_b P_hh / (P_hh - var_b)``; no update
while ``P_hh <= var_b``). The update (``h(x) = x_h``, ``H = e_h``):

    nu = wrap(z - x_h),  S = P_hh + R,  K = P H^T / S,  NIS = nu^2 / S             (2)

(Joseph form, :func:`hrtls.fusion.gating.kalman_update`), rejected when the NIS exceeds the
chi-square(1) gate.

``offset_model = "consider"`` counts the offset's error as one shared by all updates instead
(Schmidt-Kalman consider filter, Simon, Optimal State Estimation, Sec. 7.5). With ``e`` the
state error, ``e_b`` the offset's and ``c = cov(e, e_b)``, ``nu = -H e + e_b - d`` and

    S = P_hh - 2 c_h + var_b + R,   K = (P H^T - c) / S,
    P' = (I - K H) P (I - K H)^T + K (var_b + R) K^T + (I - K H) c K^T + K c^T (I - K H)^T,
    c' = (I - K H) c + K var_b                                                      (3)

(``b`` itself is not updated). ``b`` is learned from the state heading, so ``e_b`` holds its
error: ``c = P e_h`` when ``b`` is learned. Between blocks only ``c_h`` is kept and the offset's
error is taken to reach the other states through the heading, ``c = (c_h / P_hh) P e_h``:
exact under a step (``c' = F c`` moves ``c`` as ``F P e_h``), while a gyro turn adds noise to
``P_hh`` but not to ``c_h`` (no coupling). An update by another sensor that shrinks ``P_hh`` is
counted by bounding ``c_h^2 <= P_hh var_b``, which keeps the joint covariance of state and
offset positive semi-definite. Repeated updates drive ``P_hh`` towards ``var_b``, never
below it. ``R = sigma_floor^2 + (g dn)^2 + (g ddip)^2 + var_b``: ``dn`` the relative
deviation of the block's field magnitude and ``ddip`` (rad) of its dip from the reference Earth
field, the median over the walking blocks seen so far (not the first sample: a rescuer stands
at the entrance, often beside a disturbance, before walking). Blocks off the reference by more
than ``gate_fraction`` or ``gate_dip_deg``, blocks while standing, and every block before
``reference_blocks`` walking blocks have been seen are skipped (diagnostics ``"magnetic"``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from hrtls.errors import InputError
from hrtls.frames import quat_to_matrix, wrap_angle
from hrtls.fusion.gating import UpdateDiagnostics, chi2_threshold, skipped
from hrtls.fusion.state import IH, N_STATE, FilterState
from hrtls.fusion.state import heading_update as fusion_heading_update

N_BLOCK = 9
"""Columns of a block row: t_end, mean m_n (3), mean |m|, samples, mean hard iron (3; NaN
while a running fit has not been accepted)."""


@dataclass(frozen=True, kw_only=True, slots=True)
class MagHeadingParams:
    """Parameters of the magnetic heading measurement (see the module notes)."""

    block_s: float = 1.0
    sigma_floor_deg: float = 6.0
    disturbance_gain: float = 2.0
    gate_fraction: float = 0.1
    gate_dip_deg: float = 5.0
    reference_blocks: int = 10
    reference_max_blocks: int = 300
    learn_blocks: int = 10
    walk_window_s: float = 2.0
    relearn_hard_iron_ut: float = 1.0
    unfitted: Literal["skip", "use"] = "skip"
    sigma_unfitted_deg: float = 10.0
    offset_floor: bool = False
    offset_model: Literal["independent", "consider"] = "independent"

    def __post_init__(self) -> None:
        positive = ("block_s", "sigma_floor_deg", "gate_fraction", "gate_dip_deg",
                    "walk_window_s", "relearn_hard_iron_ut", "sigma_unfitted_deg")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise InputError(f"{name} = {v!r}", where="MagHeadingParams",
                                 expected="a finite positive number")
        if not (math.isfinite(self.disturbance_gain) and self.disturbance_gain >= 0):
            raise InputError(f"disturbance_gain = {self.disturbance_gain!r}",
                             where="MagHeadingParams", expected="a finite number >= 0")
        if self.offset_model not in ("independent", "consider"):
            raise InputError(f"offset_model = {self.offset_model!r}", where="MagHeadingParams",
                             expected='"independent" or "consider"')
        for name in ("reference_blocks", "reference_max_blocks", "learn_blocks"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} = {getattr(self, name)!r}", where="MagHeadingParams",
                                 expected="an integer >= 1")


class MagBlocks:
    """Per-block means of the field in the gyro-only navigation frame (chunk-invariant)."""

    STATE = ("block", "acc")

    def __init__(self, block_s: float) -> None:
        self.block_s = block_s
        self.block = -math.inf
        self.acc = np.zeros(N_BLOCK)   # sums of the open block: t_last, m_n, |m|, n, c

    def add(self, t: np.ndarray, q_nd: np.ndarray, mag: np.ndarray,
            hard_iron_ut: np.ndarray | None) -> np.ndarray:
        """The blocks completed by these samples, rows of :data:`N_BLOCK` means."""
        if not len(t):
            return np.zeros((0, N_BLOCK))
        m_n = np.einsum("nij,nj->ni", quat_to_matrix(q_nd), mag)
        # no running fit: the field as it comes is taken as calibrated (offset 0)
        c = (np.zeros((len(t), 3)) if hard_iron_ut is None
             else np.asarray(hard_iron_ut, dtype=np.float64))
        vals = np.column_stack([t, m_n, np.linalg.norm(mag, axis=1), np.ones(len(t)), c])
        blocks = np.floor(np.asarray(t) / self.block_s)
        starts = np.flatnonzero(np.r_[True, blocks[1:] != blocks[:-1]])
        sums = np.add.reduceat(vals, starts, axis=0)
        sums[:, 0] = t[np.r_[starts[1:], len(t)] - 1]          # last time of each block
        ids = blocks[starts]
        out = []
        for k in range(len(starts)):
            if ids[k] == self.block:
                last = sums[k, 0]
                self.acc = self.acc + sums[k]
                self.acc[0] = last
            else:
                if self.acc[5] > 0:
                    out.append(self._mean(self.acc))
                self.block, self.acc = float(ids[k]), sums[k].copy()
        return np.array(out).reshape(-1, N_BLOCK)

    @staticmethod
    def _mean(acc: np.ndarray) -> np.ndarray:
        row = acc.copy()
        row[1:5] /= acc[5]
        row[6:9] /= acc[5]
        return row


def field_angles(row: np.ndarray) -> tuple[float, float, float]:
    """Horizontal angle ``a`` (rad, ENU), dip (rad, positive down) and mean |m| of a block."""
    mx, my, mz = (float(v) for v in row[1:4])
    return math.atan2(my, mx), math.atan2(-mz, math.hypot(mx, my)), float(row[4])


def heading_update(state: FilterState, z_rad: float, r_rad2: float, *, t: float,
                   gate_probability: float) -> tuple[FilterState, UpdateDiagnostics]:
    """Eq. (2): the scalar EKF update of the state heading by a heading measurement."""
    return fusion_heading_update(state, float(wrap_angle(z_rad - state.heading)), r_rad2,
                                 kind="magnetic", t=t, gate_probability=gate_probability)


def consider_heading_update(state: FilterState, z_rad: float, r_rad2: float, var_b_rad2: float,
                            c: np.ndarray, *, t: float, gate_probability: float
                            ) -> tuple[FilterState, np.ndarray, UpdateDiagnostics]:
    """Eq. (3): the heading update with the offset's error ``var_b`` shared through ``c``."""
    x, p = state.x, state.P
    nu = float(wrap_angle(z_rad - state.heading))
    s = float(p[IH, IH] - 2.0 * c[IH] + var_b_rad2 + r_rad2)
    threshold = chi2_threshold(1, gate_probability)
    nu_a = np.array([nu])
    if not (s > 0.0):
        diag = UpdateDiagnostics("magnetic", t, "rejected", dof=1, threshold=threshold,
                                 innovation=nu_a, innovation_cov=np.array([[s]]),
                                 reason="innovation covariance not positive definite")
        return state, c, diag
    value = nu * nu / s
    if value > threshold:
        diag = UpdateDiagnostics("magnetic", t, "rejected", nis=value, dof=1,
                                 threshold=threshold, innovation=nu_a,
                                 innovation_cov=np.array([[s]]),
                                 reason="failed the chi-square gate")
        return state, c, diag
    k = (p[:, IH] - c) / s
    a = np.eye(N_STATE)
    a[:, IH] -= k
    ack = np.outer(a @ c, k)
    p_new = a @ p @ a.T + (var_b_rad2 + r_rad2) * np.outer(k, k) + ack + ack.T
    x_new = x + k * nu
    x_new[IH] = float(wrap_angle(x_new[IH]))
    c_new = a @ c + k * var_b_rad2
    diag = UpdateDiagnostics("magnetic", t, "accepted", nis=value, dof=1, threshold=threshold,
                             innovation=nu_a, innovation_cov=np.array([[s]]))
    return state.evolve(x=x_new, P=0.5 * (p_new + p_new.T)), c_new, diag


def _hard_iron_moved(c: np.ndarray, c_learn: np.ndarray, limit_ut: float) -> bool:
    """The hard iron in force moved away from the one ``b`` was learned with (inf: unfitted)."""
    if np.all(np.isinf(c)) or np.all(np.isinf(c_learn)):
        return bool(np.all(np.isinf(c)) != np.all(np.isinf(c_learn)))
    return float(np.linalg.norm(c - c_learn)) > limit_ut


class MagHeading:
    """Reference field, learned offset ``b`` and the updates of eq. (1)-(2)."""

    def __init__(self, params: MagHeadingParams) -> None:
        self.params = params
        self.state: dict[str, Any] = {
            "norm": deque(maxlen=params.reference_max_blocks),
            "dip": deque(maxlen=params.reference_max_blocks),
            "learn": [0.0, 0.0, 0.0, 0.0], "b": math.nan, "var_b": math.nan,
            "c_learn": [math.nan] * 3, "c_h": math.nan}

    def _check(self, row: np.ndarray, walking: bool) -> tuple[str, float]:
        """Why the block is not used (``""``: used) and its measurement variance, rad^2."""
        prm, s = self.params, self.state
        _, dip, norm = field_angles(row)
        if not walking:
            return "standing", math.nan
        s["norm"].append(norm)
        s["dip"].append(dip)
        if len(s["norm"]) < prm.reference_blocks:
            return "reference field not learned yet", math.nan
        ref_n = float(np.median(s["norm"]))
        dn = abs(norm - ref_n) / ref_n
        ddip = abs(dip - float(np.median(s["dip"])))
        if dn > prm.gate_fraction or ddip > math.radians(prm.gate_dip_deg):
            return "field off the reference (disturbed)", math.nan
        g = prm.disturbance_gain
        return "", math.radians(prm.sigma_floor_deg) ** 2 + (g * dn) ** 2 + (g * ddip) ** 2

    def apply(self, state: FilterState, t: float, row: np.ndarray, *, walking: bool,
              input_heading_rad: float, gate_probability: float
              ) -> tuple[FilterState, UpdateDiagnostics]:
        """One block at ``t``: learn ``b`` or update the state heading (eq. 1-2)."""
        prm, s = self.params, self.state
        if not state.has_input_heading or state.reference_pending:
            return state, skipped("magnetic", t, "no step heading yet")
        why, var = self._check(row, walking)
        if why:
            return state, skipped("magnetic", t, why)
        a, _, _ = field_angles(row)
        c = row[6:9]
        if not np.all(np.isfinite(c)):
            # an uncalibrated magnetometer's error depends on the heading
            if prm.unfitted == "skip":
                return state, skipped("magnetic", t, "hard iron not fitted yet")
            var += math.radians(prm.sigma_unfitted_deg) ** 2
            c = np.full(3, math.inf)
        if math.isfinite(s["b"]) and _hard_iron_moved(c, np.asarray(s["c_learn"]),
                                                      prm.relearn_hard_iron_ut):
            s["b"], s["learn"] = math.nan, [0.0, 0.0, 0.0, 0.0]
        if not math.isfinite(s["b"]):
            w = state.heading - input_heading_rad + a
            acc = s["learn"]
            acc[0] += math.cos(w)
            acc[1] += math.sin(w)
            acc[2] += 1.0
            acc[3] = max(acc[3], float(state.P[IH, IH]))
            if acc[2] < prm.learn_blocks:
                return state, skipped("magnetic", t, "learning the heading offset")
            resultant = math.hypot(acc[0], acc[1]) / acc[2]
            s["b"] = math.atan2(acc[1], acc[0])
            # circular variance of the mean of n blocks, plus the state heading's own
            s["var_b"] = acc[3] + (-2.0 * math.log(max(resultant, 1e-9))) / acc[2]
            s["c_learn"] = [float(v) for v in c]
            s["c_h"] = float(state.P[IH, IH])
            return state, skipped("magnetic", t, "heading offset learned")
        z = input_heading_rad - a + s["b"]
        if prm.offset_model == "consider":
            return self._consider(state, t, z, var, gate_probability)
        r = var + s["var_b"]
        p_hh = float(state.P[IH, IH])
        if prm.offset_floor and p_hh > s["var_b"]:
            # every update shares the offset's error: none may bring P_hh below var_b
            r = max(r, s["var_b"] * p_hh / (p_hh - s["var_b"]))
        elif prm.offset_floor:
            return state, skipped("magnetic", t, "heading variance at the offset's")
        return heading_update(state, z, r, t=t, gate_probability=gate_probability)

    def _consider(self, state: FilterState, t: float, z: float, var: float,
                  gate_probability: float) -> tuple[FilterState, UpdateDiagnostics]:
        """Eq. (3) with ``c_h`` kept between blocks."""
        s = self.state
        var_b = s["var_b"]
        # a snapshot from before the consider model: b's error as learned from P_hh now
        c_h = s.get("c_h", math.nan)
        c_h = c_h if math.isfinite(c_h) else float(state.P[IH, IH])
        p_hh = float(state.P[IH, IH])
        bound = math.sqrt(max(p_hh, 0.0) * var_b) * (1.0 - 1e-9)
        c_h = min(max(c_h, -bound), bound)
        c = state.P[:, IH] * (c_h / p_hh) if p_hh > 0.0 else np.zeros(N_STATE)
        state, c, diag = consider_heading_update(state, z, var, var_b, c, t=t,
                                                 gate_probability=gate_probability)
        s["c_h"] = float(c[IH])
        return state, diag
