"""Magnetic field: the Earth's field plus localized indoor anomalies (steel, machines).

The Earth field in ENU from its total intensity ``F``, inclination ``I`` (positive down) and
declination ``D`` (east of true north) is ``F [cos I sin D, cos I cos D, -sin I]`` uT.

An anomaly is a magnetic dipole of moment ``m`` (A m^2) at ``c``. Its field at ``p`` is
``(mu0 / 4 pi) (3 (m . u) u - m) / r^3`` with ``r = |p - c|``, ``u = (p - c) / r``; the ``r^3`` is
softened to ``(r^2 + r0^2)^(3/2)`` so the field stays finite next to the source. Disturbances of
tens of uT within a metre of steel, as the papers report indoors (Basso Sec. IV, Inderst
Sec. 6.3.1), come from moments of order 100 A m^2.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

FloatArray = NDArray[np.float64]
MU0_OVER_4PI_UT = 0.1
"""mu0 / (4 pi) = 1e-7 T m / A expressed as uT m^3 / (A m^2)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class EarthField:
    """Geomagnetic field (default: central Italy, about 46 uT, 58 deg inclination)."""

    total_ut: float = 46.0
    inclination_rad: float = float(np.deg2rad(58.0))
    declination_rad: float = float(np.deg2rad(3.0))

    def vector_enu(self) -> FloatArray:
        """Field vector in ENU, uT."""
        ci = np.cos(self.inclination_rad)
        return self.total_ut * np.array([ci * np.sin(self.declination_rad),
                                         ci * np.cos(self.declination_rad),
                                         -np.sin(self.inclination_rad)])


@dataclass(frozen=True, slots=True)
class MagneticAnomaly:
    """A dipole source: position (m, ENU), moment (A m^2, ENU) and softening radius (m)."""

    position: tuple[float, float, float]
    moment: tuple[float, float, float]
    softening_m: float = 0.3


@dataclass(frozen=True, slots=True)
class MagneticEnvironment:
    """The Earth field plus a list of anomalies."""

    earth: EarthField = field(default_factory=EarthField)
    anomalies: Sequence[MagneticAnomaly] = ()

    def field_at(self, xyz: FloatArray) -> FloatArray:
        """Field (N, 3) in uT at positions ``xyz`` (N, 3) in m."""
        p = np.atleast_2d(np.asarray(xyz, dtype=np.float64))
        if p.shape[1] != 3:
            raise InputError(f"shape {p.shape}", where="xyz", expected="(N, 3) positions in m")
        out = np.broadcast_to(self.earth.vector_enu(), p.shape).copy()
        for a in self.anomalies:
            d = p - np.asarray(a.position)
            r2 = np.sum(d * d, axis=1) + a.softening_m**2
            r = np.sqrt(r2)
            m = np.asarray(a.moment)
            md = d @ m
            out += MU0_OVER_4PI_UT * (3.0 * md[:, None] * d / r2[:, None] - m) / (r2 * r)[:, None]
        return out


def random_anomalies(rng: np.random.Generator, sites: FloatArray, *,
                     strength_ut_at_1m: tuple[float, float] = (5.0, 40.0),
                     softening_m: float = 0.3) -> list[MagneticAnomaly]:
    """Dipoles at ``sites`` (N, 3) with random directions and 1-m field strengths in the range.

    A dipole of moment ``m`` gives ``0.1 m`` to ``0.2 m`` uT at 1 m (equator to axis), so ``m``
    is drawn as ``strength / 0.15``.
    """
    sites = np.atleast_2d(np.asarray(sites, dtype=np.float64))
    out = []
    for c in sites:
        direction = rng.standard_normal(3)
        direction /= np.linalg.norm(direction)
        strength = rng.uniform(*strength_ut_at_1m)
        moment = direction * strength / (1.5 * MU0_OVER_4PI_UT)
        out.append(MagneticAnomaly(position=(float(c[0]), float(c[1]), float(c[2])),
                                   moment=(float(moment[0]), float(moment[1]),
                                           float(moment[2])), softening_m=softening_m))
    return out
