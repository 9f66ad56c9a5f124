"""Evaluation harness against hand-computed numbers."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Checkpoints, GroundTruth, StepEvents, Trajectory
from hrtls.errors import InputError
from hrtls.evaluate.metrics import (
    activity_confusion,
    axis_errors,
    checkpoint_errors,
    compare_steps,
    cumulative_distance,
    error_cdf,
    error_stats,
    heading_errors,
    hold_previous,
    integral_mean_error,
    match_events,
    moving_speed_rmse,
    position_errors,
    position_errors_2d_3d,
    velocity_rmse,
)
from hrtls.evaluate.plots import plot_cdf, plot_error_over_time, plot_trajectory
from hrtls.evaluate.report import EvaluationInputs, build_report


def test_error_stats_hand_computed():
    s = error_stats([3.0, 4.0])
    assert s.n == 2
    assert s.mean == pytest.approx(3.5)
    assert s.rmse == pytest.approx(np.sqrt(12.5))
    assert s.median == pytest.approx(3.5)
    assert s.p75 == pytest.approx(3.75)
    assert s.p90 == pytest.approx(3.9)
    assert s.p95 == pytest.approx(3.95)
    assert s.max == 4.0
    e = error_stats([])
    assert e.n == 0 and np.isnan(e.mean)
    with pytest.raises(InputError):
        error_stats([1.0, np.nan])


def test_error_cdf():
    x, p = error_cdf([2.0, 1.0, 3.0])
    np.testing.assert_allclose(x, [1, 2, 3])
    np.testing.assert_allclose(p, [1 / 3, 2 / 3, 1])


def _line_truth(n: int = 101) -> GroundTruth:
    t = np.linspace(0.0, 10.0, n)
    return GroundTruth(t, np.column_stack([t, np.zeros(n), np.zeros(n)]), np.zeros(n))


def test_position_errors_constant_offset():
    truth = _line_truth()
    est = Trajectory.build(t=truth.t, xyz=truth.xyz + np.array([3.0, 4.0, 12.0]))
    _, e = position_errors(est, truth)
    np.testing.assert_allclose(e, 5.0)
    _, e3 = position_errors(est, truth, horizontal=False)
    np.testing.assert_allclose(e3, 13.0)


def test_position_errors_hold_the_ends_of_a_short_estimate():
    truth = _line_truth()  # x = t on [0, 10]
    est = Trajectory.build(t=[2.0, 4.0], xyz=[[2.0, 1.0, 0.0], [4.0, 1.0, 0.0]])
    t, e = position_errors(est, truth)
    np.testing.assert_array_equal(t, truth.t)  # no truth sample dropped
    inside = (t >= 2.0) & (t <= 4.0)
    np.testing.assert_allclose(e[inside], 1.0)
    # before the start the first estimate (2, 1) is held, after the end the last (4, 1)
    np.testing.assert_allclose(e[t < 2.0], np.hypot(2.0 - t[t < 2.0], 1.0))
    np.testing.assert_allclose(e[t > 4.0], np.hypot(t[t > 4.0] - 4.0, 1.0))


def test_track_that_stops_early_scores_worse_than_one_that_continues():
    truth = _line_truth()
    full = Trajectory.build(t=truth.t, xyz=truth.xyz + np.array([0.5, 0.0, 0.0]))
    early = Trajectory.build(t=truth.t[:30], xyz=full.xyz[:30])
    assert position_errors(early, truth)[1].mean() > position_errors(full, truth)[1].mean()
    cps = Checkpoints(np.array([1.0, 9.0]), np.array([[1.0, 0.0, 0.0], [9.0, 0.0, 0.0]]),
                      np.array(["a", "b"]))
    _, e_c, lab = checkpoint_errors(early, cps)
    assert list(lab) == ["a", "b"]  # the checkpoint after the end is scored, not dropped
    assert e_c[1] > 5.0


def test_axis_errors_hand_computed():
    truth = _line_truth()
    est = Trajectory.build(t=truth.t, xyz=truth.xyz + np.array([-0.3, 0.4, 2.0]))
    np.testing.assert_allclose(axis_errors(est, truth), np.broadcast_to([0.3, 0.4],
                                                                         (len(truth.t), 2)))


def test_moving_speed_rmse_of_a_constant_speed_error():
    t = np.linspace(0.0, 20.0, 2001)
    truth = GroundTruth(t, np.column_stack([t, np.zeros_like(t), np.zeros_like(t)]),
                        np.zeros_like(t))
    est = Trajectory.build(t=t, xyz=np.column_stack([1.2 * t, np.zeros_like(t),
                                                     np.zeros_like(t)]))
    assert moving_speed_rmse(est, truth, moving_m_s=0.2) == pytest.approx(0.2, abs=1e-6)
    assert math.isnan(moving_speed_rmse(est, truth, moving_m_s=5.0))


def test_checkpoint_errors():
    est = Trajectory.build(t=[0.0, 10.0], xyz=[[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    cps = Checkpoints(np.array([5.0, 10.0]), np.array([[5.0, 2.0, 0.0], [10.0, 0.0, 0.0]]),
                      np.array(["a", "b"]))
    _, e, lab = checkpoint_errors(est, cps)
    np.testing.assert_allclose(e, [2.0, 0.0])
    assert lab.tolist() == ["a", "b"]


def test_integral_mean_error_hand_computed():
    # errors 0, 2, 2 m at 0, 10, 20 m: integral 10 + 20 = 30 m^2 over 20 m -> 1.5 m, 7.5 %
    mean, frac = integral_mean_error([0.0, 10.0, 20.0], [0.0, 2.0, 2.0], 20.0)
    assert mean == pytest.approx(1.5)
    assert frac == pytest.approx(0.075)
    with pytest.raises(InputError):
        integral_mean_error([0.0], [1.0], 10.0)
    with pytest.raises(InputError):
        integral_mean_error([0.0, 5.0], [0.0, 1.0], 0.0)


def test_cumulative_distance():
    np.testing.assert_allclose(cumulative_distance([[0, 0, 0], [3, 4, 9], [3, 8, 0]]),
                               [0, 5, 9])


def _steps(t_end, length):
    t_end = np.asarray(t_end, dtype=float)
    return StepEvents.build(t_start=t_end - 0.5, t_end=t_end, length_m=length)


def test_compare_steps_hand_computed():
    true = _steps(np.arange(1.0, 11.0), np.full(10, 0.7))
    est = _steps(np.arange(1.0, 10.0) + 0.1, np.full(9, 0.75))
    c = compare_steps(est, true)
    assert c.n_true == 10 and c.n_estimated == 9
    assert c.count_error == -1
    assert c.count_error_fraction == pytest.approx(-0.1)
    assert c.n_matched == 9
    assert c.step_length_bias_m == pytest.approx(0.05)
    assert c.step_length_rmse_m == pytest.approx(0.05)
    assert c.length_error_fraction == pytest.approx((9 * 0.75 - 7.0) / 7.0)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0, 100), max_size=30), st.lists(st.floats(0, 100), max_size=30),
       st.floats(0.01, 2.0))
def test_match_events_is_one_to_one(a, b, tol):
    a = np.sort(np.asarray(a))
    b = np.sort(np.asarray(b))
    ia, ib = match_events(a, b, tolerance_s=tol)
    assert len(set(ia.tolist())) == len(ia)
    assert len(set(ib.tolist())) == len(ib)
    if len(ia):
        assert np.all(np.abs(a[ia] - b[ib]) <= tol)


def test_heading_error_wraps():
    t = np.array([0.0, 1.0])
    truth = GroundTruth(t, np.zeros((2, 3)), np.array([-np.pi + 0.1, -np.pi + 0.1]))
    est = Trajectory.build(t=t, xyz=np.zeros((2, 3)), heading_rad=[np.pi - 0.1, np.pi - 0.1])
    _, e = heading_errors(est, truth)
    np.testing.assert_allclose(e, 0.2, atol=1e-12)


def test_velocity_rmse_constant_offset():
    truth = _line_truth(1001)
    est = Trajectory.build(t=truth.t, xyz=truth.xyz * [1.5, 1.0, 1.0])  # 1.5 m/s vs 1 m/s
    v, s = velocity_rmse(est, truth)
    assert v == pytest.approx(0.5, abs=1e-6)
    assert s == pytest.approx(0.5, abs=1e-6)


def test_activity_confusion_hand_computed():
    # truth: standing until 2 s, then walking; estimate samples at 0.5 .. 4.5 s
    tt = np.array([0.0, 2.0])
    tc = np.array([0, 1])
    et = np.array([0.5, 1.5, 2.5, 3.5, 4.5])
    ec = np.array([0, 1, 1, 1, 2])
    np.testing.assert_array_equal(hold_previous(tt, tc, et), [0, 0, 1, 1, 1])
    c = activity_confusion(tt, tc, et, ec)
    assert c.accuracy == pytest.approx(3 / 5)
    assert c.matrix[0, 0] == 1 and c.matrix[0, 1] == 1
    assert c.matrix[1, 1] == 2 and c.matrix[1, 2] == 1
    assert c.matrix.sum() == 5
    assert c.labels[:2] == ("standing", "walking")


def test_report_is_strict_json_with_expected_numbers(tmp_path):
    truth = _line_truth()
    est = Trajectory.build(t=truth.t, xyz=truth.xyz + np.array([0.0, 1.0, 0.0]),
                           heading_rad=np.full(len(truth), 0.1),
                           activity=np.ones(len(truth), int))
    cps = Checkpoints(np.array([5.0, 10.0]), np.array([[5.0, 0.0, 0.0], [10.0, 0.0, 0.0]]),
                      np.array(["1", "2"]))
    report = build_report(EvaluationInputs(
        estimate=est, truth=truth, checkpoints=cps,
        estimated_steps=_steps([1.0, 2.0], [0.7, 0.7]), true_steps=_steps([1.0, 2.0],
                                                                         [0.7, 0.8]),
        true_activity=(np.array([0.0]), np.array([1])), reference={"paper": "x"}))
    text = json.dumps(report, allow_nan=False)
    assert "paper_reference" in text
    assert report["position"]["mean"] == pytest.approx(1.0)
    assert report["position"]["final_fraction_of_distance"] == pytest.approx(0.1)
    assert report["heading"]["max"] == pytest.approx(0.1)
    # checkpoints at 5 m and 10 m with 1 m error, start known: (0.5*5 + 5) / 10 / 10
    assert report["checkpoints"]["integral_mean_error_m"] == pytest.approx(0.75)
    assert report["checkpoints"]["integral_mean_error_fraction"] == pytest.approx(0.075)
    assert report["steps"]["length_error_fraction"] == pytest.approx(-0.1 / 1.5)
    assert report["activity"]["accuracy"] == pytest.approx(1.0)


def test_plots_write_png(tmp_path):
    truth = _line_truth()
    est = Trajectory.build(t=truth.t, xyz=truth.xyz + np.array([0.0, 0.5, 0.0]))
    t, e = position_errors(est, truth)
    for path in (plot_trajectory(tmp_path / "a.png", est, truth),
                 plot_error_over_time(tmp_path / "b.png", t, e),
                 plot_cdf(tmp_path / "c.png", {"x": e})):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.floats(0.0, 50.0), st.sampled_from([0.0, 1.0, math.nan])),
                max_size=300))
def test_report_cdf_points_are_those_of_the_sorted_errors(errors):
    """The partial sort gives the points of the full CDF (ties and NaN, last, included)."""
    from hrtls.evaluate.report import _cdf_points

    e = np.array(errors, dtype=np.float64)
    x, p = error_cdf(e)
    idx = np.unique(np.linspace(0, e.size - 1, min(50, e.size)).round().astype(int))
    got = _cdf_points(e)
    assert np.array_equal(np.array(got["error_m"]), x[idx], equal_nan=True)
    assert got["fraction"] == p[idx].tolist()


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 200), st.integers(0, 2**16))
def test_errors_2d_3d_are_the_norms_of_the_differences(n, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    est = Trajectory.build(t=t, xyz=rng.normal(0, 30, (n, 3)))
    truth = GroundTruth(t + 0.05, rng.normal(0, 30, (n, 3)), None)
    h, d3 = position_errors_2d_3d(est, truth)
    d = est.position_at(truth.t) - truth.xyz
    assert np.array_equal(h, np.sqrt(np.sum(d[:, :2] * d[:, :2], axis=1)))
    assert np.array_equal(d3, np.sqrt(np.sum(d * d, axis=1)))
