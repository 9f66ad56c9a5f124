"""Attitude methods by name.

``euler-ekf``, ``quat-ekf``, ``complementary``, ``inertial-lp``, ``device``.
"""

from __future__ import annotations

from hrtls.attitude.base import AttitudeFilter, CommonParams
from hrtls.attitude.complementary import ComplementaryFilter
from hrtls.attitude.device import DeviceOrientation
from hrtls.attitude.euler_ekf import EulerEkf
from hrtls.attitude.inertial_lowpass import InertialLowpass
from hrtls.attitude.quat_ekf import QuatEkf
from hrtls.errors import InputError

__all__ = ["DEFAULT_FILTER", "FILTERS", "METHODS", "make_filter"]

FILTERS: dict[str, type[AttitudeFilter]] = {
    EulerEkf.name: EulerEkf,
    QuatEkf.name: QuatEkf,
    ComplementaryFilter.name: ComplementaryFilter,
    InertialLowpass.name: InertialLowpass,
}
"""Sensor-fusion filters (they consume an IMU stream)."""

DEFAULT_FILTER = InertialLowpass.name
"""The filter of the tracker's ``auto`` attitude and of ``hrtls attitude``: the best end to end
on the real IPIN files and the papers' development seeds (``benchmarks/attitude_end_to_end.py``,
``docs/attitude.md``)."""

METHODS: dict[str, type[AttitudeFilter] | type[DeviceOrientation]] = {
    **FILTERS,
    DeviceOrientation.name: DeviceOrientation,
}
"""All methods, including the pass-through of a device orientation (it consumes an
:class:`~hrtls.data.OrientationSeries` instead of an IMU stream)."""


def make_filter(method: str, params: CommonParams | None = None) -> AttitudeFilter:
    """Create the sensor-fusion filter registered as ``method`` (default parameters if None)."""
    try:
        cls = FILTERS[method]
    except KeyError:
        raise InputError(f"unknown attitude filter {method!r}", where="method",
                         expected=" | ".join(sorted(METHODS)),
                         hint="'device' uses the device's orientation: see DeviceOrientation"
                         ) from None
    return cls(params)
