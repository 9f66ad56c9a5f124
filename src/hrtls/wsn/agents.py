"""Mobile agents for sensor-network localization: the interface, a robot and a simple rescuer.

Both kinds of agent (Inderst thesis Sec. 5.3-5.4 and 6.4) do the same three things for the
network algorithms: walk or drive to a target point, report where they think they are (with a
covariance), and report the ranges to the nodes they hear there. :class:`MobileAgent` is that
protocol; the real rescuer filter (PDR with range corrections) can implement it later.

* :class:`RobotAgent` - unicycle (eq. 6.2) driven by the via-point law of eq. 6.3 (holonomic
  velocity projected on the heading, heading steered by ``K_w * beta``, circular arrival region),
  localized by an EKF whose prediction is the discrete unicycle and whose observations are ranges
  to localized nodes (eq. 6.4). The per-step loop is a compiled kernel.
* :class:`RescuerAgent` - a simulated walker: straight steps toward the target, dead-reckoning
  error that grows with distance (heading and step-length noise), and the same range update at
  each correction.

Simulation of the radio is :class:`RangeWorld`: true node positions, the link radius ``rho``
(the agent at a way point is a temporary node of the disk graph) and the agent's radio range
``d_r`` (Theorem 2 uses ``d_r = 2 rho``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numba
import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.frames import wrap_angle

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


# ------------------------------------------------------------------------------------------
# Interfaces
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RangeScan:
    """Ranges an agent measured at one place.

    Attributes
    ----------
    node:
        Indices of the nodes heard (within the agent's radio range).
    range_m:
        Measured distances, m.
    linked:
        True for nodes within the link radius ``rho`` (the agent acts as a disk-graph node).
    """

    node: IntArray
    range_m: FloatArray
    linked: BoolArray


@dataclass(frozen=True, eq=False)
class Landmarks:
    """Localized nodes an agent may use for range corrections.

    ``node`` are their indices, ``position_m`` their estimated positions and ``sigma_m`` the
    standard deviation of those positions (one value for all, or one per landmark), m.
    """

    node: IntArray
    position_m: FloatArray
    sigma_m: float | FloatArray = 0.0

    def sigmas(self) -> FloatArray:
        """Per-landmark position sigma, ``(k,)``."""
        return np.broadcast_to(np.asarray(self.sigma_m, dtype=np.float64),
                               (np.asarray(self.node).size,)).copy()


@dataclass(frozen=True, eq=False)
class AgentLeg:
    """Outcome of one ``go_to``.

    Attributes
    ----------
    estimate_m, covariance_m2:
        Agent's position estimate at arrival and its 2x2 covariance.
    true_m:
        True position at arrival (simulation; equals the estimate for real agents without truth).
    path_m, path_true_m:
        Estimated and true positions along the leg, ``(k, 2)``.
    length_m:
        Distance travelled (true), m.
    reached:
        False when the agent gave up (step limit).
    scan:
        Ranges heard at the arrival point.
    """

    estimate_m: FloatArray
    covariance_m2: FloatArray
    true_m: FloatArray
    path_m: FloatArray
    path_true_m: FloatArray
    length_m: float
    reached: bool
    scan: RangeScan


class MobileAgent(Protocol):
    """What the network algorithms need from a rescuer or a robot."""

    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Current position estimate (2,) and covariance (2, 2)."""
        ...

    def go_to(self, target_m: FloatArray, landmarks: Landmarks) -> AgentLeg:
        """Move to ``target_m`` using ``landmarks`` for range corrections; report arrival."""
        ...

    def scan(self) -> RangeScan:
        """Ranges to the nodes heard at the current place."""
        ...


@dataclass(eq=False)
class RangeWorld:
    """Simulated radio: true node positions, link radius, agent radio range and range noise.

    Parameters
    ----------
    true_positions_m:
        ``(n, 2)`` true node positions.
    link_radius_m:
        ``rho``: the agent is linked to nodes within this distance (disk model).
    radio_range_m:
        The agent hears nodes (and measures their range) within this distance (``>= rho``).
    range_noise_fraction:
        Range standard deviation as a fraction of the true range.
    rng:
        Random generator of the range noise.
    """

    true_positions_m: FloatArray
    link_radius_m: float
    radio_range_m: float
    range_noise_fraction: float = 0.0
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))

    def __post_init__(self) -> None:
        self.true_positions_m = np.asarray(self.true_positions_m, dtype=np.float64).reshape(-1, 2)
        if not (0 < self.link_radius_m <= self.radio_range_m):
            raise InputError(f"rho={self.link_radius_m}, d_r={self.radio_range_m}",
                             where="RangeWorld", expected="0 < link_radius_m <= radio_range_m")

    def scan_at(self, true_m: FloatArray) -> RangeScan:
        """Ranges heard from the true position ``true_m``."""
        d = np.linalg.norm(self.true_positions_m - np.asarray(true_m).reshape(1, 2), axis=1)
        idx = np.flatnonzero(d <= self.radio_range_m)
        r = d[idx]
        if self.range_noise_fraction > 0 and idx.size:
            r = r * (1.0 + self.range_noise_fraction * self.rng.standard_normal(idx.size))
            r = np.maximum(r, 0.0)
        return RangeScan(node=idx.astype(np.int64), range_m=r,
                         linked=d[idx] <= self.link_radius_m)


def range_update(
    x: FloatArray,
    p: FloatArray,
    landmarks_m: FloatArray,
    ranges_m: FloatArray,
    sigma_m: FloatArray,
    *,
    gate_sigma: float = 4.0,
    iterations: int = 1,
) -> tuple[FloatArray, FloatArray, int]:
    """EKF update with range observations ``d = ||p_j - p_r||`` (thesis eq. 6.4).

    ``x`` may be ``[x, y]`` or ``[x, y, heading]`` (only the position is observed). Observations
    whose innovation exceeds ``gate_sigma`` standard deviations (at the prior) are skipped. With
    ``iterations > 1`` all ranges are fused in one batch by the iterated EKF (relinearized at the
    current iterate), which avoids the overconfidence of a single linearization when the prior is
    much wider than the ranges. Returns the new state, covariance and the number of used ranges.
    """
    xs = np.array(x, dtype=np.float64, copy=True)
    ps = np.array(p, dtype=np.float64, copy=True)
    lm = np.asarray(landmarks_m, dtype=np.float64).reshape(-1, 2)
    z = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    sg = np.asarray(sigma_m, dtype=np.float64).reshape(-1)
    dim = xs.size

    def jac(xx: FloatArray, idx: IntArray) -> tuple[FloatArray, FloatArray]:
        d = xx[:2][None, :] - lm[idx]
        h = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
        hm = np.zeros((idx.size, dim))
        hm[:, :2] = d / h[:, None]
        return h, hm

    h0, hm0 = jac(xs, np.arange(z.size))
    s0 = np.einsum("ij,jk,ik->i", hm0, ps, hm0) + sg**2
    use = np.flatnonzero((h0 > 1e-9) & ((z - h0) ** 2 <= gate_sigma**2 * s0))
    if use.size == 0:
        return xs, ps, 0
    if iterations <= 1:
        for k in use.tolist():  # sequential scalar updates, Joseph form
            hk, hmk = jac(xs, np.array([k]))
            row = hmk[0]
            s = float(row @ ps @ row) + float(sg[k]) ** 2
            kg = ps @ row / s
            xs = xs + kg * float(z[k] - hk[0])
            ikh = np.eye(dim) - np.outer(kg, row)
            ps = ikh @ ps @ ikh.T + np.outer(kg, kg) * float(sg[k]) ** 2
        return xs, 0.5 * (ps + ps.T), int(use.size)
    r = np.diag(sg[use] ** 2)
    x0 = xs.copy()
    xi = xs.copy()
    kg = np.zeros((dim, use.size))
    hm = np.zeros((use.size, dim))
    for _ in range(iterations):
        h, hm = jac(xi, use)
        smat = hm @ ps @ hm.T + r
        kg = np.linalg.solve(smat, hm @ ps).T
        xi = x0 + kg @ (z[use] - h - hm @ (x0 - xi))
    ikh = np.eye(dim) - kg @ hm
    ps = ikh @ ps @ ikh.T + kg @ r @ kg.T
    return xi, 0.5 * (ps + ps.T), int(use.size)


# ------------------------------------------------------------------------------------------
# Robot: unicycle + via-point controller + range EKF
# ------------------------------------------------------------------------------------------
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


@numba.njit(cache=True)
def _wrap(a: float) -> float:
    return math.pi - ((math.pi - a) % (2.0 * math.pi))


@numba.njit(cache=True)
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


# ------------------------------------------------------------------------------------------
# Rescuer: simple simulated walker
# ------------------------------------------------------------------------------------------
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
