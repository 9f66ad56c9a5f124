"""Observations of the surroundings: position fixes, beacon RSS, passive tag reads, radio ranges.

Times are float64 s on the same clock as the IMU and *non-decreasing*: several readings may share
a time (one scan hears many beacons), but a reading never goes back in time. Ids refer to the
session's landmarks (``landmarks.json``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.data.validation import (
    FloatArray,
    as_float_matrix,
    as_float_vector,
    as_str_vector,
    check_finite,
    check_time,
)
from hrtls.errors import InputError

StrArray = NDArray[np.str_]


def _check_times(t: FloatArray, where: str) -> FloatArray:
    tt = as_float_vector(t, where=f"{where} time")
    check_time(tt, where=where, strict=False)
    return tt


@dataclass(frozen=True, slots=True, eq=False)
class PositionFixes:
    """External position fixes (camera, UWB, ...) in the navigation frame.

    Attributes
    ----------
    t: times, s, (N,).
    xyz: positions, m, (N, 3); ``has_z`` tells whether z was measured (else z is 0).
    sigma_m: 1-sigma horizontal accuracy, m, (N,), > 0.
    """

    t: FloatArray
    xyz: FloatArray
    sigma_m: FloatArray
    has_z: bool = False
    name: str = "fixes"

    def __post_init__(self) -> None:
        t = _check_times(self.t, self.name)
        xyz = as_float_matrix(self.xyz, where=self.name, columns=3, length=len(t))
        sigma = as_float_vector(self.sigma_m, where=f"{self.name} sigma", length=len(t))
        check_finite(xyz, where=self.name)
        check_finite(sigma, where=f"{self.name} sigma")
        if np.any(sigma <= 0):
            idx = int(np.flatnonzero(sigma <= 0)[0])
            raise InputError(f"sigma {sigma[idx]}", where=f"{self.name} index {idx}",
                             expected="a positive 1-sigma accuracy in m")
        for attr, value in (("t", t), ("xyz", xyz), ("sigma_m", sigma)):
            object.__setattr__(self, attr, value)

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True, eq=False)
class RssReadings:
    """Received signal strength of beacons / anchors, dBm."""

    t: FloatArray
    anchor: StrArray
    rss_dbm: FloatArray
    name: str = "rss"

    def __post_init__(self) -> None:
        t = _check_times(self.t, self.name)
        anchor = as_str_vector(self.anchor, where=f"{self.name} anchor", length=len(t))
        rss = as_float_vector(self.rss_dbm, where=f"{self.name} rss_dbm", length=len(t))
        check_finite(rss, where=f"{self.name} rss_dbm")
        if np.any((rss > 30.0) | (rss < -150.0)):
            idx = int(np.flatnonzero((rss > 30.0) | (rss < -150.0))[0])
            raise InputError(f"RSS {rss[idx]} dBm", where=f"{self.name} index {idx}",
                             expected="a received power between -150 and 30 dBm")
        for attr, value in (("t", t), ("anchor", anchor), ("rss_dbm", rss)):
            object.__setattr__(self, attr, value)

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True, eq=False)
class TagDetections:
    """Passive (RFID) tag reads: range free, only *which* tag was read *when*."""

    t: FloatArray
    tag: StrArray
    name: str = "tags"

    def __post_init__(self) -> None:
        t = _check_times(self.t, self.name)
        tag = as_str_vector(self.tag, where=f"{self.name} tag", length=len(t))
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "tag", tag)

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True, eq=False)
class RangeMeasurements:
    """Measured distances to radio nodes, m, with optional per-reading 1-sigma (NaN: unknown)."""

    t: FloatArray
    node: StrArray
    range_m: FloatArray
    sigma_m: FloatArray
    name: str = "ranges"

    def __post_init__(self) -> None:
        t = _check_times(self.t, self.name)
        node = as_str_vector(self.node, where=f"{self.name} node", length=len(t))
        rng = as_float_vector(self.range_m, where=f"{self.name} range", length=len(t))
        sigma = as_float_vector(self.sigma_m, where=f"{self.name} sigma", length=len(t))
        check_finite(rng, where=f"{self.name} range")
        check_finite(sigma, where=f"{self.name} sigma", allow_nan=True)
        if np.any(rng < 0):
            idx = int(np.flatnonzero(rng < 0)[0])
            raise InputError(f"range {rng[idx]}", where=f"{self.name} index {idx}",
                             expected="a distance >= 0 m")
        if np.any(sigma <= 0):
            idx = int(np.flatnonzero(sigma <= 0)[0])
            raise InputError(f"sigma {sigma[idx]}", where=f"{self.name} index {idx}",
                             expected="a positive 1-sigma in m, or empty")
        for attr, value in (("t", t), ("node", node), ("range_m", rng), ("sigma_m", sigma)):
            object.__setattr__(self, attr, value)

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True, slots=True, eq=False)
class GroundTruth:
    """Reference trajectory (simulated or measured): positions in m, optional heading in rad."""

    t: FloatArray
    xyz: FloatArray
    heading_rad: FloatArray | None = None
    name: str = "truth"

    def __post_init__(self) -> None:
        t = as_float_vector(self.t, where=f"{self.name} time")
        check_time(t, where=self.name)
        xyz = as_float_matrix(self.xyz, where=self.name, columns=3, length=len(t))
        check_finite(xyz, where=self.name)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "xyz", xyz)
        if self.heading_rad is not None:
            heading = as_float_vector(self.heading_rad, where=f"{self.name} heading",
                                      length=len(t))
            check_finite(heading, where=f"{self.name} heading")
            object.__setattr__(self, "heading_rad", heading)

    def __len__(self) -> int:
        return len(self.t)

    def position_at(self, t_query: FloatArray) -> FloatArray:
        """Linearly interpolated positions (M, 3) at ``t_query``."""
        tq = np.asarray(t_query, dtype=np.float64)
        return np.column_stack([np.interp(tq, self.t, c) for c in self.xyz.T])


@dataclass(frozen=True, slots=True, eq=False)
class Checkpoints:
    """Ground truth at known points only: when the person passed which surveyed point."""

    t: FloatArray
    xyz: FloatArray
    label: StrArray
    name: str = "checkpoints"

    def __post_init__(self) -> None:
        t = _check_times(self.t, self.name)
        xyz = as_float_matrix(self.xyz, where=self.name, columns=3, length=len(t))
        check_finite(xyz, where=self.name)
        label = np.asarray(self.label, dtype=np.str_)
        if label.shape != (len(t),):
            raise InputError(f"{label.shape} labels", where=f"{self.name} label",
                             expected=f"{len(t)} labels (may be empty strings)")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "label", label)

    def __len__(self) -> int:
        return len(self.t)
