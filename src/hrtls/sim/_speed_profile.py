"""Speed profile of a stop-free run and headings while standing (see :mod:`.motion_truth`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hrtls.kernels import njit

if TYPE_CHECKING:
    from hrtls.sim.motion_truth import PathGeometry

FloatArray = NDArray[np.float64]


@njit(cache=True)
def run_profile_kernel(seg_s0: FloatArray, seg_v: FloatArray, length: float, dt: float,
                       accel: float, decel: float, max_n: int) -> tuple[FloatArray, FloatArray]:
    """Arc length and speed of one stop-free run sampled every ``dt`` (starts and ends at rest).

    ``seg_s0`` are the starts of the speed-limit segments (first is 0), ``seg_v`` their limits.
    The speed tends to ``min(limit, braking curves of later limits and of the end)`` with the
    acceleration bounds ``accel`` / ``decel``.
    """
    s_out = np.empty(max_n)
    v_out = np.empty(max_n)
    s = 0.0
    v = 0.0
    n = 0
    s_out[0] = 0.0
    v_out[0] = 0.0
    n = 1
    nseg = seg_s0.shape[0]
    v_floor = 0.5 * accel * dt
    while n < max_n:
        j = nseg - 1
        while j > 0 and seg_s0[j] > s:
            j -= 1
        target = seg_v[j]
        for m in range(j + 1, nseg):
            brake = np.sqrt(seg_v[m] * seg_v[m] + 2.0 * decel * max(seg_s0[m] - s, 0.0))
            target = min(target, brake)
        target = min(target, np.sqrt(2.0 * decel * max(length - s, 0.0)))
        dv = target - v
        dv = min(max(dv, -2.0 * decel * dt), accel * dt)  # room to track the braking curve
        v = max(v + dv, v_floor)
        if s + v * dt >= length:
            s_out[n] = length
            v_out[n] = 0.0
            n += 1
            break
        s += v * dt
        s_out[n] = s
        v_out[n] = v
        n += 1
    return s_out[:n], v_out[:n]


def smootherstep(x: FloatArray) -> FloatArray:
    """``6x^5 - 15x^4 + 10x^3`` of ``x`` clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return np.asarray(x * x * x * (x * (6.0 * x - 15.0) + 10.0), dtype=np.float64)


def run_speed_limits(geo: PathGeometry, *, start_m: float, end_m: float,
                     leg_speed_m_s: FloatArray, lateral_accel_m_s2: float
                     ) -> tuple[FloatArray, FloatArray]:
    """Speed-limit segments of the run ``[start_m, end_m]``: starts and limits.

    Starts are in m from the run's start; a limit (m/s) is the leg speed, in an arc also
    ``sqrt(a_lat / k)`` and the next leg's speed.
    """
    starts = np.clip(geo.s0, start_m, end_m)
    ends = np.clip(geo.s0 + geo.length, start_m, end_m)
    idx = np.flatnonzero(ends - starts > 1e-9)
    limits = leg_speed_m_s[geo.leg[idx]].copy()
    curv = np.abs(geo.k[idx])
    arc = curv > 0
    limits[arc] = np.minimum(limits[arc], np.sqrt(lateral_accel_m_s2 / curv[arc]))
    # arcs join two legs: use the slower of both
    nxt = np.minimum(geo.leg[idx] + 1, len(leg_speed_m_s) - 1)
    limits[arc] = np.minimum(limits[arc], leg_speed_m_s[nxt[arc]])
    seg_s0 = starts[idx] - start_m
    seg_s0[0] = 0.0
    return seg_s0, limits


def still_headings(*, duration_s: float, heading_rad: float, turn_rad: float,
                   turn_rate_rad_s: float, dt_s: float, min_turn_s: float) -> FloatArray:
    """Headings while standing ``duration_s``, turning ``turn_rad`` on the spot at its start."""
    n = round(duration_s / dt_s)
    if n <= 0:
        return np.empty(0)
    if abs(turn_rad) > 0:
        # the peak rate of the smootherstep is 1.875x its mean
        t_turn = max(abs(turn_rad) * 1.875 / max(turn_rate_rad_s, 1e-3), min_turn_s)
        n_turn = min(round(t_turn / dt_s), n)
        frac = smootherstep(np.arange(1, n + 1) / max(n_turn, 1))
        return np.asarray(heading_rad + turn_rad * frac, dtype=np.float64)
    return np.full(n, heading_rad)
