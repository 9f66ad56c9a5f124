"""Prediction without motion sensors: a random walk of the position (and heading).

When a session has no IMU (infrastructure only: RSS, ranges or tags alone, like Tarrio's "RSS
alone" baseline) the filter still needs a prediction between observations. The position stays
where it is and its covariance grows like that of a walker of unknown direction,
``P_xy += sigma_speed^2 dt I`` (a velocity white-noise model), ``P_zz += sigma_vertical^2 dt``,
``P_hh += sigma_heading_rate^2 dt``. This is our addition; none of the papers needs it.

:func:`random_walk_covariance` is the compiled growth on plain arrays (with the parameters as a
:data:`RANDOM_WALK_DTYPE` record), shared by :func:`predict_random_walk` and the tracker's
event loop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion._records import to_record
from hrtls.fusion.state import FilterState
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True)
class RandomWalkParams:
    """Growth rates of the random walk.

    Attributes
    ----------
    sigma_speed_m_per_sqrt_s: horizontal diffusion, m/sqrt(s) (a walker: about 1).
    sigma_vertical_m_s: vertical, m/s.
    sigma_heading_rate_rad_s: heading, rad/s.
    """

    sigma_speed_m_per_sqrt_s: float = 1.0
    sigma_vertical_m_s: float = 0.05
    sigma_heading_rate_rad_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("sigma_speed_m_per_sqrt_s", "sigma_vertical_m_s",
                     "sigma_heading_rate_rad_s"):
            finite_scalar(getattr(self, name), where=f"RandomWalkParams.{name}",
                          non_negative=True)

    def record(self) -> np.ndarray:
        """The parameters as a one-element :data:`RANDOM_WALK_DTYPE` array."""
        return to_record(RANDOM_WALK_DTYPE, self)


RANDOM_WALK_DTYPE = np.dtype([("sigma_speed_m_per_sqrt_s", np.float64),
                              ("sigma_vertical_m_s", np.float64),
                              ("sigma_heading_rate_rad_s", np.float64)])
"""Record of :class:`RandomWalkParams` for compiled code (same field names)."""


@njit(cache=True, error_model="numpy")
def random_walk_covariance(prm: np.record, p: FloatArray, dt: float) -> None:
    # pragma: no cover - compiled
    """Grow the covariance ``p`` over ``dt`` seconds in place (``prm``: a random-walk record)."""
    p[0, 0] += prm.sigma_speed_m_per_sqrt_s ** 2 * dt
    p[1, 1] += prm.sigma_speed_m_per_sqrt_s ** 2 * dt
    p[2, 2] += prm.sigma_vertical_m_s ** 2 * dt
    p[3, 3] += prm.sigma_heading_rate_rad_s ** 2 * dt


def predict_random_walk(state: FilterState, t: float,
                        params: RandomWalkParams | None = None) -> FilterState:
    """Advance ``state`` to time ``t`` (>= ``state.t``) without moving it."""
    prm = params or RandomWalkParams()
    tt = finite_scalar(t, where="random walk t")
    if tt < state.t:
        raise InputError(f"t = {tt} s is before the filter time {state.t} s",
                         where="random walk t", expected="time order")
    p = state.P.copy()
    random_walk_covariance(prm.record()[0], p, tt - state.t)
    return state.evolve(t=tt, P=p)
