"""Unit conversions at the boundary and checks that catch signals in the wrong unit.

Inside hrtls everything is SI (s, m, m/s^2, rad, rad/s) with the magnetic field in microtesla.
Readers convert with the factors below. The ``suspect_*`` functions look at a whole signal and
return a message when it looks like another unit; containers turn that message into a
:class:`~hrtls.errors.UnitError` that says how to fix it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrtls.frames import GRAVITY_M_S2

DEG = np.pi / 180.0
"""Radians per degree."""
G_TO_M_S2 = GRAVITY_M_S2
"""m/s^2 per g."""
GAUSS_TO_UT = 100.0
"""Microtesla per gauss."""
NT_TO_UT = 1e-3
"""Microtesla per nanotesla."""
HPA_TO_PA = 100.0
"""Pascal per hectopascal (= millibar)."""

TIME_SCALES_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Seconds per unit of the time units readers understand."""

_MIN_SAMPLES_FOR_UNIT_CHECK = 20
_MAX_SAMPLES_FOR_UNIT_CHECK = 1 << 16


def _norms(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row norms of at most ``_MAX_SAMPLES_FOR_UNIT_CHECK`` evenly spaced samples."""
    step = -(-len(values) // _MAX_SAMPLES_FOR_UNIT_CHECK)
    v = values[::step]
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def _median_outside(norms: NDArray[np.float64], bands: tuple[tuple[float, float], ...]) -> bool:
    """True when the median of ``norms`` is surely in none of the closed ``bands``.

    Decided by counting, without placing the median, when the middle values (one for an odd
    count, two for an even count, whose mean numpy takes) lie on the same side of each band
    edge; False (not sure: compute the median) otherwise. A NaN needs no care: numpy's median
    is then NaN, in no band, and either answer leads to no message.
    """
    n = len(norms)
    k = n // 2
    for lo, hi in bands:
        below = int(np.count_nonzero(norms < lo))  # rank of the first value >= lo
        upto = int(np.count_nonzero(norms <= hi))
        middle = (k,) if n % 2 else (k - 1, k)
        if all(below > i for i in middle) or all(upto <= i for i in middle):
            continue  # the middle values are all below lo, or all above hi
        return False
    return True


def suspect_accelerometer_unit(values: NDArray[np.float64]) -> str | None:
    """Return a message when accelerometer samples (N, 3) look like g rather than m/s^2.

    The median norm of a body-worn accelerometer is close to gravity (9.81 m/s^2) whatever the
    motion; a median near 1 means g, near 1000 means milli-g.
    """
    if len(values) < _MIN_SAMPLES_FOR_UNIT_CHECK:
        return None
    norms = _norms(values)
    if _median_outside(norms, ((0.4, 2.5), (400.0, 2500.0))):
        return None
    median = float(np.median(norms))
    if 0.4 <= median <= 2.5:
        return (f"median |a| = {median:.3g}, which is gravity in g, not m/s^2; "
                f"multiply by {G_TO_M_S2} (readers: accel_unit='g')")
    if 400.0 <= median <= 2500.0:
        return (f"median |a| = {median:.4g}, which is gravity in milli-g; "
                f"multiply by {G_TO_M_S2 / 1000} (readers: accel_unit='mg')")
    return None


def suspect_gyroscope_unit(values: NDArray[np.float64]) -> str | None:
    """Return a message when gyroscope samples (N, 3) look like deg/s rather than rad/s.

    A person or a hand-held board rarely turns faster than about 20 rad/s (1150 deg/s); in deg/s
    ordinary walking already reaches 50-250. The 99th percentile of the norm above 25 is taken
    as deg/s.
    """
    if len(values) < _MIN_SAMPLES_FOR_UNIT_CHECK:
        return None
    norms = _norms(values)
    if not (norms > 25.0).any():
        return None  # no percentile exceeds the largest value (with a NaN: NaN, not > 25)
    p99 = float(np.percentile(norms, 99))
    if p99 > 25.0:
        return (f"99th percentile of |w| = {p99:.4g}, which only makes sense in deg/s; "
                f"multiply by pi/180 (readers: gyro_unit='deg/s')")
    return None


def suspect_magnetometer_unit(values: NDArray[np.float64]) -> str | None:
    """Return a message when magnetometer samples look like gauss, nT or mG rather than uT.

    The Earth's field is 22-67 uT; indoor disturbances can double it. Medians far outside
    about 5-300 uT point to another unit.
    """
    if len(values) < _MIN_SAMPLES_FOR_UNIT_CHECK:
        return None
    norms = _norms(values)
    if _median_outside(norms, ((0.05, 3.0), (5000.0, 300000.0))):
        return None
    median = float(np.median(norms))
    if 0.05 <= median <= 3.0:
        return (f"median |m| = {median:.3g}, which is gauss, not uT; multiply by 100 "
                f"(readers: mag_unit='gauss')")
    if 5000.0 <= median <= 300000.0:
        return (f"median |m| = {median:.4g}, which is nT, not uT; multiply by 0.001 "
                f"(readers: mag_unit='nT')")
    return None


def time_scale_from_name(unit: str) -> float:
    """Seconds per unit for ``'s'``, ``'ms'``, ``'us'`` or ``'ns'``."""
    try:
        return TIME_SCALES_S[unit]
    except KeyError:
        from hrtls.errors import InputError

        raise InputError(f"unknown time unit {unit!r}", where="time unit",
                         expected="one of s, ms, us, ns") from None


def guess_time_scale(t_raw: NDArray[np.float64], *, nominal_rate_hz: float | None = None) -> float:
    """Guess seconds-per-tick of raw timestamps from their median spacing.

    Sensor rates lie between about 1 Hz and 2 kHz. The unit whose median step falls in that
    band wins, trying s, ms, us, ns in order. With ``nominal_rate_hz`` the closest match wins.
    """
    steps = np.diff(t_raw)
    steps = steps[steps > 0]
    if len(steps) == 0:
        return 1.0
    median_step = float(np.median(steps))
    if nominal_rate_hz is not None:
        return min(TIME_SCALES_S.values(),
                   key=lambda s: abs(np.log(median_step * s * nominal_rate_hz)))
    for scale in TIME_SCALES_S.values():
        dt = median_step * scale
        if 1.0 / 5000.0 <= dt <= 2.0:
            return scale
    return 1.0
