"""What a grid scan row holds: of an anchor's readings in its window the mean in dBm, mean
power or median (``[prediction.grid] window_statistic``); of the density its mean or per-axis
median (``point_estimate``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.rss_grid import (
    WINDOW_STATISTICS,
    GridParams,
    causal_scans,
    median_row,
    moments,
    window_medians,
)
from hrtls.fusion.rss_grid_kernels import marginal_median
from hrtls.pipeline import TrackerConfig


def _scans(rss: np.ndarray, statistic: str, anchor: np.ndarray | None = None):
    t = np.linspace(0.05, 0.45, len(rss))
    a = np.zeros(len(rss), dtype=np.int64) if anchor is None else anchor
    return causal_scans(t, a, rss, n_anchors=int(a.max()) + 1, scan_s=0.5, average_s=1.0,
                        t_origin=0.0, statistic=statistic)


def test_hand_computed_window_values() -> None:
    rss = np.array([-60.0, -70.0, -90.0])
    # mean in dBm: -220 / 3; mean power: 10 log10((1e-6 + 1e-7 + 1e-9) / 3) mW; median -70
    assert _scans(rss, "mean-db").rss_dbm[0] == pytest.approx(-220.0 / 3.0)
    assert _scans(rss, "mean-power").rss_dbm[0] == pytest.approx(
        10.0 * math.log10(1.101e-6 / 3.0))
    assert _scans(rss, "median").rss_dbm[0] == pytest.approx(-70.0)
    assert _scans(rss[:2], "median").rss_dbm[0] == pytest.approx(-65.0)
    # two anchors, each its own readings; the weights do not depend on the statistic
    a = np.array([0, 1, 0, 1], dtype=np.int64)
    r = np.array([-60.0, -80.0, -70.0, -82.0])
    sc = _scans(r, "mean-power", a)
    np.testing.assert_allclose(sc.rss_dbm, [10.0 * math.log10(0.55e-6),
                                            10.0 * math.log10((1e-8 + 10.0 ** -8.2) / 2.0)])
    np.testing.assert_allclose(sc.weight, _scans(r, "mean-db", a).weight)


def test_window_medians_kernel_matches_numpy() -> None:
    v = np.array([3.0, -1.0, 7.0, 2.0, 2.5, -4.0])
    lo, hi = np.array([0, 1, 5]), np.array([3, 6, 6])
    np.testing.assert_allclose(window_medians(v, lo, hi),
                               [np.median(v[0:3]), np.median(v[1:6]), v[5]])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-100.0, -40.0), min_size=1, max_size=12))
def test_statistics_lie_within_the_window_and_power_mean_is_not_below_db_mean(
        values: list[float]) -> None:
    rss = np.array(values)
    got = {s: _scans(rss, s).rss_dbm[0] for s in WINDOW_STATISTICS}
    for v in got.values():
        assert rss.min() - 1e-9 <= v <= rss.max() + 1e-9
    # Jensen: log of the mean power >= mean of the logs; equal for equal readings
    assert got["mean-power"] >= got["mean-db"] - 1e-9
    if np.ptp(rss) == 0.0:
        for v in got.values():
            assert v == pytest.approx(rss[0])


def test_unknown_statistic_is_refused() -> None:
    with pytest.raises(InputError, match="window_statistic"):
        GridParams(window_statistic="mode")  # type: ignore[arg-type]
    cfg = TrackerConfig().model_dump()
    cfg["prediction"]["grid"]["window_statistic"] = "max"
    with pytest.raises(ValueError, match="window_statistic"):
        TrackerConfig.model_validate(cfg)
    assert GridParams().window_statistic == "mean-db"


def test_hand_computed_median_row() -> None:
    # x marginal 0.2 / 0.2 / 0.6 at x = 0, 1, 2: cumulative 0.4 at x = 1, 1.0 at x = 2, so the
    # median is 1 + 0.1 / 0.6; one row of cells: y median at its centre, 5
    assert marginal_median(np.array([0.2, 0.2, 0.6]), 0.0, 1.0) == pytest.approx(7.0 / 6.0)
    assert marginal_median(np.array([0.6, 0.4]), 3.0, 0.5) == pytest.approx(3.0)
    d = np.array([[0.2, 0.2, 0.6]])
    row = np.zeros(5)
    moments(d, 0.0, 5.0, 1.0, row)
    np.testing.assert_allclose(row, [1.4, 5.0, 0.64, 0.0, 0.0], atol=1e-12)
    median_row(d, 0.0, 5.0, 1.0, row)
    # covariance about the median: 0.64 + (1.4 - 7/6)^2
    np.testing.assert_allclose(row, [7.0 / 6.0, 5.0, 0.64 + (1.4 - 7.0 / 6.0) ** 2, 0.0, 0.0],
                               atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 7), st.integers(1, 7))
def test_median_row_within_the_grid_and_spread_not_below_the_covariance(
        seed: int, ny: int, nx: int) -> None:
    rng = np.random.default_rng(seed)
    d = rng.random((ny, nx)) ** 4
    d /= d.sum()
    row = np.zeros(5)
    moments(d, -1.0, 2.0, 0.5, row)
    before = row.copy()
    median_row(d, -1.0, 2.0, 0.5, row)
    other = before.copy()
    median_row.py_func(d, -1.0, 2.0, 0.5, other)
    np.testing.assert_allclose(row, other, rtol=1e-9, atol=1e-12)
    assert -1.0 - 1e-9 <= row[0] <= -1.0 + 0.5 * (nx - 1) + 1e-9
    assert 2.0 - 1e-9 <= row[1] <= 2.0 + 0.5 * (ny - 1) + 1e-9
    assert row[2] >= before[2] - 1e-12 and row[4] >= before[4] - 1e-12
    assert row[2] * row[4] - row[3] ** 2 >= -1e-9
    # half the mass on either side of the median of each marginal (within a cell's mass)
    px = d.sum(axis=0)
    x = -1.0 + 0.5 * np.arange(nx)
    assert px[x < row[0] - 1e-9].sum() <= 0.5 + 1e-9


def test_unknown_point_estimate_is_refused() -> None:
    with pytest.raises(InputError, match="point_estimate"):
        GridParams(point_estimate="mode")  # type: ignore[arg-type]
    assert GridParams().point_estimate == "mean"
    assert GridParams(point_estimate="median").record()["median_point"][0] == 1.0
    assert GridParams().record()["median_point"][0] == 0.0
