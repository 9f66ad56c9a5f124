"""Stops of the scenario simulator: a full last step, then an uncounted closing movement."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hrtls.sim.gait_model as gait_model
import hrtls.sim.stop_model as stop_model
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.walk_steps import WalkStepParams
from hrtls.sim.gait_model import GaitParams, simulate_gait
from hrtls.sim.imu_model import body_kinematics, ideal_imu
from hrtls.sim.motion_truth import Waypoint, simulate_motion
from hrtls.sim.stop_model import (
    CLOSING_AMPLITUDE_RANGE,
    LAST_STEP_AMPLITUDE_RANGE,
    LAST_STEP_CYCLE_RANGE,
    cycle_acceleration,
    cycle_displacement,
)


def _walk_stop_walk():
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=12.0, y=0.0, stop_s=5.0, corner_radius_m=0.0),
           Waypoint(x=12.0, y=9.0)]
    return simulate_motion(wps, rate_hz=100.0, end_pause_s=5.0)


def _runs(steps):
    new_run = np.concatenate([[True], np.abs(steps.t_start[1:] - steps.t_end[:-1]) > 1e-9])
    first = np.flatnonzero(new_run)
    return first, np.append(first[1:] - 1, len(steps) - 1)


def test_cycle_hand_values():
    # u = 0: displacement -T^2 (f(0) - f(1)), f(0) = 1/8/pi^2 + 1/4/pi^2 + 1/36/pi^2,
    # f(1) = 1/8/pi^2 - 1/4/pi^2 - 1/36/pi^2, so the difference is (1/2 + 1/18) / pi^2
    np.testing.assert_allclose(cycle_displacement(np.array([0.0]), 2.0),
                               [-4.0 * (0.5 + 1.0 / 18.0) / np.pi ** 2])
    np.testing.assert_allclose(cycle_acceleration(np.array([0.0, 0.5, 1.0, 1.5])),
                               [1.0, -0.5, 0.0, 0.0], atol=1e-15)


@settings(max_examples=30, deadline=None)
@given(period=st.floats(0.3, 1.5))
def test_cycle_displacement_integrates_to_the_acceleration(period):
    dt = 1e-3
    t = np.arange(-2.0 * period, 2.0 * period, dt)
    x = cycle_displacement(t / period, period)
    acc = np.gradient(np.gradient(x, dt), dt)
    np.testing.assert_allclose(acc[5:-5], cycle_acceleration(t / period)[5:-5], atol=2e-4)
    outside = np.abs(t) >= period
    assert np.all(x[outside] == 0.0)
    # no net velocity or displacement: the pose is unchanged after the cycle
    assert abs(np.gradient(x, dt)[np.searchsorted(t, period) - 1]) < 1e-3


def test_stops_only_change_the_vertical_after_each_last_step(monkeypatch):
    motion = _walk_stop_walk()
    with_stops = simulate_gait(motion, GaitParams(), np.random.default_rng(3))
    monkeypatch.setattr(gait_model, "stop_pulses", lambda t, *a: np.zeros_like(t))
    plain = simulate_gait(motion, GaitParams(), np.random.default_rng(3))
    np.testing.assert_array_equal(with_stops.phase, plain.phase)
    np.testing.assert_array_equal(with_stops.steps.t_end, plain.steps.t_end)
    np.testing.assert_array_equal(with_stops.offset_body[:, :2], plain.offset_body[:, :2])
    np.testing.assert_array_equal(with_stops.euler_osc, plain.euler_osc)
    changed = np.flatnonzero(with_stops.offset_body[:, 2] != plain.offset_body[:, 2])
    _, last = _runs(plain.steps)
    t_last = plain.steps.t_end[last]
    assert changed.size > 0
    near = np.any(np.abs(motion.t[changed][:, None] - (t_last[None, :] + 0.8)) < 2.5, axis=1)
    assert np.all(near)
    # every run ends at rest: both stops got a last step and a closing movement
    for tl in t_last:
        assert np.any(np.abs(motion.t[changed] - tl) < 0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_last_step_detected_and_closing_movement_not_counted(seed, monkeypatch):
    # the middle of the ranges (module notes)
    monkeypatch.setattr(stop_model, "LAST_STEP_CYCLE_RANGE", (1.0, 1.0))
    monkeypatch.setattr(stop_model, "CLOSING_AMPLITUDE_RANGE", (0.38, 0.38))
    motion = _walk_stop_walk()
    gait = simulate_gait(motion, GaitParams().drawn(np.random.default_rng(seed)),
                         np.random.default_rng(seed))
    imu = ideal_imu(body_kinematics(motion, gait))
    ga = GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns", window_features=False,
                      walk_steps=WalkStepParams())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        te = ga.process(imu.t, imu.specific_force).steps.t_end
    _, last = _runs(gait.steps)
    for tl in gait.steps.t_end[last]:
        assert np.any(np.abs(te - tl) < 0.3), "the last true step is detected"
        assert not np.any((te > tl + 0.3) & (te < tl + 3.0)), "the closing movement is no step"


def _end_ratios(te, peak, t_last):
    """Tracker's measure of the last step and the next detected step (closing), or None."""
    k = int(np.argmin(np.abs(te - t_last)))
    if k < 5 or abs(te[k] - t_last) > 0.2:
        return None
    level = np.median(peak[k - 4:k])
    close = peak[k + 1] / level if k + 1 < te.size and te[k + 1] - te[k] <= 1.5 else np.nan
    return peak[k] / level, close


def test_scenario_stops_in_the_trackers_measure_match_the_real_ones():
    # colombo_natural, development seeds 0-2; real HA/001 walk ends (module notes): last step
    # 0.70-1.08 of the level (median 0.85), closing movement 0.28-0.49
    from hrtls.sim.scenarios import run_scenario

    last, close = [], []
    for seed in range(3):
        r = run_scenario("colombo_natural", seed)
        acc = r.session.imu.accel
        ga = GaitAnalyzer(rate_hz=acc.rate_hz, heading="yaw", step_yaw="turns",
                          window_features=False, walk_steps=WalkStepParams(closing_ratio=0.0))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            st = ga.process(acc.t, acc.values).steps
        first, end = _runs(r.true_steps)
        for a, b in zip(first, end, strict=True):
            if b - a >= 4:
                got = _end_ratios(st.t_end, st.acc_max, r.true_steps.t_end[b])
                assert got is not None, "the last true step is detected"
                last.append(got[0])
                close.append(got[1])
    assert len(last) >= 15
    assert 0.75 <= np.median(last) <= 0.95
    assert np.mean(np.array(last) < WalkStepParams().closing_ratio) <= 0.1
    assert 0.28 <= np.nanmedian(close) <= 0.49


def test_the_generators_ranges():
    assert LAST_STEP_AMPLITUDE_RANGE == (0.6, 1.0)
    assert LAST_STEP_CYCLE_RANGE == (0.8, 1.2)
    assert CLOSING_AMPLITUDE_RANGE == (0.28, 0.49)
