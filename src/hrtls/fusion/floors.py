"""Floors from the filter's height: index, level, the flight rule and a level constraint.

The 3-D step prediction (Inderst eq. 4.25) moves z by the stair height on every stair step, so
z drifts by a fraction of a riser per flight, and a classifier that labels part of a flight as
walking (its window lags, a landing looks flat) leaves z short of the next floor. Floors are
``round((z - ground_z) / floor_height)``; the floor itself is decided by the *flight rule*
(:func:`flight_step`, causal, one step at a time):

* a flight starts at a stair step and lasts until ``end_flat_steps`` consecutive steps that are
  not stairs (a landing of a few steps stays inside the flight);
* the flight's climb ``c`` has the sign of the majority of its stair climb, once up and down
  differ by ``direction_fraction`` of a floor height (a person does not turn round on a
  flight, the classifier confuses up and down; before that ``c`` is 0; once the flight has
  changed the floor, the direction of that change) and the size of the mean stair step
  ``|dz|`` times its ``n`` stair steps and the ``g`` steps between them that were not labelled
  stairs (a classifier misses some steps of a flight), ``min(n + g, 2 n)``: flat steps count
  only as long as at least half of the flight's steps are stairs;
* the floor is the flight's first floor plus ``k = sign(c) floor(|c| / h + 1 - change_fraction)``:
  one floor once ``|c| >= change_fraction h``, two at ``(1 + change_fraction) h``, ...; z is
  pulled to the new floor's level when ``k`` changes;
* after the flight, every walking or standing step pulls z to the floor's level with a soft
  pseudo-measurement (:func:`floor_level_update`).

A flight whose stair steps add up to less than ``change_fraction h / 2`` never changes the
floor: isolated misclassified stair steps (a few between runs of ``end_flat_steps`` steps that
are not stairs) leave it alone. This is our addition; the thesis only reports the floor
through z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion.gating import (
    UpdateDiagnostics,
    chi2_threshold,
    scalar_diagnostics,
    scalar_update,
)
from hrtls.fusion.state import FilterState
from hrtls.kernels import njit

FLIGHT_STATE = ("floor_start", "floor", "up_m", "down_m", "flat_steps", "stair_steps",
                "gap_steps")
"""The flight rule's state (:func:`flight_step`): the floor the flight started on, the floor now
(NaN before the first step), the flight's stair climb up and down (m), the steps that were not
stairs since its last stair step, its stair steps and the other steps between them."""


@dataclass(frozen=True, slots=True)
class FlightParams:
    """Parameters of the flight rule (:func:`flight_step`).

    Attributes
    ----------
    change_fraction: share of a floor height a flight's climb needs to change the floor.
    end_flat_steps: consecutive steps that are not stairs that end a flight (a landing and a
        classifier's lag are shorter).
    direction_fraction: share of a floor height by which a flight's stair climb up and down
        must differ before it has a direction.
    """

    change_fraction: float = 0.6
    end_flat_steps: int = 12
    direction_fraction: float = 0.15

    def __post_init__(self) -> None:
        if not (isinstance(self.change_fraction, int | float)
                and 0.5 <= self.change_fraction < 1.0):
            raise InputError(f"{self.change_fraction!r}", where="FlightParams.change_fraction",
                             expected="0.5 <= change_fraction < 1 (of a floor height)")
        if not (isinstance(self.direction_fraction, int | float)
                and 0.0 < self.direction_fraction < self.change_fraction):
            raise InputError(f"{self.direction_fraction!r}",
                             where="FlightParams.direction_fraction",
                             expected="0 < direction_fraction < change_fraction")
        if not (isinstance(self.end_flat_steps, int) and self.end_flat_steps >= 1):
            raise InputError(f"{self.end_flat_steps!r}", where="FlightParams.end_flat_steps",
                             expected="an integer >= 1")


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


@njit(cache=True, error_model="numpy")
def flight_step(st: FloatArray, dz_m: float, stairs: bool, floor_height_m: float,
                change_fraction: float, end_flat_steps: float,
                direction_fraction: float) -> bool:  # pragma: no cover
    """One step of the flight rule (module docstring), ``st`` (:data:`FLIGHT_STATE`) in place.

    Returns True when z is to be pulled to the level of floor ``st[1]`` after this step.
    """
    if stairs:
        if dz_m > 0.0:
            st[2] += dz_m
        else:
            st[3] -= dz_m
        if st[5] > 0.0:
            st[6] += st[4]          # the flat steps inside the flight so far
        st[5] += 1.0
        st[4] = 0.0
        up, down = st[2], st[3]
        if st[1] != st[0]:           # the flight changed the floor: its direction is known
            sign = 1.0 if st[1] > st[0] else -1.0
        else:
            margin = direction_fraction * floor_height_m
            sign = 1.0 if up - down >= margin else -1.0 if down - up >= margin else 0.0
        climb = (up + down) / st[5] * min(st[5] + st[6], 2.0 * st[5])
        floor = st[0] + sign * math.floor(climb / floor_height_m + 1.0 - change_fraction)
        changed = floor != st[1]
        st[1] = floor
        return changed
    st[4] += 1.0
    if st[5] > 0.0 and st[4] < end_flat_steps:
        return False                 # a landing, or stairs the classifier missed
    st[0] = st[1]
    st[2] = st[3] = st[5] = st[6] = 0.0
    return True


@njit(cache=True, error_model="numpy")
def floor_level_correction(x: FloatArray, p: FloatArray, floor_height_m: float,
                           ground_z_m: float, sigma_m: float, threshold: float, gated: bool,
                           floor: float = math.nan
                           ) -> tuple[int, float, float, float]:  # pragma: no cover - compiled
    """Pull ``z = x[2]`` to the level of ``floor`` (NaN: the nearest), in place (compiled core).

    Returns ``(code, nis, S, nu)`` of the scalar update (see
    :func:`hrtls.fusion.gating.scalar_update`).
    """
    if not math.isfinite(floor):
        floor = np.rint((x[2] - ground_z_m) / floor_height_m)
    level = ground_z_m + floor_height_m * floor
    nu = level - x[2]
    code, nis, s = scalar_update(x, p, (0.0, 0.0, 1.0, 0.0), sigma_m * sigma_m, nu, threshold,
                                 gated)
    return code, nis, s, nu


def floor_level_update(state: FilterState, floor_height_m: float, *, sigma_m: float = 0.1,
                       ground_z_m: float = 0.0, gate_probability: float | None = 0.999,
                       floor: int | None = None) -> tuple[FilterState, UpdateDiagnostics]:
    """Pseudo-measurement ``z = level of floor`` (None: the nearest) with 1-sigma ``sigma_m``."""
    h = finite_scalar(floor_height_m, where="floor_height_m", positive=True)
    s = finite_scalar(sigma_m, where="floor sigma_m", positive=True)
    ground = finite_scalar(ground_z_m, where="floor ground_z_m")
    threshold = math.inf if gate_probability is None else chi2_threshold(1, gate_probability)
    x, p = state.x.copy(), state.P.copy()
    code, nis, s_inn, nu = floor_level_correction(
        x, p, h, ground, s, threshold, gate_probability is not None,
        math.nan if floor is None else float(floor))
    diag = scalar_diagnostics("floor", state.t, code, nis, s_inn, nu, threshold)
    return (state.evolve(x=x, P=p) if diag.accepted else state), diag
