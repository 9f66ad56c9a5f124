"""What a mobile agent exchanges with the network algorithms, and the simulated radio.

:class:`MobileAgent` is the protocol (go to a point, report the position estimate, scan the
ranges to the nodes heard there), with its :class:`RangeScan`, :class:`Landmarks` and
:class:`AgentLeg`; :class:`RangeWorld` simulates the radio (true node positions, the link
radius ``rho`` and the agent's radio range ``d_r``); :func:`range_update` corrects a position
estimate with ranges to localized nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

__all__ = ["AgentLeg", "Landmarks", "MobileAgent", "RangeScan", "RangeWorld", "range_update"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


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
