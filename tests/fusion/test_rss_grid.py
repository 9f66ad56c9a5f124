"""The grid point-mass filter of RSS alone: hand-computed cells, kernels against Python."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.path_loss import PATH_LOSS_DTYPE, PathLossModel, mean_rss_dbm
from hrtls.fusion.rss_grid import (
    RSS_SPAN_DB,
    GridGeometry,
    GridParams,
    RssGridFilter,
    blur,
    causal_scans,
    log_likelihood,
    moments,
)


def _model(**kw: float) -> np.record:
    rec = np.zeros(1, dtype=PATH_LOSS_DTYPE)
    rec[0] = PathLossModel(**kw).record()[0]
    return rec[0]


def test_geometry_covers_the_anchors_plus_margin() -> None:
    g = GridGeometry.around(np.array([[0.0, 0.0], [4.0, 2.0]]), cell_m=1.0, margin_m=1.0,
                            max_cells=1000)
    x, y = g.centres()
    assert (x[0], x[-1], y[0], y[-1]) == (-1.0, 5.0, -1.0, 3.0)
    with pytest.raises(InputError, match="anchor"):
        GridGeometry.around(np.zeros((0, 2)), cell_m=1.0, margin_m=1.0, max_cells=1000)


def test_blur_of_a_point_is_the_normalised_gaussian() -> None:
    d = np.zeros((9, 9))
    d[4, 4] = 1.0
    blur(d, 1.0, np.empty_like(d))
    w = np.exp(-0.5 * np.arange(-3, 4) ** 2)
    w /= w.sum()
    np.testing.assert_allclose(d[1:8, 1:8], np.outer(w, w), atol=1e-15)
    assert d.sum() == pytest.approx(1.0)


def test_likelihood_of_one_reading_by_hand() -> None:
    dist = np.array([[[1.0, 10.0]]])                 # one anchor, one row, two cells
    out = np.zeros((1, 2))
    log_likelihood(dist, np.array([0]), np.array([-70.0]), np.array([0.5]), np.zeros(1),
                   _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0), 0.1, out)
    for j, mu in enumerate((-59.0, -79.0)):
        z = (-70.0 - mu) / 4.0
        lik = 0.9 * math.exp(-0.5 * z * z) / (math.sqrt(2 * math.pi) * 4.0) + 0.1 / RSS_SPAN_DB
        assert out[0, j] == pytest.approx(0.5 * math.log(lik), rel=1e-12)


def test_mean_rss_is_the_path_loss_law() -> None:
    assert mean_rss_dbm(-59.0, 2.0, 1.0, 10.0) == pytest.approx(-79.0)
    np.testing.assert_allclose(PathLossModel(a_dbm=-60.0, eta=3.0).expected_rss([1.0, 100.0]),
                               [-60.0, -120.0])


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 12), st.integers(3, 12), st.floats(0.0, 3.0), st.integers(0, 2**31))
def test_kernels_equal_their_python_reading_and_keep_a_density(ny: int, nx: int, sigma: float,
                                                              seed: int) -> None:
    rng = np.random.default_rng(seed)
    d = rng.random((ny, nx))
    d /= d.sum()
    a, b = d.copy(), d.copy()
    blur(a, sigma, np.empty_like(a))
    blur.py_func(b, sigma, np.empty_like(b))
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert np.all(a >= 0) and a.sum() == pytest.approx(1.0)
    m1, m2 = np.zeros(5), np.zeros(5)
    moments(a, 1.0, -2.0, 0.5, m1)
    moments.py_func(a, 1.0, -2.0, 0.5, m2)
    np.testing.assert_allclose(m1, m2, rtol=1e-9, atol=1e-12)
    assert m1[2] >= 0 and m1[4] >= 0 and m1[2] * m1[4] - m1[3] ** 2 >= -1e-9


def test_causal_scans_average_only_the_past_window() -> None:
    t = np.array([0.1, 0.2, 0.6, 0.7, 1.3])
    anchor = np.array([0, 1, 0, 0, 1])
    rss = np.array([-60.0, -70.0, -62.0, -64.0, -80.0])
    sc = causal_scans(t, anchor, rss, n_anchors=2, scan_s=0.5, average_s=1.0, t_origin=0.0)
    np.testing.assert_allclose(sc.t, [0.2, 0.7, 1.3])
    np.testing.assert_array_equal(sc.count, [2, 2, 2])
    np.testing.assert_allclose(sc.rss_dbm, [-60, -70, -62, -70, -63, -80])
    # weight: share of the window's readings that are new in the scan
    np.testing.assert_allclose(sc.weight, [1, 1, 2 / 3, 0, 0, 1])
    late = causal_scans(t, anchor, rss, n_anchors=2, scan_s=0.5, average_s=1.0, t_origin=0.0,
                        t_from=0.7)
    np.testing.assert_allclose(late.t, [1.3])
    # each new reading counted as its information fraction (hrtls.fusion.shadowing eq. 1)
    info = np.array([1.0, 1.0, 0.5, 0.25, 1.0])
    disc = causal_scans(t, anchor, rss, n_anchors=2, scan_s=0.5, average_s=1.0, t_origin=0.0,
                        info=info)
    np.testing.assert_allclose(disc.rss_dbm, sc.rss_dbm)
    np.testing.assert_allclose(disc.weight, [1, 1, 0.75 / 3, 0, 0, 1])


def test_first_scan_places_the_walker_where_the_readings_say() -> None:
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    model = PathLossModel(sigma_db=2.0)
    truth = np.array([2.0, 3.0])
    rss = model.expected_rss(np.maximum(np.linalg.norm(anchors - truth, axis=1), 1.0))
    f = RssGridFilter(anchors, model=model, params=GridParams(cell_m=0.25))
    sc = causal_scans(np.zeros(4), np.arange(4), rss, n_anchors=4, scan_s=0.5, average_s=1.0,
                      t_origin=0.0)
    rows, state = f.update(f.start(), sc)
    assert np.linalg.norm(rows.mean_xy[0] - truth) < 0.5
    assert state.started and state.density.sum() == pytest.approx(1.0)
    # a second identical scan 1 s later: the walker may have moved, but not by much
    sc2 = causal_scans(np.ones(4), np.arange(4), rss, n_anchors=4, scan_s=0.5, average_s=0.5,
                       t_origin=0.0)
    rows2, _ = f.update(state, sc2)
    assert np.trace(rows2.cov_xy[0]) <= np.trace(rows.cov_xy[0]) + 1e-9


def test_params_refuse_nonsense() -> None:
    with pytest.raises(InputError, match="average_s"):
        GridParams(scan_s=1.0, average_s=0.5)
    with pytest.raises(InputError, match="cell_m"):
        GridParams(cell_m=0.0)


def test_a_large_site_gets_larger_cells_within_max_cells() -> None:
    anchors = np.array([[0.0, 0.0], [300.0, 200.0]])
    g = GridGeometry.around(anchors, cell_m=0.25, margin_m=2.0, max_cells=10_000)
    assert g.nx * g.ny <= 10_000 and g.cell_m > 2.0
    x, y = g.centres()
    assert x[0] <= -2.0 + 1e-9 and x[-1] >= 302.0 - 1e-9 and y[-1] >= 202.0 - 1e-9
