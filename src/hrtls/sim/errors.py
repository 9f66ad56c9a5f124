"""Sensor error models: noise, bias, bias random walk, scale, misalignment, quantization, range.

A triad's measurement of the true value ``x`` is

    ``y = sat(quant((I + S) M x + b0 + b_rw(t) + n))``

with ``S = diag(scale)``, ``M`` a small non-orthogonality (identity plus off-diagonal angles),
``b0`` the turn-on bias, ``b_rw`` a random walk (bias instability), ``n`` white noise, ``quant``
rounding to the resolution and ``sat`` clipping to the full scale.

Noise densities are datasheet-style: white noise of density ``N`` (unit/sqrt(Hz)) sampled at
``fs`` with a noise bandwidth of ``fs / 2`` has a per-sample standard deviation
``N * sqrt(fs / 2)``. The bias random walk density ``K`` (unit/s/sqrt(Hz)) adds
``K * sqrt(dt)`` per sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True, kw_only=True)
class SensorErrorModel:
    """Error parameters of a three-axis sensor (units of the sensor: m/s^2, rad/s, uT, Pa).

    Attributes
    ----------
    noise_density: white noise density, unit/sqrt(Hz).
    bias_sigma: standard deviation of the turn-on bias, unit.
    bias_walk_density: bias random-walk density, unit/s/sqrt(Hz).
    scale_sigma: standard deviation of the scale-factor error (fraction, 0.01 = 1 %).
    misalignment_sigma_rad: standard deviation of each axis non-orthogonality angle, rad.
    resolution: quantization step (one LSB), unit; 0 for none.
    full_scale: measurement range +-full_scale, unit; inf for none.
    """

    noise_density: float = 0.0
    bias_sigma: float = 0.0
    bias_walk_density: float = 0.0
    scale_sigma: float = 0.0
    misalignment_sigma_rad: float = 0.0
    resolution: float = 0.0
    full_scale: float = float("inf")
    bias_fixed: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("noise_density", "bias_sigma", "bias_walk_density", "scale_sigma",
                     "misalignment_sigma_rad", "resolution"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise InputError(f"{name} = {value}", where="SensorErrorModel",
                                 expected="a finite value >= 0")
        if not self.full_scale > 0:
            raise InputError(f"full_scale = {self.full_scale}", where="SensorErrorModel",
                             expected="a positive range")

    def noise_sigma(self, rate_hz: float) -> float:
        """Per-sample white-noise standard deviation at ``rate_hz``."""
        return float(self.noise_density * np.sqrt(0.5 * rate_hz))

    @classmethod
    def from_sigma(cls, sigma: float, rate_hz: float, **kwargs: Any) -> SensorErrorModel:
        """Model whose per-sample noise at ``rate_hz`` has standard deviation ``sigma``."""
        return cls(noise_density=sigma / np.sqrt(0.5 * rate_hz), **kwargs)


@dataclass(frozen=True, slots=True)
class ErrorRealization:
    """The constant errors drawn for one sensor of one simulated device.

    Attributes
    ----------
    bias: turn-on bias (3,), unit.
    scale: scale-factor errors (3,) (fractions).
    misalignment: (3, 3) matrix ``M`` (identity plus small off-diagonal terms).
    """

    bias: FloatArray
    scale: FloatArray
    misalignment: FloatArray

    def to_dict(self) -> dict[str, list[float] | list[list[float]]]:
        """JSON-able form."""
        return {"bias": self.bias.tolist(), "scale": self.scale.tolist(),
                "misalignment": self.misalignment.tolist()}


def realize_errors(model: SensorErrorModel, rng: np.random.Generator) -> ErrorRealization:
    """Draw the constant errors of one sensor."""
    bias = rng.normal(0.0, model.bias_sigma, 3) if model.bias_sigma > 0 else np.zeros(3)
    bias = bias + np.asarray(model.bias_fixed, dtype=np.float64)
    scale = rng.normal(0.0, model.scale_sigma, 3) if model.scale_sigma > 0 else np.zeros(3)
    mis = np.eye(3)
    if model.misalignment_sigma_rad > 0:
        off = rng.normal(0.0, model.misalignment_sigma_rad, (3, 3))
        mis = mis + off - np.diag(np.diag(off))
    return ErrorRealization(bias=bias, scale=scale, misalignment=mis)


def apply_sensor_errors(x: FloatArray, t: FloatArray, model: SensorErrorModel,
                        realization: ErrorRealization, rng: np.random.Generator) -> FloatArray:
    """Measurements (N, 3) of true values ``x`` (N, 3) sampled at times ``t`` (s)."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or len(t) != len(x):
        raise InputError(f"shape {x.shape} with {len(t)} times", where="apply_sensor_errors",
                         expected="(N, 3) values with N times")
    n = len(x)
    m = (np.eye(3) + np.diag(realization.scale)) @ realization.misalignment
    y = x @ m.T + realization.bias
    if n and model.bias_walk_density > 0:
        dt = np.diff(t, prepend=t[0])
        steps = rng.standard_normal((n, 3)) * (model.bias_walk_density * np.sqrt(dt))[:, None]
        y = y + np.cumsum(steps, axis=0)
    if n and model.noise_density > 0:
        rate = 1.0 / float(np.median(np.diff(t))) if n > 1 else 1.0
        y = y + rng.standard_normal((n, 3)) * model.noise_sigma(rate)
    if model.resolution > 0:
        y = np.round(y / model.resolution) * model.resolution
    if np.isfinite(model.full_scale):
        y = np.clip(y, -model.full_scale, model.full_scale)
    return y


def sample_times(t0: float, t1: float, rate_hz: float, jitter_s: float,
                 rng: np.random.Generator) -> FloatArray:
    """Sample instants from ``t0`` to ``t1`` at ``rate_hz`` with Gaussian jitter ``jitter_s``.

    The jitter is clipped to +-0.4 sample periods so times stay strictly increasing, and the
    first and last instants stay inside ``[t0, t1]``.
    """
    if not rate_hz > 0:
        raise InputError(f"rate {rate_hz}", where="rate_hz", expected="a positive rate in Hz")
    dt = 1.0 / rate_hz
    n = int(np.floor((t1 - t0) / dt + 1e-9)) + 1
    t = t0 + np.arange(n) * dt
    if jitter_s > 0 and n > 2:
        e = np.clip(rng.normal(0.0, jitter_s, n), -0.4 * dt, 0.4 * dt)
        e[0] = 0.0
        e[-1] = min(e[-1], 0.0)
        t = t + e
    return np.asarray(t, dtype=np.float64)
