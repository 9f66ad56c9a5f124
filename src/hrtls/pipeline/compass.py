"""Compass correction of a slowly wandering attitude yaw (our addition, not from the papers).

A device AHRS (Basso's built-in orientation) or a gyro-driven filter lets its yaw wander by a
few degrees over minutes; on a long walk without infrastructure that wander is the main error.
Magnetic north does not move: expressed in the navigation frame with the filter's attitude, the
horizontal direction of the (hard-iron corrected) magnetic field changes only by the yaw error.
So the yaw error at ``t`` is the angle of that direction at ``t`` minus its angle during a
reference window just after the start pose (where the start heading holds), and the attitude is
rotated back about the vertical by it.

* Hard iron ``c``: sphere fit ``|m|^2 = 2 c.m + k`` by least squares over all samples of the
  completed 1 s blocks before the current one (normal equations accumulated; a weak prior
  ``c = 0`` keeps a fit without tilt excitation solvable), so the estimate at a sample is the
  same however the recording is cut into chunks.
* The reference direction is linear in ``c``: with ``S1 = sum R_i m_i`` and ``S2 = sum R_i`` over
  the reference window, it is the angle of ``(S1 - S2 c)_xy`` for the current ``c``.
* Error angle smoothed by a first-order low pass on its unit vector (time constant ``tau_s``);
  samples whose field magnitude is off the fitted sphere by more than ``gate_fraction`` or
  whose dip differs from the reference window's by more than ``gate_dip_deg`` (magnetic
  disturbance) hold the filtered value. No correction before ``warmup_s`` of data (the
  fit needs turns), nor while the horizontal hard iron still moved by more than
  ``max_drift_c_ut`` over the last ``stable_s``, nor when the fitted field is not an Earth
  field (``earth_field_ut``; before the first turns the samples lie on an arc that a small
  sphere fits well).
* ``field_corrected = True``: the field given is already hard-iron corrected (the tracker's
  ``[attitude] mag_hard_iron = "fit"``, :mod:`hrtls.calibration.hard_iron`). There is no
  warm-up, and until the own fit has settled ``c`` is zero and the field magnitude is the RMS
  of the samples so far. A running external estimate is given per sample
  (``hard_iron_ut`` of :meth:`CompassYaw.correct`, NaN rows before it is known): those samples
  come raw and are neither fitted nor corrected, and the reference direction, kept on the raw
  field, is taken with the external offset in force at each sample.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from hrtls.frames import quat_multiply, quat_to_matrix
from hrtls.kernels import njit

FloatArray = np.ndarray


@dataclass(frozen=True, kw_only=True, slots=True)
class CompassParams:
    """Parameters of :class:`CompassYaw` (see the module notes)."""

    block_s: float = 1.0
    reference_s: float = 20.0
    warmup_s: float = 60.0
    tau_s: float = 5.0
    gate_fraction: float = 0.15
    gate_dip_deg: float = 4.0
    prior_weight: float = 1.0
    stable_s: float = 20.0
    max_drift_c_ut: float = 0.5
    earth_field_ut: tuple[float, float] = (20.0, 70.0)
    field_corrected: bool = False


@njit(cache=True)
def _smooth_kernel(t: FloatArray, err: FloatArray, ok: FloatArray, alpha_tau: float,
                   state: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Low pass of the unit vector of ``err``; ``state = [t_prev, cos, sin, started]``."""
    out = np.empty(t.shape[0])
    for i in range(t.shape[0]):
        if ok[i] > 0.5:
            if state[3] < 0.5:
                state[1] = math.cos(err[i])
                state[2] = math.sin(err[i])
                state[3] = 1.0
            else:
                dt = max(t[i] - state[0], 0.0)
                a = 1.0 - math.exp(-dt / alpha_tau)
                state[1] += a * (math.cos(err[i]) - state[1])
                state[2] += a * (math.sin(err[i]) - state[2])
        state[0] = t[i]
        out[i] = math.atan2(state[2], state[1]) if state[3] > 0.5 else 0.0
    return out


class CompassYaw:
    """Causal, chunk-invariant yaw-wander correction from the magnetometer."""

    def __init__(self, t_pose: float, params: CompassParams | None = None) -> None:
        self.params = params or CompassParams()
        self.t_pose = t_pose
        self.n_tot = np.zeros((4, 4))
        self.y_tot = np.zeros(4)
        self.n_cur = np.zeros((4, 4))
        self.y_cur = np.zeros(4)
        self.cur_block = -math.inf
        self.c: FloatArray = np.zeros(3)
        self.radius = math.nan
        self.history: deque[np.ndarray] = deque(
            maxlen=max(1, round(self.params.stable_s / self.params.block_s)))
        self.s1 = np.zeros(3)
        self.s2 = np.zeros((3, 3))
        self.n_ref = 0
        self.t_first = math.nan
        self.smooth = np.array([-math.inf, 1.0, 0.0, 0.0])
        self.last_error = 0.0

    def _solve(self) -> None:
        self._solve_sphere()
        if self.params.field_corrected and not math.isfinite(self.radius):
            # until the own fit has settled: the corrected field as it is
            count = self.n_tot[3, 3]
            if count >= 10.0:
                r = math.sqrt(self.y_tot[3] / count)
                lo, hi = self.params.earth_field_ut
                self.c = np.zeros(3)
                self.radius = r if lo <= r <= hi else math.nan

    def _solve_sphere(self) -> None:
        w = self.params.prior_weight
        n = self.n_tot + np.diag([w, w, w, 0.0])
        count = self.n_tot[3, 3]
        if count < 10.0:
            return
        sol = np.linalg.solve(n + 1e-9 * np.eye(4), self.y_tot)
        r2 = float(sol[3] + sol[:3] @ sol[:3])
        prm = self.params
        self.history.append(sol[:3].copy())
        if r2 > 0:
            self.c = np.asarray(sol[:3], dtype=np.float64)
            # the sphere is used only once the hard iron has settled (turns seen) and the
            # fitted field is an Earth field
            r = math.sqrt(r2)
            lo, hi = prm.earth_field_ut
            old = self.history[0]
            settled = (len(self.history) == self.history.maxlen
                       and float(np.hypot(*(self.c[:2] - old[:2]))) <= prm.max_drift_c_ut)
            self.radius = r if settled and lo <= r <= hi else math.nan

    def correct(self, t: FloatArray, q_nd: FloatArray, mag: FloatArray,
                hard_iron_ut: FloatArray | None = None) -> FloatArray:
        """The attitude ``q_nd`` with the estimated yaw wander removed (same shape).

        ``hard_iron_ut`` (N, 3): the external offset already removed from ``mag`` at each
        sample (``field_corrected``; NaN rows: not known yet, ``mag`` raw there).
        """
        prm = self.params
        if len(t) == 0:
            return np.asarray(q_nd)
        known = (np.ones(len(t), dtype=bool) if hard_iron_ut is None
                 else np.all(np.isfinite(hard_iron_ut), axis=1))
        c_ext = np.zeros((len(t), 3)) if hard_iron_ut is None else np.where(
            known[:, None], hard_iron_ut, 0.0)
        if math.isnan(self.t_first):
            self.t_first = float(t[0])
        blocks = np.floor(t / prm.block_s)
        rows = np.column_stack([2.0 * mag, np.ones(len(t))])
        b = np.sum(mag * mag, axis=1)
        starts = np.flatnonzero(np.r_[True, blocks[1:] != blocks[:-1]])
        ends = np.r_[starts[1:], len(t)]
        c_of = np.empty((len(t), 3))
        r_of = np.empty(len(t))
        for i0, i1 in zip(starts.tolist(), ends.tolist(), strict=True):
            if blocks[i0] != self.cur_block:
                # a new block: commit the previous one, refit on all completed blocks
                self.n_tot += self.n_cur
                self.y_tot += self.y_cur
                self.n_cur = np.zeros((4, 4))
                self.y_cur = np.zeros(4)
                self.cur_block = float(blocks[i0])
                self._solve()
            c_of[i0:i1] = self.c
            r_of[i0:i1] = self.radius
            rr = rows[i0:i1]
            bb = b[i0:i1]
            keep = known[i0:i1]
            if math.isfinite(self.radius):
                # disturbed samples do not enter the fit
                keep = keep & (np.abs(np.linalg.norm(mag[i0:i1] - self.c, axis=1)
                                      - self.radius) <= prm.gate_fraction * self.radius)
            if not keep.all():
                rr, bb = rr[keep], bb[keep]
            self.n_cur += rr.T @ rr
            self.y_cur += rr.T @ bb
        rot = quat_to_matrix(q_nd)
        mn = np.einsum("nij,nj->ni", rot, mag - c_of)
        ang = np.arctan2(mn[:, 1], mn[:, 0])
        ref = (t >= self.t_pose) & (t < self.t_pose + prm.reference_s)
        if np.any(ref):
            self.s1 += np.einsum("nij,nj->i", rot[ref], mag[ref] + c_ext[ref])
            self.s2 += np.sum(rot[ref], axis=0)
            self.n_ref += int(np.count_nonzero(ref))
        err = np.zeros(len(t))
        ok = np.zeros(len(t))
        if self.n_ref:
            v = self.s1[None, :] - np.einsum("ij,nj->ni", self.s2, c_of + c_ext)
            a_ref = np.arctan2(v[:, 1], v[:, 0])
            err = np.asarray(np.angle(np.exp(1j * (ang - a_ref))))
            mag_r = np.linalg.norm(mag - c_of, axis=1)
            # a disturbed field changes its magnitude or its dip (angle below the horizon)
            dip = np.arctan2(-mn[:, 2], np.hypot(mn[:, 0], mn[:, 1]))
            dip_ref = np.arctan2(-v[:, 2], np.hypot(v[:, 0], v[:, 1]))
            warmup = 0.0 if prm.field_corrected else prm.warmup_s
            ok = ((t >= self.t_pose + prm.reference_s) & (t - self.t_first >= warmup)
                  & known & np.isfinite(r_of)
                  & (np.abs(mag_r - r_of) <= prm.gate_fraction * np.nan_to_num(r_of))
                  & (np.abs(dip - dip_ref) <= math.radians(prm.gate_dip_deg)))
        e = _smooth_kernel(np.asarray(t, dtype=np.float64), err, ok.astype(np.float64),
                           prm.tau_s, self.smooth)
        if len(e):
            self.last_error = float(e[-1])
        half = -0.5 * e
        qz = np.column_stack([np.cos(half), np.zeros_like(half), np.zeros_like(half),
                              np.sin(half)])
        return np.asarray(quat_multiply(qz, q_nd))
