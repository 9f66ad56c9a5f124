"""Seeds and options of the named scenarios: independent generators, options over defaults."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError

__all__ = ["DEFAULTS", "scenario_options", "scenario_rngs"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def scenario_rngs(seed: int, n: int = 8) -> list[np.random.Generator]:
    """Independent generators: 0 path, 1 gait, 2 imu, 3 camera, 4 rss, 5 tags, 6 ranges, 7 misc."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)]



def scenario_options(options: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    """``options`` over ``defaults`` (plus ``calibration``), converted to the defaults' types."""
    defaults = {**defaults, "calibration": False}
    unknown = set(options) - set(defaults)
    if unknown:
        raise InputError(f"unknown option(s) {sorted(unknown)}", where="scenario options",
                         expected="one of " + ", ".join(sorted(defaults)))
    out = dict(defaults)
    for k, v in options.items():
        out[k] = type(defaults[k])(v) if defaults[k] is not None and not isinstance(
            v, type(defaults[k])) else v
    return out


DEFAULTS: dict[str, dict[str, Any]] = {
    "colombo_circle": {"laps": 5, "total_m": 31.0, "speed_m_s": 0.0, "tp_s": 8.0},
    "colombo_square": {"laps": 5, "total_m": 40.0, "speed_m_s": 0.0, "tp_s": 8.0},
    "colombo_natural": {"distance_m": 35.0, "tp_s": 10.0},
    "basso": {"placement": "random", "device": "mpu6150_phone", "rate_hz": 50.0},
    "tarrio_circle": {"laps": 5.0, "speed_m_s": 1.0, "rss_period_s": 2.0,
                      "readings_per_period": 5},
    "tarrio_office": {"user": 1, "readings_per_period": 5},
    "inderst_ring": {"tags": "all", "distance_m": 500.0, "speed_m_s": 0.9},
    "inderst_multifloor": {"speed_m_s": 1.1, "pressure": True},
    "inderst_two_users": {"user": "A", "tags": True},
    "inderst_wsn_random": {"n_nodes": 50, "radius": 0.2, "n_anchors": 4,
                           "distance_sigma": 0.005},
    "inderst_wsn_building": {"n_anchors": 3, "range_m": 5.0},
    "office_random_walk": {"duration_s": 600.0, "device": "mpu6150_phone"},
}
"""Options of each scenario and their defaults (``-O key=value`` on the command line)."""
