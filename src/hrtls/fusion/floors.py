"""Floors from the filter's height: index, level, and a level constraint after stairs.

The 3-D step prediction (Inderst eq. 4.25) moves z by the stair height on every stair step, so
z drifts by a fraction of a riser per flight. Floors are ``round((z - ground_z) / floor_height)``
and, once the user walks flat again, :func:`floor_level_update` pulls z to the level of the nearest
floor with a soft (gated) pseudo-measurement. This is our addition; the thesis only reports the
floor through z.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    chi2_threshold,
    scalar_diagnostics,
    scalar_update,
)
from hrtls.fusion.state import FilterState


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


@numba.njit(cache=True, error_model="numpy")
def floor_level_correction(x: FloatArray, p: FloatArray, floor_height_m: float,
                           ground_z_m: float, sigma_m: float, threshold: float, gated: bool
                           ) -> tuple[int, float, float, float]:  # pragma: no cover - compiled
    """Pull ``z = x[2]`` to the level of the nearest floor, in place (compiled core).

    Returns ``(code, nis, S, nu)`` of the scalar update (see
    :func:`hrtls.fusion.gating.scalar_update`).
    """
    level = ground_z_m + floor_height_m * np.rint((x[2] - ground_z_m) / floor_height_m)
    nu = level - x[2]
    code, nis, s = scalar_update(x, p, (0.0, 0.0, 1.0, 0.0), sigma_m * sigma_m, nu, threshold,
                                 gated)
    return code, nis, s, nu


def floor_level_update(state: FilterState, floor_height_m: float, *, sigma_m: float = 0.1,
                       ground_z_m: float = 0.0, gate_probability: float | None = 0.999
                       ) -> tuple[FilterState, UpdateDiagnostics]:
    """Pseudo-measurement ``z = level of the nearest floor`` with 1-sigma ``sigma_m``."""
    h = finite_scalar(floor_height_m, where="floor_height_m", positive=True)
    s = finite_scalar(sigma_m, where="floor sigma_m", positive=True)
    ground = finite_scalar(ground_z_m, where="floor ground_z_m")
    threshold = math.inf if gate_probability is None else chi2_threshold(1, gate_probability)
    x, p = state.x.copy(), state.P.copy()
    code, nis, s_inn, nu = floor_level_correction(x, p, h, ground, s, threshold,
                                                  gate_probability is not None)
    diag = scalar_diagnostics("floor", state.t, code, nis, s_inn, nu, threshold)
    return (state.evolve(x=x, P=p) if diag.accepted else state), diag
