"""Velocity-driven position prediction (Colombo et al. 2014, Sec. III-D, eq. 15-17).

The walking speed ``v`` along the body's forward axis (the hybrid-automaton output of
:mod:`hrtls.gait`) and the yaw ``theta`` from the attitude filter drive the nonholonomic model
``dp/dt = s(theta) v`` with ``s = [cos, sin]`` (eq. 15; in ENU with yaw CCW from east, which is the
same formula as the paper's frame once the yaw is expressed in ours). Discretized per sample
(eq. 16) and with the covariance of eq. 17::

    p(k) = p(k-1) + dt_k s(theta_k) v_k
    P(k) = F P(k-1) F^T + G_v var_v G_v^T,   F = I + d/d(heading),  G_v = dt_k s(theta_k)

Reading: the paper propagates with the input of sample ``k`` over ``[t_k, t_k+1]``; we apply
the input of sample ``k`` over ``(t_k-1, t_k]`` (backward rectangle) so that a chunked run is
exactly the same as one batch run without storing the previous input; at 100-250 Hz the
difference is below a millimetre per step.

In ``heading_mode="input"`` (the paper) the state heading is overwritten each sample by the
attitude yaw with its variance ``sigma_theta^2`` (cross terms cleared); ``F P F^T`` then adds
exactly ``G_theta sigma_theta^2 G_theta^T`` of eq. 17. In ``heading_mode="state"`` yaw *changes* are
integrated into the state heading, whose variance grows by ``heading_rate_var`` per second;
the first yaw only sets the reference, unless the state heading is less certain than it (an
unknown start heading), then the state adopts it.

The per-sample loop is a numba kernel (:func:`velocity_kernel`) over plain arrays; the wrapper
validates input. The vertical coordinate is not changed (the paper's model is planar).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.fusion._checks import (
    FloatArray,
    broadcast_vector,
    finite_scalar,
    finite_vector,
    non_decreasing_time,
)
from hrtls.fusion.state import FilterState
from hrtls.kernels import njit

HeadingMode = Literal["input", "state"]


@njit(cache=True)
def _wrap(a: float) -> float:  # pragma: no cover - compiled
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@njit(cache=True)
def velocity_kernel(t: FloatArray, speed: FloatArray, yaw: FloatArray, var_yaw: FloatArray,
                    var_speed: FloatArray, t0: float, x: FloatArray, p: FloatArray,
                    mode_state: bool, prev_yaw: float, has_prev: bool, heading_rate_var: float,
                    xs_out: FloatArray, covxy_out: FloatArray, varh_out: FloatArray
                    ) -> tuple[float, bool]:  # pragma: no cover - compiled
    """Eq. 16-17 over all samples; ``x`` (4,) and ``p`` (4, 4) are updated in place.

    Returns the last yaw input and whether it is set (the ``input_heading`` of the state).
    """
    t_prev = t0
    for k in range(t.shape[0]):
        dt = t[k] - t_prev
        t_prev = t[k]
        # heading input
        if mode_state:
            if has_prev:
                x[3] = _wrap(x[3] + _wrap(yaw[k] - prev_yaw))
                p[3, 3] += heading_rate_var * dt
            elif p[3, 3] > var_yaw[k]:
                # first input knows the heading better than the state: adopt it
                x[3] = _wrap(yaw[k])
                for i in range(4):
                    p[3, i] = 0.0
                    p[i, 3] = 0.0
                p[3, 3] = var_yaw[k]
        else:
            x[3] = _wrap(yaw[k])
            for i in range(4):
                p[3, i] = 0.0
                p[i, 3] = 0.0
            p[3, 3] = var_yaw[k]
        prev_yaw = yaw[k]
        has_prev = True
        c = np.cos(x[3])
        s = np.sin(x[3])
        v = speed[k]
        # eq. 16
        x[0] += dt * c * v
        x[1] += dt * s * v
        # eq. 17: F P F^T with F = I + a e0 e3^T + b e1 e3^T
        a = -dt * v * s
        b = dt * v * c
        for j in range(4):
            p[0, j] += a * p[3, j]
            p[1, j] += b * p[3, j]
        for i in range(4):
            p[i, 0] += a * p[i, 3]
            p[i, 1] += b * p[i, 3]
        # + G_v var_v G_v^T
        g = dt * dt * var_speed[k]
        p[0, 0] += g * c * c
        p[0, 1] += g * c * s
        p[1, 0] += g * c * s
        p[1, 1] += g * s * s
        for i in range(4):
            xs_out[k, i] = x[i]
        covxy_out[k, 0, 0] = p[0, 0]
        covxy_out[k, 0, 1] = p[0, 1]
        covxy_out[k, 1, 0] = p[1, 0]
        covxy_out[k, 1, 1] = p[1, 1]
        varh_out[k] = p[3, 3]
    return prev_yaw, has_prev


def velocity_reference(t: FloatArray, speed: FloatArray, yaw: FloatArray, var_yaw: FloatArray,
                       var_speed: FloatArray, state: FilterState, mode_state: bool,
                       heading_rate_var: float) -> tuple[FloatArray, FloatArray]:
    """Slow pure-numpy version of :func:`velocity_kernel` (matrices written out), for tests.

    Returns the final ``x`` and ``P``.
    """
    x = state.x.copy()
    p = state.P.copy()
    t_prev = state.t
    prev, has_prev = state.input_heading_rad, state.has_input_heading
    for k in range(len(t)):
        dt = t[k] - t_prev
        t_prev = t[k]
        if mode_state:
            if has_prev:
                x[3] = np.angle(np.exp(1j * (x[3] + yaw[k] - prev)))
                p[3, 3] += heading_rate_var * dt
            elif p[3, 3] > var_yaw[k]:
                x[3] = np.angle(np.exp(1j * yaw[k]))
                p[3, :] = 0.0
                p[:, 3] = 0.0
                p[3, 3] = var_yaw[k]
        else:
            x[3] = np.angle(np.exp(1j * yaw[k]))
            p[3, :] = 0.0
            p[:, 3] = 0.0
            p[3, 3] = var_yaw[k]
        prev, has_prev = yaw[k], True
        sv = np.array([np.cos(x[3]), np.sin(x[3])])
        x[:2] += dt * sv * speed[k]
        f = np.eye(4)
        f[:2, 3] = dt * speed[k] * np.array([-sv[1], sv[0]])
        gv = np.zeros(4)
        gv[:2] = dt * sv
        p = f @ p @ f.T + np.outer(gv, gv) * var_speed[k]
    return x, p


@dataclass(frozen=True, kw_only=True)
class VelocityPredictionParams:
    """Parameters of the velocity-driven prediction.

    Attributes
    ----------
    sigma_speed_m_s:
        1-sigma of the walking speed when the caller gives no variance (``sigma_v`` of eq. 17).
    sigma_yaw_rad:
        1-sigma of the yaw when the caller gives no variance (``sigma_theta`` of eq. 17).
    heading_mode:
        ``"input"`` (paper) or ``"state"`` (see the module docstring).
    heading_rate_var_rad2_s:
        Heading random-walk intensity in ``"state"`` mode, rad^2/s.
    """

    sigma_speed_m_s: float = 0.1
    sigma_yaw_rad: float = 0.05
    heading_mode: HeadingMode = "input"
    heading_rate_var_rad2_s: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("sigma_speed_m_s", "sigma_yaw_rad", "heading_rate_var_rad2_s"):
            finite_scalar(getattr(self, name), where=f"VelocityPredictionParams.{name}",
                          non_negative=True)
        if self.heading_mode not in ("input", "state"):
            raise InputError(f"heading_mode {self.heading_mode!r}",
                             where="VelocityPredictionParams.heading_mode",
                             expected="'input' or 'state'")


@dataclass(frozen=True, slots=True, eq=False)
class VelocityPredictionResult:
    """Per-sample prediction.

    Attributes
    ----------
    t: sample times, s (N,).
    xyz: positions, m (N, 3).
    heading_rad: state heading, rad (N,).
    cov_xy: horizontal covariance, m^2 (N, 2, 2).
    var_heading: heading variance, rad^2 (N,).
    state: state after the last sample.
    """

    t: FloatArray
    xyz: FloatArray
    heading_rad: FloatArray
    cov_xy: FloatArray
    var_heading: FloatArray
    state: FilterState


class VelocityPredictor:
    """Colombo eq. 15-17 position prediction from walking speed and yaw."""

    def __init__(self, params: VelocityPredictionParams | None = None) -> None:
        self.params = params or VelocityPredictionParams()

    def run(self, state: FilterState, t: ArrayLike, speed_m_s: ArrayLike, yaw_rad: ArrayLike,
            var_yaw_rad2: ArrayLike | None = None,
            var_speed_m2_s2: ArrayLike | None = None) -> VelocityPredictionResult:
        """Propagate ``state`` through all samples (one chunk; call again with the next chunk).

        Parameters
        ----------
        state:
            State at (or before) the first sample.
        t:
            Sample times, s, non-decreasing and >= ``state.t``.
        speed_m_s:
            Forward walking speed, m/s (>= 0).
        yaw_rad:
            Yaw / heading of the body, rad (ENU, CCW from east).
        var_yaw_rad2, var_speed_m2_s2:
            Per-sample (or scalar) variances; defaults from the parameters.
        """
        tt = finite_vector(t, where="velocity t")
        n = tt.shape[0]
        non_decreasing_time(tt, where="velocity t", after=state.t)
        v = broadcast_vector(speed_m_s, n, where="velocity speed_m_s")
        if np.any(v < 0.0):
            idx = int(np.flatnonzero(v < 0.0)[0])
            raise InputError(f"speed {v[idx]}", where=f"velocity speed_m_s index {idx}",
                             expected="a forward speed >= 0 m/s")
        yaw = finite_vector(yaw_rad, where="velocity yaw_rad", length=n)
        prm = self.params
        vy = broadcast_vector(prm.sigma_yaw_rad**2 if var_yaw_rad2 is None else var_yaw_rad2, n,
                              where="velocity var_yaw_rad2", non_negative=True)
        vv = broadcast_vector(prm.sigma_speed_m_s**2 if var_speed_m2_s2 is None
                              else var_speed_m2_s2, n, where="velocity var_speed_m2_s2",
                              non_negative=True)
        x = state.x.copy()
        p = state.P.copy()
        xs = np.empty((n, 4))
        covxy = np.empty((n, 2, 2))
        varh = np.empty(n)
        prev, has_prev = velocity_kernel(tt, v, yaw, vy, vv, float(state.t), x, p,
                                         prm.heading_mode == "state", state.input_heading_rad,
                                         state.has_input_heading, prm.heading_rate_var_rad2_s,
                                         xs, covxy, varh)
        t_end = float(tt[-1]) if n else state.t
        new_state = FilterState(t_end, x, p, float(prev), bool(has_prev))
        return VelocityPredictionResult(tt, xs[:, :3].copy(), xs[:, 3].copy(), covxy, varh,
                                        new_state)
