"""The grid filter's velocity modes and per-anchor burst state: hand-computed cells, invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.path_loss import PATH_LOSS_DTYPE, PathLossModel
from hrtls.fusion.rss_grid import (
    RSS_SPAN_DB,
    GridParams,
    GridScans,
    GridState,
    RssGridFilter,
    apply_likelihood,
    burst_predict,
    burst_update,
    causal_scans,
    log_likelihood,
    mix_modes,
    move_modes,
)

NO_MAP = np.zeros((0, 0, 0))
"""No radio map (the kernels' empty map and variance)."""

ANCHORS = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])


def _model(**kw: float) -> np.record:
    rec = np.zeros(1, dtype=PATH_LOSS_DTYPE)
    rec[0] = PathLossModel(**kw).record()[0]
    return rec[0]


def _walk(n: int, seed: int = 3) -> GridScans:
    """Scans of four anchors heard by a walker going along +x at 1 m/s, one per 0.5 s."""
    model = PathLossModel(sigma_db=3.0)
    t = np.repeat(0.5 * np.arange(n), 4)
    xy = np.column_stack([2.0 + t, np.full(t.size, 5.0)])
    a = np.tile(np.arange(4), n)
    d = np.maximum(np.linalg.norm(xy - ANCHORS[a], axis=1), 1.0)
    rss = model.expected_rss(d) + np.random.default_rng(seed).normal(0.0, 3.0, t.size)
    return causal_scans(t, a, rss, n_anchors=4, scan_s=0.5, average_s=0.5, t_origin=0.0)


def test_number_of_modes_and_refused_settings() -> None:
    assert GridParams().n_modes == 1
    assert GridParams(mode_turn_deg=90.0).n_modes == 4
    assert GridParams(mode_turn_deg=180.0, stopped_mode=True).n_modes == 3
    assert GridParams(mode_turn_deg=45.0, stopped_mode=True).n_modes == 9
    assert GridParams(stopped_mode=True).n_modes == 2
    for bad in ({"mode_turn_deg": 200.0}, {"mode_speed_m_per_s": 1.0},
                {"mode_switch_per_s": -1.0}, {"burst_sigma_db": -1.0}):
        with pytest.raises(InputError):
            GridParams(**bad)  # type: ignore[arg-type]


def test_mix_modes_by_hand() -> None:
    """Two modes, two cells: p'(x, m) = (1 - s) p(x, m) + s p(x, other); three: s / 2 each."""
    d = np.array([[[0.4, 0.1]], [[0.2, 0.3]]])
    mix_modes(d, 0.25)
    np.testing.assert_allclose(d, [[[0.35, 0.15]], [[0.25, 0.25]]], rtol=1e-14)
    d = np.array([[[0.3]], [[0.6]], [[0.1]]])
    mix_modes(d, 0.5)
    np.testing.assert_allclose(d[:, 0, 0], [0.5 * 0.3 + 0.25 * 0.7, 0.5 * 0.6 + 0.25 * 0.4,
                                            0.5 * 0.1 + 0.25 * 0.9], rtol=1e-14)
    one = np.array([[[0.7, 0.3]]])
    mix_modes(one, 0.9)                            # one mode: nothing to switch to
    np.testing.assert_array_equal(one, [[[0.7, 0.3]]])


def test_move_modes_by_hand() -> None:
    """Mode 0 at v, mode 1 at v turned by 90 deg, mode 2 stopped; each keeps its mass."""
    d = np.zeros((3, 5, 5))
    d[0, 2, 2], d[1, 2, 2], d[2, 2, 2] = 0.5, 0.3, 0.2
    # v = (1, 0) m/s, dt = 1 s, 0.5 m cells: 2 columns; turned: 2 rows; no blur
    move_modes(d, np.array([1.0, 0.0]), math.pi / 2, True, 1.0, 0.5, 0.0, np.empty((5, 5)))
    expect = np.zeros((3, 5, 5))
    expect[0, 2, 4], expect[1, 4, 2], expect[2, 2, 2] = 0.5, 0.3, 0.2
    np.testing.assert_allclose(d, expect, atol=1e-15)
    # moved out of the grid: the mass stays with its mode, back on the cells inside
    d = np.zeros((2, 3, 3))
    d[0, 1, 1], d[0, 1, 2], d[1, 1, 1] = 0.3, 0.3, 0.4
    move_modes(d, np.array([0.5, 0.0]), math.pi, False, 1.0, 0.5, 0.0, np.empty((3, 3)))
    assert d[0].sum() == pytest.approx(0.6) and d[1].sum() == pytest.approx(0.4)
    assert d[0, 1, 2] == pytest.approx(0.6) and d[1, 1, 0] == pytest.approx(0.4)


def test_apply_likelihood_by_hand() -> None:
    """Every mode times exp(ll), normalised over modes and cells; the mode weights follow."""
    d = np.array([[[0.25, 0.25]], [[0.4, 0.1]]])
    pos = np.zeros((1, 2))
    apply_likelihood(d, np.log(np.array([[1.0, 3.0]])), pos)
    z = 0.25 + 0.75 + 0.4 + 0.3
    np.testing.assert_allclose(d, [[[0.25 / z, 0.75 / z]], [[0.4 / z, 0.3 / z]]], rtol=1e-14)
    np.testing.assert_allclose(pos, [[0.65 / z, 1.05 / z]], rtol=1e-14)
    # a scan that excludes the whole prior: the likelihood, shared equally by the modes
    d = np.array([[[1.0, 0.0]], [[0.0, 0.0]]])
    apply_likelihood(d, np.array([[-math.inf, 0.0]]), pos)
    np.testing.assert_allclose(d, [[[0.0, 0.5]], [[0.0, 0.5]]])


def test_burst_component_of_the_likelihood_by_hand() -> None:
    """l = (1-e) [(1-b) N(r; mu+o, s) + b N(r; mu+o, sqrt(s^2 + burst^2))] + e / span."""
    dist = np.array([[[1.0, 10.0]]])
    out = np.zeros((1, 2))
    prm = GridParams(outlier_probability=0.1, burst_sigma_db=6.0).record()[0]
    log_likelihood(dist, NO_MAP, NO_MAP,
                   np.array([0]), np.array([-70.0]), np.array([0.5]), np.zeros(1),
                   np.array([9.0]), np.array([0.2]), _model(a_dbm=-59.0, eta=2.0, sigma_db=4.0),
                   prm, out)
    s, sb = 5.0, math.sqrt(61.0)
    for j, mu in enumerate((-59.0, -79.0)):
        e = -70.0 - mu
        lik = 0.9 * (0.8 * math.exp(-0.5 * (e / s) ** 2) / (math.sqrt(2 * math.pi) * s) +
                     0.2 * math.exp(-0.5 * (e / sb) ** 2) / (math.sqrt(2 * math.pi) * sb)) + \
            0.1 / RSS_SPAN_DB
        assert out[0, j] == pytest.approx(0.5 * math.log(lik), rel=1e-12)


def test_burst_update_and_predict_by_hand() -> None:
    """Point mass: odds *= (N(e; sb) / N(e; s))^w; the chain relaxes to enter / (enter + exit)."""
    dist = np.array([[[1.0, 10.0]], [[10.0, 1.0]]])
    density = np.array([[1.0, 0.0]])
    burst = np.array([0.1, 0.0])
    prm = GridParams(burst_sigma_db=8.0).record()[0]
    burst_update(dist, NO_MAP, NO_MAP,
                 density, np.array([0, 1]), np.array([-71.0, -70.0]), np.array([0.5, 1.0]),
                 np.zeros(2), np.zeros(2), burst, _model(a_dbm=-59.0, eta=2.0, sigma_db=6.0), prm)
    s, sb, e = 6.0, 10.0, -12.0
    ratio = (math.exp(-0.5 * (e / sb) ** 2) / sb) / (math.exp(-0.5 * (e / s) ** 2) / s)
    odds = 0.1 / 0.9 * ratio ** 0.5
    assert burst[0] == pytest.approx(odds / (1 + odds), rel=1e-12)
    assert burst[0] > 0.1                          # a 2-sigma reading makes a burst likelier
    assert burst[1] == 0.0                         # probability 0 stays 0
    b = np.array([1.0, 0.0])
    burst_predict(b, 2.0, 0.1, 0.4)
    np.testing.assert_allclose(b, 0.2 + np.array([0.8, -0.2]) * math.exp(-1.0), rtol=1e-14)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 5), st.integers(3, 9), st.integers(3, 9), st.floats(0.0, 1.0),
       st.floats(-1.5, 1.5), st.floats(-1.5, 1.5), st.floats(0.0, 2.0), st.integers(0, 2**31))
def test_mixing_and_motion_keep_the_mass(k: int, ny: int, nx: int, leave: float, vx: float,
                                         vy: float, sigma: float, seed: int) -> None:
    """Switching keeps the position density; the motion keeps each mode's mass; nothing < 0."""
    rng = np.random.default_rng(seed)
    d = rng.random((k, ny, nx))
    d /= d.sum()
    pos = d.sum(axis=0)
    mix_modes(d, leave)
    np.testing.assert_allclose(d.sum(axis=0), pos, rtol=1e-12, atol=1e-15)
    mass = d.sum(axis=(1, 2))
    move_modes(d, np.array([vx, vy]), 0.7, k > 1, 1.0, 0.5, sigma, np.empty((ny, nx)))
    assert np.all(d >= 0.0)
    if k > 1:
        np.testing.assert_allclose(d.sum(axis=(1, 2)), mass, rtol=1e-12)
    else:
        assert d.sum() == pytest.approx(1.0)


@settings(max_examples=6, deadline=None)
@given(st.sampled_from([90.0, 120.0, 180.0]), st.booleans(), st.floats(0.0, 2.0),
       st.integers(0, 1000))
def test_modes_of_one_velocity_are_the_one_mode_filter(turn: float, stopped: bool,
                                                       switch: float, seed: int) -> None:
    """Without a persistent velocity every mode stands still: the rows are one mode's."""
    scans = _walk(8, seed)
    one = RssGridFilter(ANCHORS, model=PathLossModel(sigma_db=3.0),
                        params=GridParams(cell_m=0.5, velocity_time_s=0.0))
    many = RssGridFilter(ANCHORS, model=PathLossModel(sigma_db=3.0), params=GridParams(
        cell_m=0.5, velocity_time_s=0.0, mode_turn_deg=turn, stopped_mode=stopped,
        mode_switch_per_s=switch))
    r1, s1 = one.update(one.start(), scans)
    rk, sk = many.update(many.start(), scans)
    np.testing.assert_allclose(rk.mean_xy, r1.mean_xy, atol=1e-9)
    np.testing.assert_allclose(rk.cov_xy, r1.cov_xy, atol=1e-9)
    np.testing.assert_allclose(sk.density.sum(axis=0), s1.density[0], atol=1e-12)


def test_modes_and_bursts_chunked_equal_one_call_and_pick_the_walking_direction() -> None:
    params = GridParams(cell_m=0.5, mode_turn_deg=45.0, mode_speed_m_per_s=1.0,
                        stopped_mode=True, mode_switch_per_s=0.1, burst_sigma_db=10.0)
    f = RssGridFilter(ANCHORS, model=PathLossModel(sigma_db=3.0), params=params)
    scans = _walk(12)
    whole, end = f.update(f.start(), scans)
    cut = 6
    part = GridScans(scans.t[:cut], scans.first[:cut], scans.count[:cut],
                     scans.anchor[:scans.first[cut]], scans.rss_dbm[:scans.first[cut]],
                     scans.weight[:scans.first[cut]])
    rest = GridScans(scans.t[cut:], scans.first[cut:] - scans.first[cut], scans.count[cut:],
                     scans.anchor[scans.first[cut]:], scans.rss_dbm[scans.first[cut]:],
                     scans.weight[scans.first[cut]:])
    first, mid = f.update(f.start(), part)
    later, end2 = f.update(mid, rest)
    np.testing.assert_allclose(np.vstack([first.mean_xy, later.mean_xy]), whole.mean_xy,
                               atol=1e-12)
    np.testing.assert_allclose(end2.density, end.density, atol=1e-15)
    np.testing.assert_allclose(end2.burst_probability, end.burst_probability, atol=1e-15)
    weights = end.density.sum(axis=(1, 2))
    assert weights.sum() == pytest.approx(1.0) and int(np.argmax(weights)) == 0   # +x
    # the state object given in is unchanged, and an older one-mode state is read
    assert mid.density.shape == (9, f.geometry.ny, f.geometry.nx)
    old = GridState(mid.t, mid.density.sum(axis=0), mid.offsets_db, True,
                    mid.offsets_var_db2, mid.velocity_m_per_s)
    np.testing.assert_allclose(old.modes(9).sum(axis=0), mid.density.sum(axis=0), atol=1e-15)
