"""The unit checks decide by counting where they can: the same answer as the median/percentile."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.units import (
    _norms,
    suspect_accelerometer_unit,
    suspect_gyroscope_unit,
    suspect_magnetometer_unit,
)

EDGES = [0.05, 0.4, 2.5, 3.0, 25.0, 400.0, 2500.0, 5000.0, 300000.0, 9.81, 30.0]


def _reference(kind: str, values: np.ndarray) -> bool:
    """Whether the check should complain, from the exact median or 99th percentile."""
    norms = _norms(values)
    if kind == "gyro":
        return bool(np.percentile(norms, 99) > 25.0)
    m = float(np.median(norms))
    bands = ((0.4, 2.5), (400.0, 2500.0)) if kind == "accel" else ((0.05, 3.0), (5000.0, 3e5))
    return any(lo <= m <= hi for lo, hi in bands)


def _near(edge: float, ulps: int) -> float:
    x = edge
    for _ in range(abs(ulps)):
        x = float(np.nextafter(x, np.inf if ulps > 0 else -np.inf))
    return x


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(EDGES), st.integers(-2, 2)), min_size=20,
                max_size=61),
       st.integers(0, 2**16), st.booleans())
def test_counted_decisions_match_the_median(edges, seed, with_nan):
    """Norms at and next to every band edge (odd and even counts, ties, a NaN)."""
    rng = np.random.default_rng(seed)
    norms = np.array([_near(e, u) for e, u in edges])
    if with_nan:
        norms[rng.integers(len(norms))] = np.nan
    values = np.zeros((len(norms), 3))
    values[:, 0] = norms  # the row norm is |x| exactly
    for kind, check in (("accel", suspect_accelerometer_unit), ("gyro", suspect_gyroscope_unit),
                        ("mag", suspect_magnetometer_unit)):
        assert (check(values) is not None) == _reference(kind, values), kind


@settings(max_examples=400, deadline=None)
@given(st.integers(20, 61), st.sampled_from(EDGES), st.integers(-2, 2), st.integers(0, 2**16))
def test_decisions_with_the_middle_values_at_a_band_edge(n, edge, shift, seed):
    """``c`` norms just below an edge, the others at or just above it: c around n / 2."""
    rng = np.random.default_rng(seed)
    c = n // 2 + shift
    low = [_near(edge, -int(u)) for u in rng.integers(1, 3, c)]
    high = [_near(edge, int(u)) for u in rng.integers(0, 3, n - c)]
    values = np.zeros((n, 3))
    values[:, 0] = rng.permutation(np.array(low + high))
    for kind, check in (("accel", suspect_accelerometer_unit), ("gyro", suspect_gyroscope_unit),
                        ("mag", suspect_magnetometer_unit)):
        assert (check(values) is not None) == _reference(kind, values), kind


def test_si_signals_pass_and_wrong_units_are_caught():
    rng = np.random.default_rng(0)
    acc = rng.normal([0.0, 0.0, 9.81], 1.0, (5000, 3))
    gyr = rng.normal(0.0, 1.0, (5000, 3))
    mag = rng.normal([20.0, 0.0, -40.0], 2.0, (5000, 3))
    assert suspect_accelerometer_unit(acc) is None
    assert suspect_gyroscope_unit(gyr) is None
    assert suspect_magnetometer_unit(mag) is None
    assert "g" in (suspect_accelerometer_unit(acc / 9.81) or "")
    assert "deg/s" in (suspect_gyroscope_unit(np.degrees(gyr) * 10) or "")
    assert "nT" in (suspect_magnetometer_unit(mag * 1000) or "")
