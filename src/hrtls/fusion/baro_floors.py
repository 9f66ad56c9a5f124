"""Floors from a barometer: relative altitude, a slow drift follower, sustained floor changes.

Altitude relative to the first reading follows the hypsometric equation,
``a = (R_d T / g) ln(p_0 / p)`` (R_d = 287.05 J/(kg K), g = 9.80665 m/s^2) with the
standard-atmosphere temperature at the first pressure, ``T = 288.15 K (p_0 / 101325 Pa)^0.190263``
(8434.6 m of scale height at sea level), smoothed by a causal moving mean of ``smooth_s``.
The floor is a state machine run sample by sample (causal, compiled):

* ``level`` is the altitude of the current floor as the barometer sees it. While the altitude
  stays within ``freeze_fraction`` of a floor height of it, ``level`` follows it with time
  constant ``drift_tau_s``: weather drift (about 1 hPa an hour, 8 m) is absorbed;
* a change faster than people climb (``max_climb_m_s`` over 1 s of the altitude smoothed over
  ``step_smooth_s``, beyond the climb the step model expects: the last step's ``dz`` over its
  duration while the steps are stairs) met while standing or on stairs is a pressure step of
  a door or the ventilation: while it lasts (until the change beyond the continued climb is
  below half that speed) the altitude is continued at the step model's climb rate on stairs,
  else at the barometer's climb rate of the 3 s before when steps were detected then, else
  held, and the step is removed from then on. A fast change that lasts more than
  ``max_step_s`` is no door (their pressure rises within a second): it is a climb (an
  elevator) and is kept whole, to its end. While walking on steps that are not stairs, a change is
  removed only when it takes back about the steps removed so far (a door opened while
  standing closes) or is faster than 1.5 ``max_climb_m_s``: the walking classifier may
  have missed the stairs, and a door step met on a flight (0.3 m/s of climb, close to the
  limits) swallowed the flight; a door while walking flat (about 0.7 m) stays below the
  sustained change a floor needs. Such a kept change opens an excursion (the altitude before
  it is remembered): a fast change back towards that altitude is the door closing and is kept
  too, walking or not, so the altitude comes back (removing it would leave the door's height
  behind for good); a step removed after a kept start removes that start too. The climb
  rate continued through a step is that of the altitude without the steps removed so far
  over the 3 s before, as both halves of them agree (a door edge in one half is no flight),
  limited to ``max_climb_m_s`` / 2;
* the floor changes only when the altitude has stayed more than ``change_fraction`` of a floor
  height away from ``level`` for ``hold_s``: the floor moves by ``round(d / floor_height)`` and
  ``level`` by as many floor heights (the rest of the climb, or a floor height a little off,
  is left to the follower).

``z`` is the height relative to the start, ``floor * floor_height + (a - level)``: on a floor
it is the floor's height, on stairs it follows the climb, so ``round(z / floor_height)``
switches at half the climb as the true floor does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.kernels import njit

FloatArray = NDArray[np.float64]
R_DRY_J_KG_K = 287.05
G0_M_S2 = 9.80665


def scale_height_m(p0_pa: float) -> float:
    """``R_d T / g`` with the standard-atmosphere temperature at pressure ``p0_pa``, m."""
    return R_DRY_J_KG_K * 288.15 * (p0_pa / 101325.0) ** 0.190263 / G0_M_S2


@dataclass(frozen=True, slots=True)
class BaroFloorParams:
    """Parameters of :func:`baro_floors` (times in s, lengths in m, fractions of a floor)."""

    floor_height_m: float = 3.0
    smooth_s: float = 2.0
    hold_s: float = 2.0
    change_fraction: float = 0.6
    freeze_fraction: float = 0.25
    drift_tau_s: float = 60.0
    max_climb_m_s: float = 1.0
    step_smooth_s: float = 0.5
    max_step_s: float = 4.0

    def __post_init__(self) -> None:
        for name in ("floor_height_m", "smooth_s", "hold_s", "change_fraction",
                     "freeze_fraction", "drift_tau_s", "max_climb_m_s", "step_smooth_s",
                     "max_step_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0.0):
                raise InputError(f"{name} = {value}", where="BaroFloorParams",
                                 expected="a positive finite number")
        if self.step_smooth_s >= self.smooth_s:
            raise InputError(f"step_smooth_s {self.step_smooth_s} >= smooth_s {self.smooth_s}",
                             where="BaroFloorParams", expected="step_smooth_s < smooth_s")
        if self.freeze_fraction >= self.change_fraction or self.change_fraction >= 1.0:
            raise InputError(f"freeze_fraction {self.freeze_fraction}, change_fraction "
                             f"{self.change_fraction}", where="BaroFloorParams",
                             expected="0 < freeze_fraction < change_fraction < 1")


@dataclass(frozen=True, slots=True, eq=False)
class BaroFloors:
    """Per pressure sample: time, smoothed relative altitude, floor level, floor and height.

    ``pressure_steps`` counts the pressure steps (doors, ventilation) that were absorbed.
    """

    t: FloatArray
    altitude_m: FloatArray
    level_m: FloatArray
    floor: NDArray[np.int64]
    z_m: FloatArray
    pressure_steps: int = 0

    @property
    def changes(self) -> int:
        """Number of floor changes."""
        return int(np.count_nonzero(np.diff(self.floor))) if len(self.floor) > 1 else 0

    def at(self, t_query: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
        """Floor and height at ``t_query`` from the last sample at or before it (causal)."""
        idx = np.searchsorted(self.t, np.asarray(t_query, dtype=np.float64), side="right") - 1
        idx = np.clip(idx, 0, len(self.t) - 1)
        before = np.asarray(t_query) < self.t[0]
        floor = np.where(before, self.floor[0], self.floor[idx])
        z = np.where(before, self.z_m[0], self.z_m[idx])
        return floor.astype(np.int64), z


def relative_altitude(t: FloatArray, pressure_pa: FloatArray, *, smooth_s: float) -> FloatArray:
    """Causally smoothed altitude above the first reading, m (hypsometric equation)."""
    p = np.asarray(pressure_pa, dtype=np.float64)
    return _causal_mean(t, scale_height_m(float(p[0])) * np.log(p[0] / p), smooth_s)


def _causal_mean(t: FloatArray, x: FloatArray, window_s: float) -> FloatArray:
    c = np.concatenate([[0.0], np.cumsum(x)])
    start = np.searchsorted(t, t - window_s, side="left")
    n = np.arange(1, len(t) + 1) - start
    return np.asarray((c[1:] - c[start]) / n)


N_SCALARS = 13
"""Scalars of :class:`BaroFloorState`: offset, in_step (2.0: a climb too long for a door
goes on), t_start, f_start, climb, steps, level, floor, pending, started, floor changes, the
kept excursion's base altitude (NaN: none), the kept excursion returning (1.0) or not."""


@dataclass(frozen=True, slots=True, eq=False)
class BaroFloorState:
    """What :func:`baro_floors_update` carries from one block of pressure samples to the next.

    ``p0_pa``: the first pressure (the altitude reference); ``scalars``: the machine's state
    (:data:`N_SCALARS`); the other arrays are the last samples the windows still reach
    (time, raw altitude, walking, fast and steady altitude, smoothed altitude, the step
    model's climb rate).
    """

    p0_pa: float
    scalars: FloatArray
    t: FloatArray
    raw_m: FloatArray
    walking: NDArray[np.bool_]
    fast_m: FloatArray
    steady_m: FloatArray
    a_m: FloatArray
    stairs_m_s: FloatArray = field(default_factory=lambda: np.zeros(0))


@njit(cache=True)
def _window_mean(t: FloatArray, x: FloatArray, i: int, window_s: float
                 ) -> float:  # pragma: no cover - compiled
    """Mean of ``x`` over the samples with ``t[i] - window_s <= t <= t[i]``."""
    s = 0.0
    j = i
    while j >= 0 and t[j] >= t[i] - window_s:
        s += x[j]
        j -= 1
    return s / (i - j)


@njit(cache=True)
def _takes_back(kept: float, before: float, change_m: float, min_m: float
                ) -> bool:  # pragma: no cover - compiled
    """Whether ``change_m`` from ``before`` goes back towards the kept excursion's base."""
    away = before - kept
    return (not np.isnan(kept) and abs(away) > min_m and away * change_m < 0.0
            and abs(change_m) > 0.5 * abs(away))


@njit(cache=True)
def _sustained_climb(t: FloatArray, z: FloatArray, j: int, max_m_s: float
                     ) -> float:  # pragma: no cover - compiled
    """Climb rate of ``z`` over the 3 s up to ``t[j]`` as both halves of them agree.

    The slower half's rate when both climb the same way, else 0 (a door edge in one half is
    no flight), limited to ``max_m_s``.
    """
    k = j
    while k > 0 and t[k - 1] >= t[j] - 3.0:
        k -= 1
    m = k
    while m < j and t[m] < t[j] - 1.5:
        m += 1
    if t[m] - t[k] < 0.5 or t[j] - t[m] < 0.5:
        return 0.0
    r1 = (z[m] - z[k]) / (t[m] - t[k])
    r2 = (z[j] - z[m]) / (t[j] - t[m])
    if r1 * r2 <= 0.0:
        return 0.0
    return float(np.sign(r1)) * min(abs(r1), abs(r2), max_m_s)


@njit(cache=True)
def _baro_block(t: FloatArray, raw: FloatArray, walking: NDArray[np.bool_], stairs: FloatArray,
                i0: int, fast: FloatArray, steady: FloatArray, a: FloatArray, st: FloatArray,
                level: FloatArray, floor: NDArray[np.int64], fast_s: float, slow_s: float,
                max_climb: float, max_step_s: float, height: float, hold_s: float,
                change: float, freeze: float, tau_s: float) -> None:  # pragma: no cover
    """Samples ``i0..`` of history + new block: smoothing, pressure steps, floor machine.

    ``fast``, ``steady`` and ``a`` hold the history before ``i0`` and are filled from it on;
    ``st`` (the scalars of :class:`BaroFloorState`) is updated in place.

    Pressure steps: while the change of ``fast`` over the last second departs from the
    expected climb (``stairs``, the step model's rate; during a step the rate it is continued
    at) by more than ``max_climb`` (until it falls below half of that) the altitude continues
    at the step model's rate on stairs, else at the climb rate of the 3 s before when the
    person was walking then, else it is held; when the change is slower again, the step (what
    went beyond that) is subtracted from then on. A fast change kept while walking flat opens
    an excursion from ``fast`` before it (``kept``); a fast change back towards it is kept
    until it is over (``back``).
    """
    offset, t_start, f_start, climb = st[0], st[2], st[3], st[4]
    in_step, riding = 0.5 < st[1] < 1.5, st[1] > 1.5
    steps, lv, fl, pending, started, changes = st[5], st[6], int(st[7]), st[8], st[9], st[10]
    kept, back = st[11], st[12] > 0.5
    j = 0
    for i in range(i0, len(t)):
        fast[i] = _window_mean(t, raw, i, fast_s)
        while t[j] < t[i] - 1.0:
            j += 1
        rate = stairs[i] if stairs[i] != 0.0 else climb if in_step else 0.0
        limit = 0.5 * max_climb if in_step or riding else max_climb
        fast_change = (t[i] - t[j] > 0.5
                       and abs(fast[i] - fast[j] - rate * (t[i] - t[j]))
                       > limit * (t[i] - t[j]))
        if back and not fast_change:
            kept, back = np.nan, False      # the kept excursion is over
        riding = riding and fast_change     # a climb too long for a door goes on
        if fast_change and not in_step and not riding:
            change_m = fast[i] - fast[j]
            if back or _takes_back(kept, fast[j] - offset, change_m, freeze * height):
                back = True                 # a kept door step closing: kept too
                fast_change = False
            elif walking[i] and stairs[i] == 0.0:
                # walking: only a change back by about an open step, or one too fast for stairs
                fast_change = ((offset * change_m < 0.0 and abs(offset) > 0.5 * abs(change_m))
                               or abs(change_m) > 1.5 * max_climb * (t[i] - t[j]))
                if not fast_change and np.isnan(kept):
                    kept = fast[j] - offset  # a kept fast change: an excursion from there
        if fast_change and not in_step and not riding:
            in_step = True
            steps += 1.0
            t_start = t[j]
            f_start = fast[j]
            if not np.isnan(kept):          # the kept start of the same step: removed too
                f_start, kept = kept + offset, np.nan
            climb = _sustained_climb(t, steady, j, 0.5 * max_climb) if walking[j] else 0.0
            rate = stairs[i] if stairs[i] != 0.0 else climb
            # continued from the change's start, a second before
            steady[i] = f_start - offset + rate * (t[i] - t_start)
        elif in_step and t[i] - t_start > max_step_s:
            steady[i] = fast[i] - offset     # too long for a door: a climb, kept whole
            in_step, riding = False, True
            steps -= 1.0
        elif in_step:
            steady[i] = steady[i - 1] + rate * (t[i] - t[i - 1])
            if not fast_change:
                offset = fast[i] - steady[i]
                in_step = False
        else:
            steady[i] = fast[i] - offset
        a[i] = _window_mean(t, steady, i, slow_s)
        # floor machine
        if started < 0.5:
            lv = a[i]
            started = 1.0
        else:
            d = a[i] - lv
            if abs(d) < freeze * height:
                lv += d * min(1.0, (t[i] - t[i - 1]) / tau_s)
            if abs(d) > change * height:
                if pending < 0.0:
                    pending = t[i]
                if t[i] - pending >= hold_s:
                    kf = int(np.rint(d / height))
                    fl += kf
                    lv += kf * height
                    pending = -1.0
                    if kf != 0:
                        changes += 1.0
            else:
                pending = -1.0
        level[i] = lv
        floor[i] = fl
    st[0], st[2], st[3], st[4] = offset, t_start, f_start, climb
    st[1] = 1.0 if in_step else 2.0 if riding else 0.0
    st[5], st[6], st[7], st[8], st[9], st[10] = steps, lv, float(fl), pending, started, changes
    st[11], st[12] = kept, 1.0 if back else 0.0


def _check_samples(t: FloatArray, pa: FloatArray) -> None:
    if t.ndim != 1 or pa.shape != t.shape:
        raise InputError(f"shapes {t.shape} and {pa.shape}", where="baro_floors",
                         expected="two 1-D arrays of the same length")
    if np.any(np.diff(t) <= 0) or not np.all(np.isfinite(pa)) or np.any(pa <= 0):
        raise InputError("times not increasing or pressures not positive",
                         where="baro_floors", expected="increasing times, pressures in Pa > 0")


def walking_flags(t: FloatArray, step_ends_s: FloatArray | None) -> NDArray[np.bool_]:
    """True where a detected step ended within the 2 s before (or at) ``t``."""
    if step_ends_s is None or not len(step_ends_s):
        return np.zeros(len(t), dtype=np.bool_)
    ends = np.sort(np.asarray(step_ends_s, dtype=np.float64))
    last = np.searchsorted(ends, t, side="right") - 1
    return np.asarray((last >= 0) & (t - ends[np.clip(last, 0, None)] <= 2.0))


def stairs_rates(t: FloatArray, step_starts_s: FloatArray | None,
                 step_ends_s: FloatArray | None, step_dz_m: FloatArray | None
                 ) -> FloatArray:
    """The step model's climb rate at ``t``, m/s (steps in time order).

    ``dz / duration`` of the last step that ended within the 2 s before (or at) ``t``; 0
    without one.
    """
    if step_ends_s is None or step_starts_s is None or step_dz_m is None \
            or not len(step_ends_s):
        return np.zeros(len(t))
    ends = np.asarray(step_ends_s, dtype=np.float64)
    rate = np.asarray(step_dz_m, dtype=np.float64) / np.maximum(
        ends - np.asarray(step_starts_s, dtype=np.float64), 0.2)
    last = np.searchsorted(ends, t, side="right") - 1
    ok = (last >= 0) & (t - ends[np.clip(last, 0, None)] <= 2.0)
    return np.asarray(np.where(ok, rate[np.clip(last, 0, None)], 0.0))


def baro_floors_update(state: BaroFloorState | None, t: FloatArray, pressure_pa: FloatArray,
                       walking: NDArray[np.bool_], *, params: BaroFloorParams,
                       stairs_m_s: FloatArray | None = None
                       ) -> tuple[BaroFloorState | None, BaroFloors]:
    """The next block of pressure samples (causal: the same result in any split).

    ``state`` is None for the first block; ``walking`` from :func:`walking_flags` and
    ``stairs_m_s`` (None: 0) from :func:`stairs_rates` with the steps known up to the block's
    end. Returns the new state and the block's floors (``pressure_steps``: the count since
    the first block).

    Raises
    ------
    InputError
        Times not increasing (also across blocks) or pressures not positive.
    """
    p = params
    t = np.asarray(t, dtype=np.float64)
    pa = np.asarray(pressure_pa, dtype=np.float64)
    _check_samples(t, pa)
    if state is not None and len(t) and len(state.t) and t[0] <= state.t[-1]:
        raise InputError(f"pressure at t = {t[0]} after t = {state.t[-1]}",
                         where="baro_floors", expected="increasing times across blocks")
    if not len(t):
        z = np.zeros(0)
        return state, BaroFloors(z, z, z, np.zeros(0, dtype=np.int64), z,
                                 0 if state is None else int(state.scalars[5]))
    if state is None:
        state = BaroFloorState(float(pa[0]), np.zeros(N_SCALARS), np.zeros(0), np.zeros(0),
                               np.zeros(0, dtype=np.bool_), np.zeros(0), np.zeros(0),
                               np.zeros(0))
        state.scalars[8] = -1.0
        state.scalars[11] = np.nan
    i0 = len(state.t)
    tt = np.concatenate([state.t, t])
    raw = np.concatenate([state.raw_m, scale_height_m(state.p0_pa) * np.log(state.p0_pa / pa)])
    walk = np.concatenate([state.walking, np.asarray(walking, dtype=np.bool_)])
    rates = np.concatenate([state.stairs_m_s if len(state.stairs_m_s) == i0 else np.zeros(i0),
                            np.zeros(len(t)) if stairs_m_s is None
                            else np.asarray(stairs_m_s, dtype=np.float64)])
    n = len(tt)
    fast = np.concatenate([state.fast_m, np.empty(n - i0)])
    steady = np.concatenate([state.steady_m, np.empty(n - i0)])
    a = np.concatenate([state.a_m, np.empty(n - i0)])
    st = state.scalars.copy()
    if len(st) < N_SCALARS:  # a state from before the kept excursion
        st = np.concatenate([st, [np.nan, 0.0]])
    level = np.empty(n)
    floor = np.zeros(n, dtype=np.int64)
    _baro_block(tt, raw, walk, rates, i0, fast, steady, a, st, level, floor, p.step_smooth_s,
                p.smooth_s - p.step_smooth_s, p.max_climb_m_s, p.max_step_s, p.floor_height_m,
                p.hold_s,
                p.change_fraction, p.freeze_fraction, p.drift_tau_s)
    keep = tt >= tt[-1] - (max(p.smooth_s, 4.0) + 1.0)
    keep[max(0, n - 2):] = True
    new = BaroFloorState(state.p0_pa, st, tt[keep], raw[keep], walk[keep], fast[keep],
                         steady[keep], a[keep], rates[keep])
    lv, fl, av = level[i0:], floor[i0:], a[i0:]
    return new, BaroFloors(t, av, lv, fl, fl * p.floor_height_m + (av - lv), int(st[5]))


def baro_floors(t: FloatArray, pressure_pa: FloatArray, *, params: BaroFloorParams | None = None,
                step_times_s: FloatArray | None = None, step_starts_s: FloatArray | None = None,
                step_dz_m: FloatArray | None = None) -> BaroFloors:
    """Floors (relative to the first sample's floor) and heights from a pressure series.

    ``step_times_s`` (the detected steps' end times) tells when the person walked: a pressure
    step met while walking keeps the climb rate of before it (stairs), otherwise the height is
    held through it; with ``step_starts_s`` and ``step_dz_m`` too, the step model's climb rate
    on stairs (:func:`stairs_rates`) is expected and continued.

    Raises
    ------
    InputError
        Fewer than two samples, times not increasing, or pressures not positive.
    """
    p = params or BaroFloorParams()
    t = np.asarray(t, dtype=np.float64)
    pa = np.asarray(pressure_pa, dtype=np.float64)
    if t.ndim != 1 or pa.shape != t.shape or len(t) < 2:
        raise InputError(f"shapes {t.shape} and {pa.shape}", where="baro_floors",
                         expected="two 1-D arrays of the same length >= 2")
    _, floors = baro_floors_update(None, t, pa, walking_flags(t, step_times_s), params=p,
                                   stairs_m_s=stairs_rates(t, step_starts_s, step_times_s,
                                                           step_dz_m))
    return floors
