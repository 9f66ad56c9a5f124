"""The heading-error bands of ``benchmarks/mission_heading.py`` (hand-computed)."""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
import pytest


@pytest.fixture(scope="module")
def bench(benchmark_import: Callable[[str], ModuleType]) -> ModuleType:
    return benchmark_import("mission_heading")


def test_bands_by_distance_walked(bench: ModuleType) -> None:
    # 1 m/s east for 70 s; the estimate is 2 degrees off up to 10 m walked, then -5 degrees
    t = np.arange(0.0, 70.0, 0.5)
    xy = np.column_stack([t, np.zeros_like(t)])
    est = np.where(t < 10.0, np.radians(2.0), np.radians(-5.0))
    errs = bench.band_errors_deg(t, est, t, xy, np.zeros_like(t))
    assert errs == pytest.approx([2.0, -5.0, -5.0])


def test_error_wraps_across_pi(bench: ModuleType) -> None:
    # truth heading just below +pi, estimate just above -pi: 2 degrees apart, not 358
    t = np.arange(0.0, 70.0, 0.5)
    xy = np.column_stack([-t, np.zeros_like(t)])
    truth = np.full_like(t, np.pi - np.radians(1.0))
    est = np.full_like(t, -np.pi + np.radians(1.0))
    assert bench.band_errors_deg(t, est, t, xy, truth) == pytest.approx([2.0, 2.0, 2.0])


def test_band_not_reached_is_nan(bench: ModuleType) -> None:
    t = np.arange(0.0, 12.0, 0.5)
    xy = np.column_stack([t, np.zeros_like(t)])
    errs = bench.band_errors_deg(t, np.zeros_like(t), t, xy, np.zeros_like(t))
    assert errs[0] == 0.0 and np.isnan(errs[1]) and np.isnan(errs[2])
