"""The rescuer agent: a simulated walker with dead-reckoning error and range corrections.

:class:`RescuerAgent` walks straight steps toward the target with a dead-reckoning error that
grows with distance (heading and step-length noise) and corrects its estimate with the ranges
to localized nodes (:func:`~hrtls.wsn.ranging.range_update`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.wsn.ranging import AgentLeg, Landmarks, RangeScan, RangeWorld, range_update

__all__ = ["RescuerAgent", "RescuerParams"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class RescuerParams:
    """Simulated rescuer.

    Attributes
    ----------
    step_length_m:
        Length of a step, m.
    step_length_noise_fraction:
        Relative error of the dead-reckoned step length.
    heading_noise_rad:
        Random-walk heading error added per step, rad.
    range_noise_fraction:
        Relative range sigma used by the range corrections.
    correct_every_steps:
        Range correction period in steps (0 = only at arrival).
    max_steps:
        Step limit of one leg.
    """

    step_length_m: float = 0.02
    step_length_noise_fraction: float = 0.0
    heading_noise_rad: float = 0.0
    range_noise_fraction: float = 0.0
    correct_every_steps: int = 0
    max_steps: int = 100000

    def __post_init__(self) -> None:
        if not self.step_length_m > 0:
            raise InputError(f"step_length_m = {self.step_length_m}", where="RescuerParams",
                             expected="> 0")


class RescuerAgent:
    """Walker that follows way points with a noisy dead-reckoned estimate (implements MobileAgent).

    It steers on its *estimate*: each step moves the true position along the true heading, and the
    estimate along the believed heading with the believed step length; the heading error is a
    random walk. Range corrections (:func:`range_update`) use localized nodes within the radio
    range. A real rescuer tracker replaces this class by implementing :class:`MobileAgent`.
    """

    def __init__(self, world: RangeWorld, start_m: FloatArray, *, params: RescuerParams,
                 rng: np.random.Generator) -> None:
        self.world = world
        self.params = params
        self.rng = rng
        self.true_m = np.array(start_m, dtype=np.float64).reshape(2)
        self.est_m = self.true_m.copy()
        self.cov = np.zeros((2, 2))
        self.heading_error_rad = 0.0
        self.steps_total = 0
        self.distance_m = 0.0

    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Current estimate and covariance."""
        return self.est_m.copy(), self.cov.copy()

    def scan(self) -> RangeScan:
        """Ranges heard at the current (true) position."""
        return self.world.scan_at(self.true_m)

    def _correct(self, landmarks: Landmarks) -> None:
        sc = self.world.scan_at(self.true_m)
        if sc.node.size == 0 or landmarks.node.size == 0:
            return
        pos_of = {int(k): i for i, k in enumerate(landmarks.node)}
        sel = [i for i, k in enumerate(sc.node) if int(k) in pos_of]
        if not sel:
            return
        rows = [pos_of[int(sc.node[i])] for i in sel]
        lm = np.array([landmarks.position_m[k] for k in rows])
        rr = sc.range_m[sel]
        sl = landmarks.sigmas()[rows]
        sig = np.sqrt((self.params.range_noise_fraction * rr) ** 2 + sl**2 + 1e-12)
        self.est_m, self.cov, _ = range_update(self.est_m, self.cov, lm, rr, sig, iterations=8)

    def go_to(self, target_m: FloatArray, landmarks: Landmarks) -> AgentLeg:
        """Walk to ``target_m`` (steers on the estimate), correcting with ranges."""
        prm = self.params
        tgt = np.asarray(target_m, dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(tgt)):
            raise InputError("non-finite target", where="RescuerAgent.go_to", expected="finite")
        pe = [self.est_m.copy()]
        pt = [self.true_m.copy()]
        length = 0.0
        reached = False
        q_len = prm.step_length_m * prm.step_length_noise_fraction
        for k in range(prm.max_steps):
            to = tgt - self.est_m
            dist = float(np.hypot(*to))
            if dist <= 1e-9:
                reached = True
                break
            step = min(prm.step_length_m, dist)
            believed = math.atan2(to[1], to[0])
            if prm.heading_noise_rad > 0:
                self.heading_error_rad += prm.heading_noise_rad * self.rng.standard_normal()
            true_len = step * (1.0 + prm.step_length_noise_fraction * self.rng.standard_normal()) \
                if prm.step_length_noise_fraction > 0 else step
            th = believed + self.heading_error_rad
            self.true_m = self.true_m + true_len * np.array([math.cos(th), math.sin(th)])
            self.est_m = self.est_m + step * np.array([math.cos(believed), math.sin(believed)])
            length += abs(true_len)
            along = np.array([math.cos(believed), math.sin(believed)])
            across = np.array([-along[1], along[0]])
            # heading error is a random walk over the whole mission (never corrected by
            # ranges): lateral variance grows by (step * sigma_h * steps so far)^2 per step
            self.steps_total += 1
            var_h = (step * prm.heading_noise_rad * self.steps_total) ** 2
            self.cov = self.cov + q_len**2 * np.outer(along, along) + var_h * np.outer(
                across, across)
            if prm.correct_every_steps and (k + 1) % prm.correct_every_steps == 0:
                self._correct(landmarks)
            pe.append(self.est_m.copy())
            pt.append(self.true_m.copy())
        self._correct(landmarks)
        self.distance_m += length
        return AgentLeg(estimate_m=self.est_m.copy(), covariance_m2=self.cov.copy(),
                        true_m=self.true_m.copy(), path_m=np.array(pe), path_true_m=np.array(pt),
                        length_m=length, reached=reached, scan=self.scan())
