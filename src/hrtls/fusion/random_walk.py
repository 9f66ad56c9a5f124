"""Prediction without motion sensors: a random walk of the position (and heading).

When a session has no IMU (infrastructure only: RSS, ranges or tags alone, like Tarrio's "RSS
alone" baseline) the filter still needs a prediction between observations. The position stays
where it is and its covariance grows like that of a walker of unknown direction,
``P_xy += sigma_speed^2 dt I`` (a velocity white-noise model), ``P_zz += sigma_vertical^2 dt``,
``P_hh += sigma_heading_rate^2 dt``. This is our addition; none of the papers needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import finite_scalar
from hrtls.fusion.state import IH, IZ, FilterState


@dataclass(frozen=True, kw_only=True)
class RandomWalkParams:
    """Growth rates of the random walk.

    Attributes
    ----------
    sigma_speed_m_s: horizontal, m/s (a walker: about 1 m/s).
    sigma_vertical_m_s: vertical, m/s.
    sigma_heading_rate_rad_s: heading, rad/s.
    """

    sigma_speed_m_s: float = 1.0
    sigma_vertical_m_s: float = 0.05
    sigma_heading_rate_rad_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("sigma_speed_m_s", "sigma_vertical_m_s", "sigma_heading_rate_rad_s"):
            finite_scalar(getattr(self, name), where=f"RandomWalkParams.{name}",
                          non_negative=True)


def predict_random_walk(state: FilterState, t: float,
                        params: RandomWalkParams | None = None) -> FilterState:
    """Advance ``state`` to time ``t`` (>= ``state.t``) without moving it."""
    prm = params or RandomWalkParams()
    tt = finite_scalar(t, where="random walk t")
    if tt < state.t:
        raise InputError(f"t = {tt} s is before the filter time {state.t} s",
                         where="random walk t", expected="time order")
    dt = tt - state.t
    p = state.P.copy()
    p[0, 0] += prm.sigma_speed_m_s**2 * dt
    p[1, 1] += prm.sigma_speed_m_s**2 * dt
    p[IZ, IZ] += prm.sigma_vertical_m_s**2 * dt
    p[IH, IH] += prm.sigma_heading_rate_rad_s**2 * dt
    return state.evolve(t=tt, P=np.asarray(p))
