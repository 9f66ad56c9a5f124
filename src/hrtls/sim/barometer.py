"""A simulated barometer: altitude to pressure, noise, drift, weather and pressure steps.

Pressure follows the standard atmosphere, ``p = p_0 (1 - 2.25577e-5 z)^5.25588``, from the
true height; on top of it:

* white noise of ``noise_pa`` (phone barometers: 1-3 Pa RMS, 0.1-0.25 m) and a resolution;
* a turn-on offset (``offset_sigma_pa``), irrelevant to relative altitude;
* weather: a linear trend drawn with ``weather_sigma_pa_per_h`` (a front moves 1-2 hPa an
  hour) plus a slow random walk;
* pressure steps of doors and ventilation: ``steps_per_h`` on average, each of
  ``N(0, step_sigma_pa)`` lasting an exponential time of mean ``step_mean_s``, rising within
  ``step_rise_s``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hrtls.data import SensorSeries
from hrtls.errors import InputError

if TYPE_CHECKING:
    from hrtls.sim.scenarios import SimulationResult

FloatArray = NDArray[np.float64]
SEA_LEVEL_PA = 101325.0


@dataclass(frozen=True, slots=True)
class BarometerModel:
    """Error model of a barometer (Pa, s, h as named)."""

    rate_hz: float = 10.0
    noise_pa: float = 2.0
    resolution_pa: float = 0.5
    offset_sigma_pa: float = 100.0
    weather_sigma_pa_per_h: float = 100.0
    weather_walk_pa_per_sqrt_s: float = 0.05
    steps_per_h: float = 20.0
    step_sigma_pa: float = 8.0
    step_mean_s: float = 40.0
    step_rise_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("rate_hz", "noise_pa", "resolution_pa", "offset_sigma_pa",
                     "weather_sigma_pa_per_h", "weather_walk_pa_per_sqrt_s", "steps_per_h",
                     "step_sigma_pa", "step_mean_s", "step_rise_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise InputError(f"{name} = {value}", where="BarometerModel",
                                 expected="a finite value >= 0")
        if self.rate_hz <= 0.0 or self.step_mean_s <= 0.0 or self.step_rise_s <= 0.0:
            raise InputError("rate_hz, step_mean_s and step_rise_s must be > 0",
                             where="BarometerModel", expected="positive values")


def altitude_to_pressure(z_m: FloatArray, *, sea_level_pa: float = SEA_LEVEL_PA) -> FloatArray:
    """Standard-atmosphere pressure at height ``z_m`` above sea level, Pa."""
    return np.asarray(sea_level_pa * (1.0 - 2.25577e-5 * np.asarray(z_m)) ** 5.25588)


def simulate_barometer(t_truth: FloatArray, z_truth_m: FloatArray, model: BarometerModel,
                       rng: np.random.Generator, *, site_altitude_m: float = 300.0,
                       name: str = "pressure") -> SensorSeries:
    """Barometer samples at ``model.rate_hz`` over the truth's time span, Pa."""
    t0, t1 = float(t_truth[0]), float(t_truth[-1])
    t = np.arange(t0, t1, 1.0 / model.rate_hz)
    z = np.interp(t, t_truth, z_truth_m) + site_altitude_m
    p = altitude_to_pressure(z)
    p += rng.normal(0.0, model.offset_sigma_pa)
    hours = (t - t0) / 3600.0
    p += rng.normal(0.0, model.weather_sigma_pa_per_h) * hours
    dt = 1.0 / model.rate_hz
    p += np.cumsum(rng.normal(0.0, model.weather_walk_pa_per_sqrt_s * np.sqrt(dt), len(t)))
    n_steps = rng.poisson(model.steps_per_h * (t1 - t0) / 3600.0)
    for start in rng.uniform(t0, t1, n_steps):
        size = rng.normal(0.0, model.step_sigma_pa)
        end = start + rng.exponential(model.step_mean_s)
        rise = np.clip((t - start) / model.step_rise_s, 0.0, 1.0)
        fall = np.clip((t - end) / model.step_rise_s, 0.0, 1.0)
        p += size * (rise - fall)
    p += rng.normal(0.0, model.noise_pa, len(t))
    if model.resolution_pa > 0.0:
        p = np.round(p / model.resolution_pa) * model.resolution_pa
    return SensorSeries(t, p, name)


def with_barometer(result: SimulationResult, *, model: BarometerModel | None = None
                   ) -> SimulationResult:
    """``result`` with a barometer on its session, from the true height (own random stream)."""
    truth = result.session.truth
    if truth is None:
        raise InputError("no ground truth to derive pressure from", where=result.scenario,
                         expected="a simulated session with truth")
    rng = np.random.default_rng([result.seed, 0xBA20])
    pressure = simulate_barometer(truth.t, truth.xyz[:, 2], model or BarometerModel(), rng)
    return replace(result, session=result.session.with_parts(pressure=pressure))
