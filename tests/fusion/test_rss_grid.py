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
    bias_update,
    blur,
    causal_scans,
    follow_velocity,
    log_likelihood,
    moments,
    shift,
)

NO_MAP = np.zeros((0, 0, 0))
"""No radio map (the kernels' empty map and variance)."""


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
    log_likelihood(dist, NO_MAP, NO_MAP,
                   np.array([0]), np.array([-70.0]), np.array([0.5]), np.zeros(1),
                   np.zeros(1), np.zeros(1), _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0),
                   GridParams(outlier_probability=0.1).record()[0], out)
    for j, mu in enumerate((-59.0, -79.0)):
        z = (-70.0 - mu) / 4.0
        lik = 0.9 * math.exp(-0.5 * z * z) / (math.sqrt(2 * math.pi) * 4.0) + 0.1 / RSS_SPAN_DB
        assert out[0, j] == pytest.approx(0.5 * math.log(lik), rel=1e-12)


def test_attenuated_component_and_offset_variance_by_hand() -> None:
    """l = (1-e) [(1-q) N(r; mu+o, s) + q N(r; mu+o-att, s)] + e/span, s^2 = sigma^2 + P."""
    dist = np.array([[[1.0, 10.0]]])
    out = np.zeros((1, 2))
    prm = GridParams(outlier_probability=0.1, attenuation_probability=0.25, attenuation_db=8.0)
    log_likelihood(dist, NO_MAP, NO_MAP,
                   np.array([0]), np.array([-70.0]), np.array([1.0]), np.array([2.0]),
                   np.array([9.0]), np.zeros(1), _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0),
                   prm.record()[0], out)
    s = 5.0                                          # sqrt(4^2 + 9)
    for j, mu in enumerate((-59.0 + 2.0, -79.0 + 2.0)):
        g = 0.75 * math.exp(-0.5 * ((-70.0 - mu) / s) ** 2) + \
            0.25 * math.exp(-0.5 * ((-70.0 - mu + 8.0) / s) ** 2)
        lik = 0.9 * g / (math.sqrt(2 * math.pi) * s) + 0.1 / RSS_SPAN_DB
        assert out[0, j] == pytest.approx(math.log(lik), rel=1e-12)
    # a reading far weaker than the model is likelier with the attenuated component
    plain, att = np.zeros((1, 2)), np.zeros((1, 2))
    for q, o in ((0.0, plain), (0.25, att)):
        log_likelihood(dist, NO_MAP, NO_MAP,
                       np.array([0]), np.array([-71.0]), np.array([1.0]), np.zeros(1),
                       np.zeros(1), np.zeros(1), _model(sigma_db=4.0),
                       GridParams(attenuation_probability=q).record()[0], o)
    assert att[0, 0] > plain[0, 0] and att[0, 1] < plain[0, 1]


def test_bias_update_by_hand() -> None:
    """A point-mass density: e = r - mu - o, S = sigma^2 / w + P, o += P e / S, P -= P^2 / S."""
    dist = np.array([[[1.0, 10.0]], [[10.0, 1.0]]])     # two anchors, two cells
    density = np.array([[1.0, 0.0]])
    off, var = np.array([1.0, 0.0]), np.array([9.0, 4.0])
    bias_update(dist, NO_MAP, NO_MAP,
                density, np.array([0, 1]), np.array([-55.0, -75.0]), np.array([0.5, 1.0]),
                off, var, _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
    s0 = 16.0 / 0.5 + 9.0
    assert off[0] == pytest.approx(1.0 + 9.0 / s0 * (-55.0 + 59.0 - 1.0), rel=1e-12)
    assert var[0] == pytest.approx(9.0 - 81.0 / s0, rel=1e-12)
    s1 = 16.0 + 4.0
    assert off[1] == pytest.approx(4.0 / s1 * (-75.0 + 79.0), rel=1e-12)
    # two equally likely cells: the spread of the predicted RSS enters S
    density = np.array([[0.5, 0.5]])
    off, var = np.zeros(2), np.array([9.0, 9.0])
    bias_update(dist, NO_MAP, NO_MAP,
                density, np.array([0]), np.array([-69.0]), np.array([1.0]), off, var,
                _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
    s = 16.0 + 100.0 + 9.0                              # Var of (-59, -79) is 100
    assert off[0] == pytest.approx(9.0 / s * 0.0, abs=1e-12) and var[0] == pytest.approx(
        9.0 - 81.0 / s, rel=1e-12)
    # a residual beyond 3 sqrt(S) is not used
    off, var = np.zeros(2), np.array([9.0, 9.0])
    bias_update(dist, NO_MAP, NO_MAP,
                np.array([[1.0, 0.0]]), np.array([0]), np.array([-30.0]), np.array([1.0]),
                off, var, _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0))
    assert off[0] == 0.0 and var[0] == 9.0


def _walk(anchors: np.ndarray, model: PathLossModel, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = np.repeat(np.arange(0.0, 10.0, 0.5), len(anchors)) + 0.01
    a = np.tile(np.arange(len(anchors)), 20)
    xy = np.column_stack([2.0 + 0.5 * t, 3.0 + 0.2 * t])
    d = np.maximum(np.linalg.norm(xy - anchors[a], axis=1), 1.0)
    return t, a, model.expected_rss(d) + rng.normal(0.0, 4.0, len(t))


@settings(max_examples=15, deadline=None)
@given(st.floats(-10.0, 10.0), st.integers(0, 2**31), st.sampled_from([0.0, 3.0]))
def test_a_bias_common_to_readings_and_offsets_does_not_move_the_walker(
        c: float, seed: int, bias_sigma: float) -> None:
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    model = PathLossModel()
    t, a, rss = _walk(anchors, model, seed)
    prm = GridParams(cell_m=0.5, bias_sigma_db=bias_sigma, attenuation_probability=0.2)
    f = RssGridFilter(anchors, model=model, params=prm)
    rows = []
    for common_db in (0.0, c):
        sc = causal_scans(t, a, rss + common_db, n_anchors=4, scan_s=0.5, average_s=1.0,
                          t_origin=0.0)
        rows.append(f.update(f.start(np.full(4, common_db)), sc)[0])
    np.testing.assert_allclose(rows[1].mean_xy, rows[0].mean_xy, atol=1e-6)


def test_the_bias_state_learns_a_constant_anchor_offset() -> None:
    """A +6 dB anchor: the bias state finds it and the track is closer to the walk."""
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    model = PathLossModel()
    t, a, rss = _walk(anchors, model, 3)
    rss = rss + np.where(a == 1, 6.0, 0.0)
    sc = causal_scans(t, a, rss, n_anchors=4, scan_s=0.5, average_s=1.0, t_origin=0.0)
    err = []
    for sigma in (0.0, 4.0):
        f = RssGridFilter(anchors, model=model, params=GridParams(cell_m=0.25,
                                                                  bias_sigma_db=sigma))
        rows, state = f.update(f.start(), sc)
        xy = np.column_stack([2.0 + 0.5 * rows.t, 3.0 + 0.2 * rows.t])
        err.append(float(np.mean(np.linalg.norm(rows.mean_xy - xy, axis=1)[10:])))
        if sigma:
            assert state.offsets_db[1] - np.mean(state.offsets_db[[0, 2, 3]]) > 3.0
            assert state.offsets_var_db2 is not None and np.all(state.offsets_var_db2 < 16.0)
    assert err[1] < err[0]


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


def test_shift_moves_a_point_mass_by_v_dt() -> None:
    d = np.zeros((9, 9))
    d[4, 4] = 1.0
    # v = (0.6, -0.2) m/s for dt = 2.5 s on 0.5 m cells: 3 columns right, 1 row down
    shift(d, 0.6 * 2.5 / 0.5, -0.2 * 2.5 / 0.5, np.empty_like(d))
    expect = np.zeros((9, 9))
    expect[3, 7] = 1.0
    np.testing.assert_allclose(d, expect, atol=1e-15)
    # a fraction of a cell splits the mass between the two neighbours, mean moved exactly
    d = np.zeros((9, 9))
    d[4, 4] = 1.0
    shift(d, 1.25, 0.0, np.empty_like(d))
    assert (d[4, 5], d[4, 6]) == pytest.approx((0.75, 0.25))
    m = np.zeros(5)
    moments(d, 0.0, 0.0, 1.0, m)
    assert (m[0], m[1]) == pytest.approx((5.25, 4.0))


def test_follow_velocity_by_hand() -> None:
    v = np.array([1.0, 0.0])
    # gain dt / (tau + dt) = 0.5 / 2.5 = 0.2; displacement per second (0, 2)
    follow_velocity(v, np.array([0.0, 0.0]), np.array([0.0, 1.0]), 0.5, 2.0, 10.0)
    np.testing.assert_allclose(v, [0.8, 0.4])
    follow_velocity(v, np.array([0.0, 0.0]), np.array([10.0, 0.0]), 0.5, 0.0, 1.5)
    np.testing.assert_allclose(v, [1.5, 0.0])      # gain 1, clipped to 1.5 m/s


@settings(max_examples=25, deadline=None)
@given(st.integers(3, 12), st.integers(3, 12), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0),
       st.integers(0, 2**31))
def test_shift_keeps_a_density_and_equals_its_python_reading(ny: int, nx: int, sx: float,
                                                            sy: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    d = rng.random((ny, nx))
    d /= d.sum()
    a, b = d.copy(), d.copy()
    shift(a, sx, sy, np.empty_like(a))
    shift.py_func(b, sx, sy, np.empty_like(b))
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert np.all(a >= 0) and a.sum() == pytest.approx(1.0)
    z = d.copy()
    shift(z, 0.0, 0.0, np.empty_like(z))
    np.testing.assert_array_equal(z, d)


def _walk_scans(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Readings of four anchors of a walker going along x at 1 m/s, one scan per 0.5 s."""
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    model = PathLossModel(sigma_db=3.0)
    t = np.repeat(0.5 * np.arange(n), 4)
    xy = np.column_stack([2.0 + t, np.full(t.size, 5.0)])
    a = np.tile(np.arange(4), n)
    d = np.maximum(np.linalg.norm(xy - anchors[a], axis=1), 1.0)
    rss = model.expected_rss(d) + np.random.default_rng(3).normal(0.0, 3.0, t.size)
    return t, a, rss


def test_zero_velocity_is_the_old_diffusion_and_chunks_give_one_run() -> None:
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    model = PathLossModel(sigma_db=3.0)
    t, a, rss = _walk_scans(12)
    sc = causal_scans(t, a, rss, n_anchors=4, scan_s=0.5, average_s=0.5, t_origin=0.0)
    # a velocity state that is never fed (infinite time constant) stays zero: plain diffusion
    plain = RssGridFilter(anchors, model=model,
                          params=GridParams(cell_m=0.5, velocity_time_s=0.0))
    still = RssGridFilter(anchors, model=model,
                          params=GridParams(cell_m=0.5, velocity_time_s=1e300))
    r0, _ = plain.update(plain.start(), sc)
    r1, s1 = still.update(still.start(), sc)
    np.testing.assert_allclose(r1.mean_xy, r0.mean_xy, atol=1e-12)
    assert np.all(np.abs(s1.velocity_m_per_s) < 1e-290)
    # with velocity: the rows of one call equal those of two calls carrying the state
    f = RssGridFilter(anchors, model=model, params=GridParams(cell_m=0.5, velocity_time_s=2.0))
    whole, end = f.update(f.start(), sc)
    cut = 6.0 * 0.5
    first, mid = f.update(f.start(), causal_scans(t[t < cut], a[t < cut], rss[t < cut],
                                                  n_anchors=4, scan_s=0.5, average_s=0.5,
                                                  t_origin=0.0))
    rest, end2 = f.update(mid, causal_scans(t, a, rss, n_anchors=4, scan_s=0.5, average_s=0.5,
                                            t_origin=0.0, t_from=mid.t))
    np.testing.assert_allclose(np.vstack([first.mean_xy, rest.mean_xy]), whole.mean_xy,
                               atol=1e-12)
    np.testing.assert_allclose(end2.velocity_m_per_s, end.velocity_m_per_s, atol=1e-12)
    # the walker goes along +x: the persistent velocity learnt points that way
    assert end.velocity_m_per_s[0] > 0.3
