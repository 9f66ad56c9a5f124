"""The robot agent: unicycle, via-point controller and range EKF (Inderst Sec. 5.4, 6.4).

:class:`RobotAgent` is a unicycle (eq. 6.2) driven by the via-point law of eq. 6.3 (holonomic
velocity projected on the heading, heading steered by ``K_w * beta``, circular arrival
region), localized by an EKF whose prediction is the discrete unicycle and whose observations
are ranges to localized nodes (eq. 6.4). The per-step loop is the compiled kernel
:func:`robot_leg_kernel`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.frames import wrap_angle
from hrtls.kernels import njit
from hrtls.wsn.ranging import AgentLeg, Landmarks, RangeScan, RangeWorld

__all__ = ["RobotAgent", "RobotParams", "RobotState", "robot_leg_kernel", "robot_leg_reference"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class RobotParams:
    """Robot and controller parameters (thesis Sec. 6.4, eq. 6.2-6.4).

    Attributes
    ----------
    dt_s:
        Integration / control period, s.
    k_p_per_s:
        Gain of the holonomic velocity ``u_vh = k_p (target - p)``, 1/s.
    k_v:
        ``u_v = k_v ||u_vh|| cos(beta)`` (eq. 6.3a), dimensionless.
    k_w_per_s:
        ``u_w = k_w beta`` (eq. 6.3b), 1/s.
    max_speed_m_s, max_turn_rate_rad_s:
        Saturations of ``u_v`` and ``u_w``.
    arrival_radius_m:
        Radius of the circular via-point region where the robot stops.
    speed_noise_fraction, turn_rate_noise_rad_s:
        Odometry errors (true velocity = commanded * (1 + n_v), turn rate + n_w), per step.
    range_noise_fraction:
        Relative range sigma assumed by the EKF.
    range_every_steps:
        EKF range update period in steps.
    max_steps:
        Step limit of one leg.
    """

    dt_s: float = 0.05
    k_p_per_s: float = 2.0
    k_v: float = 1.0
    k_w_per_s: float = 4.0
    max_speed_m_s: float = 0.2
    max_turn_rate_rad_s: float = 3.0
    arrival_radius_m: float = 0.005
    speed_noise_fraction: float = 0.0
    turn_rate_noise_rad_s: float = 0.0
    range_noise_fraction: float = 0.0
    range_every_steps: int = 5
    max_steps: int = 20000

    def __post_init__(self) -> None:
        positive = ("dt_s", "k_p_per_s", "k_v", "k_w_per_s", "max_speed_m_s",
                    "max_turn_rate_rad_s", "arrival_radius_m")
        for name in positive:
            if not getattr(self, name) > 0:
                raise InputError(f"{name} = {getattr(self, name)}", where="RobotParams",
                                 expected="a positive number")
        if self.range_every_steps < 1 or self.max_steps < 1:
            raise InputError("step counts must be >= 1", where="RobotParams", expected=">= 1")


@njit(cache=True)
def _wrap(a: float) -> float:
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@njit(cache=True)
def robot_leg_kernel(
    true_pose: FloatArray,
    est_pose: FloatArray,
    cov: FloatArray,
    target: FloatArray,
    lm_est: FloatArray,
    lm_true: FloatArray,
    lm_sigma: float,
    radio_range: float,
    dt: float,
    k_p: float,
    k_v: float,
    k_w: float,
    v_max: float,
    w_max: float,
    arrival: float,
    sv: float,
    sw: float,
    sr: float,
    range_every: int,
    max_steps: int,
    seed: int,
    path_true: FloatArray,
    path_est: FloatArray,
) -> tuple[int, float, bool]:
    """Drive to ``target`` (in place on poses and covariance); returns steps, length, reached.

    Unicycle (eq. 6.2) integrated with period ``dt``; control (eq. 6.3) computed on the estimated
    pose; EKF prediction with the commanded velocities and odometry noise; range updates
    (eq. 6.4) to landmarks heard within ``radio_range`` every ``range_every`` steps.
    """
    if seed >= 0:
        np.random.seed(seed)  # noqa: NPY002 - numba's own generator, seeded per leg
    length = 0.0
    reached = False
    n = 0
    for step in range(max_steps):
        ex = target[0] - est_pose[0]
        ey = target[1] - est_pose[1]
        if math.sqrt(ex * ex + ey * ey) <= arrival:
            reached = True
            break
        # eq. 6.3: holonomic velocity, its projection on the heading, steering of beta
        uhx = k_p * ex
        uhy = k_p * ey
        beta = _wrap(math.atan2(uhy, uhx) - est_pose[2])
        uv = k_v * math.sqrt(uhx * uhx + uhy * uhy) * math.cos(beta)
        uw = k_w * beta
        uv = min(max(uv, -v_max), v_max)
        uw = min(max(uw, -w_max), w_max)
        # true motion with odometry error (eq. 6.2, Euler step)
        tv = uv
        tw = uw
        if sv > 0.0:
            tv = uv * (1.0 + sv * np.random.normal())  # noqa: NPY002
        if sw > 0.0:
            tw = uw + sw * np.random.normal()  # noqa: NPY002
        ox = true_pose[0]
        oy = true_pose[1]
        true_pose[0] += tv * dt * math.cos(true_pose[2])
        true_pose[1] += tv * dt * math.sin(true_pose[2])
        true_pose[2] = _wrap(true_pose[2] + tw * dt)
        length += math.sqrt((true_pose[0] - ox) ** 2 + (true_pose[1] - oy) ** 2)
        # EKF prediction with the commanded velocities
        c = math.cos(est_pose[2])
        s = math.sin(est_pose[2])
        f02 = -uv * dt * s
        f12 = uv * dt * c
        est_pose[0] += uv * dt * c
        est_pose[1] += uv * dt * s
        est_pose[2] = _wrap(est_pose[2] + uw * dt)
        # P = F P F^T + G Q G^T with F = I + [[0,0,f02],[0,0,f12],[0,0,0]]
        p = cov.copy()
        for i in range(3):
            cov[0, i] = p[0, i] + f02 * p[2, i]
            cov[1, i] = p[1, i] + f12 * p[2, i]
            cov[2, i] = p[2, i]
        p = cov.copy()
        for i in range(3):
            cov[i, 0] = p[i, 0] + f02 * p[i, 2]
            cov[i, 1] = p[i, 1] + f12 * p[i, 2]
            cov[i, 2] = p[i, 2]
        qv = (sv * abs(uv) * dt) ** 2
        cov[0, 0] += qv * c * c
        cov[0, 1] += qv * c * s
        cov[1, 0] += qv * c * s
        cov[1, 1] += qv * s * s
        cov[2, 2] += (sw * dt) ** 2
        # range updates (eq. 6.4)
        if (step + 1) % range_every == 0:
            for k in range(lm_est.shape[0]):
                tdx = true_pose[0] - lm_true[k, 0]
                tdy = true_pose[1] - lm_true[k, 1]
                dtrue = math.sqrt(tdx * tdx + tdy * tdy)
                if dtrue > radio_range:
                    continue
                z = dtrue
                if sr > 0.0:
                    z = dtrue * (1.0 + sr * np.random.normal())  # noqa: NPY002
                dx = est_pose[0] - lm_est[k, 0]
                dy = est_pose[1] - lm_est[k, 1]
                h = math.sqrt(dx * dx + dy * dy)
                if h < 1e-9:
                    continue
                h0 = dx / h
                h1 = dy / h
                r = (sr * z) ** 2 + lm_sigma**2 + 1e-12
                ph0 = cov[0, 0] * h0 + cov[0, 1] * h1
                ph1 = cov[1, 0] * h0 + cov[1, 1] * h1
                ph2 = cov[2, 0] * h0 + cov[2, 1] * h1
                sinn = h0 * ph0 + h1 * ph1 + r
                innov = z - h
                if innov * innov > 16.0 * sinn:
                    continue
                k0 = ph0 / sinn
                k1 = ph1 / sinn
                k2 = ph2 / sinn
                est_pose[0] += k0 * innov
                est_pose[1] += k1 * innov
                est_pose[2] = _wrap(est_pose[2] + k2 * innov)
                kv = (k0, k1, k2)
                hp = (ph0, ph1, ph2)
                for i in range(3):
                    for j in range(3):
                        cov[i, j] -= kv[i] * hp[j]
                for i in range(3):
                    for j in range(i + 1, 3):
                        m = 0.5 * (cov[i, j] + cov[j, i])
                        cov[i, j] = m
                        cov[j, i] = m
        if n < path_true.shape[0]:
            path_true[n, 0] = true_pose[0]
            path_true[n, 1] = true_pose[1]
            path_est[n, 0] = est_pose[0]
            path_est[n, 1] = est_pose[1]
            n += 1
    return n, length, reached


def robot_leg_reference(
    true_pose: FloatArray, target: FloatArray, params: RobotParams
) -> tuple[FloatArray, float]:
    """Noise-free pure-Python unicycle + eq. 6.3 controller (test reference for the kernel).

    Returns the true path ``(k, 2)`` and its length.
    """
    x, y, phi = (float(v) for v in true_pose)
    path = []
    length = 0.0
    for _ in range(params.max_steps):
        ex, ey = float(target[0]) - x, float(target[1]) - y
        if math.hypot(ex, ey) <= params.arrival_radius_m:
            break
        uh = params.k_p_per_s * np.array([ex, ey])
        beta = float(wrap_angle(math.atan2(uh[1], uh[0]) - phi))
        uv = params.k_v * float(np.hypot(*uh)) * math.cos(beta)
        uw = params.k_w_per_s * beta
        uv = float(np.clip(uv, -params.max_speed_m_s, params.max_speed_m_s))
        uw = float(np.clip(uw, -params.max_turn_rate_rad_s, params.max_turn_rate_rad_s))
        nx = x + uv * params.dt_s * math.cos(phi)
        ny = y + uv * params.dt_s * math.sin(phi)
        length += math.hypot(nx - x, ny - y)
        x, y = nx, ny
        phi = float(wrap_angle(phi + uw * params.dt_s))
        path.append((x, y))
    return np.array(path).reshape(-1, 2), length


@dataclass(frozen=True, eq=False)
class RobotState:
    """Saved state of a :class:`RobotAgent` (true and estimated pose, EKF covariance)."""

    true_pose: FloatArray
    est_pose: FloatArray
    cov: FloatArray
    distance_m: float
    legs: int

    def to_dict(self) -> dict[str, object]:
        """JSON-able form."""
        return {"true_pose": self.true_pose.tolist(), "est_pose": self.est_pose.tolist(),
                "cov": self.cov.tolist(), "distance_m": self.distance_m, "legs": self.legs}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> RobotState:
        """Inverse of :meth:`to_dict`."""
        try:
            st = cls(true_pose=np.asarray(d["true_pose"], float).reshape(3),
                     est_pose=np.asarray(d["est_pose"], float).reshape(3),
                     cov=np.asarray(d["cov"], float).reshape(3, 3),
                     distance_m=float(d["distance_m"]),  # type: ignore[arg-type]
                     legs=int(d["legs"]))  # type: ignore[call-overload]
        except (KeyError, ValueError, TypeError) as exc:
            raise InputError(f"bad robot state ({exc})", where="RobotState.from_dict",
                             expected="keys true_pose, est_pose, cov, distance_m, legs") from None
        if not (np.all(np.isfinite(st.est_pose)) and np.all(np.isfinite(st.cov))):
            raise InputError("non-finite robot state", where="RobotState.from_dict",
                             expected="finite numbers")
        return st


class RobotAgent:
    """Unicycle robot with the via-point controller and a range EKF (implements MobileAgent).

    Parameters
    ----------
    world:
        Simulated radio (:class:`RangeWorld`).
    start_pose:
        True start ``[x, y, heading]`` (m, m, rad); the estimate starts there too.
    params:
        :class:`RobotParams`.
    start_sigma_m:
        Standard deviation of the initial position estimate, m.
    seed:
        Seed of the odometry / range noise of the compiled kernel.
    """

    def __init__(self, world: RangeWorld, start_pose: FloatArray, *, params: RobotParams,
                 start_sigma_m: float = 0.0, seed: int = 0) -> None:
        self.world = world
        self.params = params
        self.true_pose = np.array(start_pose, dtype=np.float64).reshape(3)
        self.est_pose = self.true_pose.copy()
        self.cov = np.diag([start_sigma_m**2, start_sigma_m**2, 1e-6])
        self._seed = int(seed)
        self._legs = 0
        self.distance_m = 0.0

    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Current position estimate and 2x2 covariance."""
        return self.est_pose[:2].copy(), self.cov[:2, :2].copy()

    def state(self) -> RobotState:
        """Snapshot of the robot (for save / restore)."""
        return RobotState(true_pose=self.true_pose.copy(), est_pose=self.est_pose.copy(),
                          cov=self.cov.copy(), distance_m=self.distance_m, legs=self._legs)

    def restore(self, state: RobotState) -> None:
        """Continue from a snapshot taken by :meth:`state`."""
        self.true_pose = state.true_pose.copy()
        self.est_pose = state.est_pose.copy()
        self.cov = state.cov.copy()
        self.distance_m = state.distance_m
        self._legs = state.legs

    def scan(self) -> RangeScan:
        """Ranges heard at the current (true) position."""
        return self.world.scan_at(self.true_pose[:2])

    def go_to(self, target_m: FloatArray, landmarks: Landmarks) -> AgentLeg:
        """Drive to ``target_m`` with the compiled unicycle/controller/EKF kernel."""
        tgt = np.asarray(target_m, dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(tgt)):
            raise InputError("non-finite target", where="RobotAgent.go_to", expected="finite")
        prm = self.params
        cap = prm.max_steps
        pt = np.zeros((cap, 2))
        pe = np.zeros((cap, 2))
        lm_est = np.asarray(landmarks.position_m, dtype=np.float64).reshape(-1, 2)
        lm_true = self.world.true_positions_m[np.asarray(landmarks.node, dtype=np.int64)]
        noisy = prm.speed_noise_fraction > 0 or prm.turn_rate_noise_rad_s > 0 or (
            prm.range_noise_fraction > 0)
        seed = (self._seed * 100003 + self._legs) % (2**31 - 1) if noisy else -1
        self._legs += 1
        n, length, reached = robot_leg_kernel(
            self.true_pose, self.est_pose, self.cov, tgt, lm_est, lm_true,
            float(np.max(landmarks.sigmas(), initial=0.0)), float(self.world.radio_range_m),
            prm.dt_s, prm.k_p_per_s,
            prm.k_v, prm.k_w_per_s, prm.max_speed_m_s, prm.max_turn_rate_rad_s,
            prm.arrival_radius_m, prm.speed_noise_fraction, prm.turn_rate_noise_rad_s,
            prm.range_noise_fraction, prm.range_every_steps, prm.max_steps, seed, pt, pe,
        )
        self.distance_m += length
        est, cov = self.estimate()
        return AgentLeg(estimate_m=est, covariance_m2=cov, true_m=self.true_pose[:2].copy(),
                        path_m=pe[:n].copy(), path_true_m=pt[:n].copy(), length_m=float(length),
                        reached=bool(reached), scan=self.scan())
