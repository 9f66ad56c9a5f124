"""Floors from the filter's height: index, level, and a level constraint after stairs.

The 3-D step prediction (Inderst eq. 4.25) moves z by the stair height on every stair step, so
z drifts by a fraction of a riser per flight. Floors are ``round((z - ground_z) / floor_height)``
and, once the user walks flat again, :func:`floor_level_update` pulls z to the level of the nearest
floor with a soft (gated) pseudo-measurement. This is our addition; the thesis only reports the
floor through z.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion.gating import UpdateDiagnostics, kalman_update
from hrtls.fusion.state import IH, IZ, N_STATE, FilterState


def floor_index(z_m: ArrayLike, floor_height_m: float, *, ground_z_m: float = 0.0
                ) -> np.ndarray:
    """Floor numbers ``round((z - ground_z) / floor_height)`` (int64, same shape as ``z``)."""
    h = finite_scalar(floor_height_m, where="floor_height_m", positive=True)
    z = np.asarray(z_m, dtype=np.float64)
    return np.asarray(np.rint((z - ground_z_m) / h), dtype=np.int64)


def floor_level(index: ArrayLike, floor_height_m: float, *, ground_z_m: float = 0.0
                ) -> FloatArray:
    """Height of floor ``index``, m."""
    h = finite_scalar(floor_height_m, where="floor_height_m", positive=True)
    return np.asarray(ground_z_m + h * np.asarray(index, dtype=np.float64))


def floor_level_update(state: FilterState, floor_height_m: float, *, sigma_m: float = 0.1,
                       ground_z_m: float = 0.0, gate_probability: float | None = 0.999
                       ) -> tuple[FilterState, UpdateDiagnostics]:
    """Pseudo-measurement ``z = level of the nearest floor`` with 1-sigma ``sigma_m``."""
    level = float(floor_level(floor_index(state.x[IZ], floor_height_m, ground_z_m=ground_z_m),
                              floor_height_m, ground_z_m=ground_z_m))
    h = np.zeros((1, N_STATE))
    h[0, IZ] = 1.0
    s = finite_scalar(sigma_m, where="floor sigma_m", positive=True)
    res = kalman_update(state.x, state.P, h, np.array([[s * s]]),
                        np.array([level - state.x[IZ]]), gate_probability=gate_probability,
                        kind="floor", t=state.t, angle_index=IH)
    return state.evolve(x=res.x, P=res.P), res.diagnostics
