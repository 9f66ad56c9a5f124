"""Lag compensation of the grid filter (``[prediction.grid] lag_compensation``): a scan's
window of readings is placed where the walker was when they were taken, ``g v age`` behind."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.rss_grid import GridParams, RssGridFilter, causal_scans, shift_field

ANCHORS = np.array([[0.0, 0.0], [12.0, 0.0], [0.0, 8.0], [12.0, 8.0], [6.0, 4.0]])


def test_causal_scans_age_by_hand() -> None:
    t = np.array([0.1, 0.2, 0.6, 0.7, 1.3])
    anchor = np.array([0, 1, 0, 0, 1])
    rss = np.array([-60.0, -70.0, -62.0, -64.0, -80.0])
    sc = causal_scans(t, anchor, rss, n_anchors=2, scan_s=0.5, average_s=1.0, t_origin=0.0)
    # scan 0.2: rows aged 0.1 and 0 s, weights 1 and 1; scan 0.7: anchor 0's readings 0.1,
    # 0.6, 0.7 (age 0.7 - 1.4 / 3, weight 2/3), anchor 1's 0.2 (weight 0); scan 1.3: only
    # anchor 1's new reading weighs (age 0)
    assert sc.age_s is not None
    np.testing.assert_allclose(sc.age_s, [0.05, 0.7 - 1.4 / 3.0, 0.0], atol=1e-12)


def test_shift_field_by_hand() -> None:
    f = np.arange(4.0)[None, :] + 10.0 * np.arange(3.0)[:, None]      # f[i, j] = j + 10 i
    g = f.copy()
    shift_field(g, 1.0, 0.0, np.empty_like(g))       # g(x) = f(x - 1 column), edge held
    np.testing.assert_allclose(g, f[:, [0, 0, 1, 2]])
    g = f.copy()
    shift_field(g, 0.0, 0.5, np.empty_like(g))       # half a row: between rows, edge held
    np.testing.assert_allclose(g, np.vstack([f[0], f[0] + 5.0, f[1] + 5.0]))
    g = f.copy()
    shift_field(g, 0.0, 0.0, np.empty_like(g))
    np.testing.assert_array_equal(g, f)


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 10), st.integers(3, 10), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0),
       st.floats(-3.0, 3.0), st.floats(-3.0, 3.0))
def test_shift_field_moves_a_plane_exactly_inside_and_keeps_a_constant(
        ny: int, nx: int, sx: float, sy: float, ax: float, ay: float) -> None:
    i, j = np.mgrid[0:ny, 0:nx].astype(np.float64)
    f = ax * j + ay * i
    g = f.copy()
    shift_field(g, sx, sy, np.empty_like(g))
    inside = (j - sx >= 0) & (j - sx <= nx - 1) & (i - sy >= 0) & (i - sy <= ny - 1)
    np.testing.assert_allclose(g[inside], (ax * (j - sx) + ay * (i - sy))[inside], atol=1e-9)
    c = np.full((ny, nx), -3.5)
    shift_field(c, sx, sy, np.empty_like(c))
    np.testing.assert_allclose(c, -3.5, atol=1e-12)


def test_lag_compensation_is_refused_beyond_one() -> None:
    with pytest.raises(InputError, match="lag_compensation"):
        GridParams(lag_compensation=1.5)
    with pytest.raises(InputError, match="lag_compensation"):
        GridParams(lag_compensation=-0.1)


def _walk(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Readings at 2 Hz per anchor (staggered) of a walker along +x at 0.5 m/s, 20 s."""
    model = PathLossModel(sigma_db=3.0)
    t = np.arange(0.0, 20.0, 0.1)
    a = np.arange(t.size) % len(ANCHORS)
    xy = np.column_stack([1.0 + 0.5 * t, np.full(t.size, 3.0)])
    d = np.maximum(np.linalg.norm(xy - ANCHORS[a], axis=1), 1.0)
    rss = model.expected_rss(d) + np.random.default_rng(seed).normal(0.0, 2.0, t.size)
    return t, a, rss, xy


def _rows(params: GridParams, seed: int) -> tuple[np.ndarray, np.ndarray]:
    t, a, rss, xy = _walk(seed)
    f = RssGridFilter(ANCHORS, model=PathLossModel(sigma_db=3.0), params=params)
    sc = causal_scans(t, a, rss, n_anchors=len(ANCHORS), scan_s=0.5, average_s=2.0,
                      t_origin=0.0)
    rows, _ = f.update(f.start(), sc)
    truth_x = np.interp(rows.t, t, xy[:, 0])
    return rows.mean_xy, truth_x


def test_without_a_velocity_lag_compensation_changes_nothing() -> None:
    still = GridParams(cell_m=0.25, velocity_time_s=0.0)
    lagged = GridParams(cell_m=0.25, velocity_time_s=0.0, lag_compensation=1.0)
    np.testing.assert_array_equal(_rows(lagged, 0)[0], _rows(still, 0)[0])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_lag_compensation_brings_the_track_closer_behind_a_walker(seed: int) -> None:
    # along-track error (truth minus estimate, m) over the last 10 s: the 2 s window's
    # readings are about 0.75 s old, so without compensation the track trails the walker;
    # compensated, it moves ahead by about v age = 0.5 m/s x 0.75 s and trails less
    base, truth = _rows(GridParams(cell_m=0.25), seed)
    comp, _ = _rows(GridParams(cell_m=0.25, lag_compensation=1.0), seed)
    late = slice(len(truth) // 2, None)
    lag_base = float(np.mean(truth[late] - base[late, 0]))
    lag_comp = float(np.mean(truth[late] - comp[late, 0]))
    assert lag_base > 0.2
    assert lag_comp < lag_base - 0.25
    assert abs(lag_comp) < lag_base


def test_lagged_filter_chunked_equals_one_call() -> None:
    t, a, rss, _ = _walk(0)
    f = RssGridFilter(ANCHORS, model=PathLossModel(sigma_db=3.0),
                      params=GridParams(cell_m=0.5, lag_compensation=0.5))
    kw = {"n_anchors": len(ANCHORS), "scan_s": 0.5, "average_s": 2.0, "t_origin": 0.0}
    whole, end = f.update(f.start(), causal_scans(t, a, rss, **kw))
    cut = 7.0
    first, mid = f.update(f.start(), causal_scans(t[t < cut], a[t < cut], rss[t < cut], **kw))
    rest, end2 = f.update(mid, causal_scans(t, a, rss, t_from=mid.t, **kw))
    np.testing.assert_allclose(np.vstack([first.mean_xy, rest.mean_xy]), whole.mean_xy,
                               atol=1e-12)
    np.testing.assert_allclose(end2.velocity_m_per_s, end.velocity_m_per_s, atol=1e-12)
