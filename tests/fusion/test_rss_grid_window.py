"""What a grid scan row holds of an anchor's readings in its window: mean in dBm, mean power,
median (``[prediction.grid] window_statistic``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.rss_grid import WINDOW_STATISTICS, GridParams, causal_scans, window_medians
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
