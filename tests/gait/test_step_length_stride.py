"""Stride lengths from prorated steps, chord correction, scale fits (step_length_stride)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.frames import quat_from_euler
from hrtls.gait.step_length_stride import (
    chord_factor,
    fit_scale,
    prorated_stride_lengths,
    rotation_over,
    transfer_scale,
)
from hrtls.gait.turns import TurnDetector


def slow_prorated(a: np.ndarray, b: np.ndarray, ln: np.ndarray, s0: np.ndarray,
                  s1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Independent reference: every step against every stride, plain Python."""
    out = np.zeros(len(s0))
    cov = np.zeros(len(s0))
    for i in range(len(s0)):
        for k in range(len(a)):
            span = max(b[k] - a[k], 1e-9)
            ov = max(0.0, min(b[k], s1[i]) - max(a[k], s0[i]))
            out[i] += ln[k] * ov / span
            cov[i] += ov / span
    return out, cov


def test_prorated_hand_cases() -> None:
    # steps of 0.5 s, lengths 0.6, 0.7, 0.8, 0.9 m
    a = np.array([0.0, 0.5, 1.0, 1.5])
    b = a + 0.5
    ln = np.array([0.6, 0.7, 0.8, 0.9])
    # stride tiled by steps 1 and 2; stride shifted by a quarter step; stride past the end
    est = prorated_stride_lengths(a, b, ln, [0.5, 0.625, 1.75], [1.5, 1.625, 2.75])
    np.testing.assert_allclose(est.length_m, [1.5, 0.7 * 0.75 + 0.8 + 0.9 * 0.25,
                                              0.9 * 0.5])
    np.testing.assert_allclose(est.coverage, [2.0, 2.0, 0.5])
    # a missed step (gap): the stride gets only the detected share
    est2 = prorated_stride_lengths([0.0, 1.0], [0.5, 1.5], [0.6, 0.8], [0.0], [1.0])
    assert est2.length_m[0] == pytest.approx(0.6)
    assert est2.coverage[0] == pytest.approx(1.0)
    # a step detected as one long step spanning two: half its length falls into each half
    est3 = prorated_stride_lengths([0.0], [1.0], [1.2], [0.0, 0.5], [0.5, 1.0])
    np.testing.assert_allclose(est3.length_m, [0.6, 0.6])


def test_prorated_no_steps_and_errors() -> None:
    est = prorated_stride_lengths([], [], [], [0.0], [1.0])
    assert est.length_m[0] == 0.0 and est.coverage[0] == 0.0
    with pytest.raises(InputError):
        prorated_stride_lengths([0.0, 1.0], [0.5, 0.9], [1.0, 1.0], [0.0], [1.0])
    with pytest.raises(InputError):
        prorated_stride_lengths([1.0, 0.0], [1.5, 0.5], [1.0, 1.0], [0.0], [1.0])
    with pytest.raises(InputError):
        prorated_stride_lengths([0.0], [0.5], [1.0], [1.0], [1.0])
    with pytest.raises(InputError):
        prorated_stride_lengths([0.0], [0.5], [np.nan], [0.0], [1.0])
    with pytest.raises(InputError):
        prorated_stride_lengths([0.0], [0.5], [1.0, 2.0], [0.0], [1.0])


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 10_000), n_steps=st.integers(0, 25), n_strides=st.integers(1, 10))
def test_prorated_matches_slow_reference(seed: int, n_steps: int, n_strides: int) -> None:
    rng = np.random.default_rng(seed)
    a = np.sort(rng.uniform(0.0, 10.0, n_steps))
    b = a + rng.uniform(0.0, 1.5, n_steps)
    ln = rng.uniform(0.0, 1.0, n_steps)
    s0 = rng.uniform(-1.0, 11.0, n_strides)
    s1 = s0 + rng.uniform(0.05, 2.0, n_strides)
    est = prorated_stride_lengths(a, b, ln, s0, s1)
    ref_len, ref_cov = slow_prorated(a, b, ln, s0, s1)
    np.testing.assert_allclose(est.length_m, ref_len, atol=1e-9)
    np.testing.assert_allclose(est.coverage, ref_cov, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_prorated_conserves_length_over_tiling_strides(seed: int) -> None:
    # contiguous steps and contiguous strides over the same span: nothing is lost or doubled
    rng = np.random.default_rng(seed)
    edges = np.cumsum(np.concatenate([[0.0], rng.uniform(0.3, 0.8, 12)]))
    ln = rng.uniform(0.2, 0.9, 12)
    cuts = np.sort(rng.uniform(edges[0], edges[-1], 4))
    s = np.concatenate([[edges[0]], cuts, [edges[-1]]])
    s = s[np.concatenate([[True], np.diff(s) > 1e-6])]
    est = prorated_stride_lengths(edges[:-1], edges[1:], ln, s[:-1], s[1:])
    assert est.length_m.sum() == pytest.approx(ln.sum(), rel=1e-9)
    assert est.coverage.sum() == pytest.approx(12.0, rel=1e-9)


def test_chord_factor_values() -> None:
    np.testing.assert_allclose(chord_factor([0.0, np.pi / 2, np.pi, -np.pi, 2 * np.pi, 9.0]),
                               [1.0, 2 * np.sqrt(2) / np.pi, 2 / np.pi, 2 / np.pi, 0.0, 0.0],
                               atol=1e-12)
    # geometric check: chord / arc of a sampled circular arc
    for theta in (0.3, 1.2, 2.5):
        phi = np.linspace(0.0, theta, 2001)
        x, y = np.sin(phi), 1 - np.cos(phi)  # unit radius arc from the origin
        arc = float(np.sum(np.hypot(np.diff(x), np.diff(y))))
        assert chord_factor(theta) == pytest.approx(np.hypot(x[-1], y[-1]) / arc, rel=1e-6)
    with pytest.raises(InputError):
        chord_factor(np.nan)


@settings(max_examples=100, deadline=None)
@given(a=st.floats(0.0, 2 * np.pi), b=st.floats(0.0, 2 * np.pi))
def test_chord_factor_monotone_and_bounded(a: float, b: float) -> None:
    fa, fb = float(chord_factor(a)), float(chord_factor(b))
    assert 0.0 <= fa <= 1.0
    if a < b:
        assert fa >= fb - 1e-12


def test_rotation_over_matches_yaw_change() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    yaw = 0.4 * t + 0.2 * np.sin(t)
    q = quat_from_euler(np.zeros_like(t), np.full_like(t, 0.2), yaw)
    w = TurnDetector().vertical_rate(t, q)
    rot = rotation_over(t, w, [1.0, 2.5], [3.0, 9.0])
    np.testing.assert_allclose(rot, [yaw[300] - yaw[100], yaw[900] - yaw[250]], atol=1e-3)
    with pytest.raises(InputError):
        rotation_over(t[::-1], w, [1.0], [2.0])
    with pytest.raises(InputError):
        rotation_over(t, w[:-1], [1.0], [2.0])


def test_fit_and_transfer_scale() -> None:
    u = np.array([0.5, 0.6, 0.7])
    assert fit_scale(u, 1.2 * u) == pytest.approx(1.2)
    # least squares: sum(u d) / sum(u^2)
    d = np.array([0.6, 0.8, 0.7])
    assert fit_scale(u, d) == pytest.approx(float(u @ d / (u @ u)))
    with pytest.raises(InputError):
        fit_scale([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InputError):
        fit_scale([1.0], [1.0, 2.0])
    assert transfer_scale(1.2, [(1.0, 0.8), (2.0, 1.8)]) == pytest.approx(1.2 * 0.85)
    with pytest.raises(InputError):
        transfer_scale(1.2, [])
    with pytest.raises(InputError):
        transfer_scale(0.0, [(1.0, 0.8)])
    with pytest.raises(InputError):
        transfer_scale(1.0, [(1.0, -0.8)])
