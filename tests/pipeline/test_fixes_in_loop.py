"""Position fixes applied inside the compiled event loop give the results of the Python path.

The reference tracker queues every fix as a slow event, applied by
``observations.apply_fix`` (the path still used with the velocity-driven prediction or
ungated fixes); the default tracker makes them rows of the loop, which hands back to Python
only the fixes whose acceptance runs the yaw stretching and the recovery without gate. Both
must give the same trajectory, diagnostics, fix jumps, stretching yaws and step scales.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Session
from hrtls.fusion.fixes import partial_step
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.schedule import EventSchedule
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult, run_scenario


class PythonFixSchedule(EventSchedule):
    """Every fix through the heap and ``apply_fix`` (the Python reference path)."""

    fixes_in_loop = False


class PythonFixTracker(Tracker):
    """A tracker with the Python reference path for fixes."""

    schedule_class = PythonFixSchedule


def _with(cfg: TrackerConfig, section: str, **changes: object) -> TrackerConfig:
    return cfg.model_copy(update={section: getattr(cfg, section).model_copy(update=changes)})


def _run(tracker: Tracker, session: Session) -> TrackResult:
    return tracker.run(session)


def assert_same(fast: Tracker, a: TrackResult, ref: Tracker, b: TrackResult) -> None:
    ta, tb = a.trajectory, b.trajectory
    assert len(ta) == len(tb)
    np.testing.assert_allclose(ta.t, tb.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.xyz, tb.xyz, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.heading_rad, tb.heading_rad, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.cov_xy, tb.cov_xy, atol=1e-9, rtol=0)
    np.testing.assert_array_equal(ta.activity, tb.activity)
    assert a.report == b.report
    assert len(a.diagnostics) == len(b.diagnostics)
    for da, db in zip(a.diagnostics, b.diagnostics, strict=True):
        assert da.to_dict() == db.to_dict()
    np.testing.assert_allclose(np.array(fast.fix_jumps), np.array(ref.fix_jumps), atol=1e-9,
                               rtol=0)
    np.testing.assert_allclose(np.array([(p.t, p.yaw_rad) for p in fast.yaw_pseudo]),
                               np.array([(p.t, p.yaw_rad) for p in ref.yaw_pseudo]), atol=1e-9,
                               rtol=0)
    assert (fast.step_scale, fast.run_scale) == pytest.approx((ref.step_scale, ref.run_scale),
                                                              abs=1e-12)


@pytest.fixture(scope="module")
def office_long() -> SimulationResult:
    """Five minutes of the office walk (cameras, beacons, tags, range nodes)."""
    return run_scenario("office_random_walk", 5, duration_s=300.0)


CASES = {
    "default": {},
    # no soft corrections between fixes: the yaw stretching runs (fixes handed back to
    # Python) and the step scale learns from the fixes
    "fixes and tags": {"rss": {"mode": "off"}, "ranges": {"enabled": False}},
    "no stretching": {"rss": {"mode": "off"}, "ranges": {"enabled": False},
                      "fixes": {"yaw_stretch": False, "period_s": 3.0}},
    "no partial step": {"fixes": {"partial_step": False, "max_consecutive_rejections": 0}},
}


@pytest.mark.parametrize("case", list(CASES))
def test_fixes_in_loop_equal_python_path(office_long: SimulationResult, case: str) -> None:
    cfg = preset("default")
    for section, changes in CASES[case].items():
        cfg = _with(cfg, section, **changes)
    fast, ref = Tracker(cfg), PythonFixTracker(cfg)
    a, b = _run(fast, office_long.session), _run(ref, office_long.session)
    assert ("fix", "") in fast.schedule.labels      # the fixes were rows of the loop
    assert ("fix", "") not in ref.schedule.labels
    assert a.report["corrections"]["fix"]["accepted"] > 10
    if case == "fixes and tags":
        assert ref.yaw_pseudo      # the Python part of the loop's fixes ran
    assert_same(fast, a, ref, b)


def test_fixes_in_loop_without_imu_equal_python_path(office_long: SimulationResult) -> None:
    """Without an IMU the loop grows the covariance by the random walk before each fix."""
    session = office_long.session.with_parts(imu=None)
    cfg = preset("default")
    fast, ref = Tracker(cfg), PythonFixTracker(cfg)
    a, b = _run(fast, session), _run(ref, session)
    assert ("fix", "") in fast.schedule.labels
    assert a.report["corrections"]["fix"]["accepted"] > 10
    assert_same(fast, a, ref, b)


def test_fixes_in_loop_learn_the_step_scale(office_long: SimulationResult) -> None:
    """The case without stretching changes the step scale in the loop (the test can fail)."""
    cfg = preset("default")
    for section, changes in CASES["no stretching"].items():
        cfg = _with(cfg, section, **changes)
    tr = Tracker(cfg)
    tr.run(office_long.session)
    assert tr.step_scale != 1.0


@settings(max_examples=200, deadline=None)
@given(t=st.floats(-1.0, 3.0), t_start=st.floats(0.0, 1.0), dur=st.floats(0.0, 1.5),
       length=st.floats(0.0, 2.0), heading=st.floats(-math.pi, math.pi))
def test_partial_step_is_linear_in_time_within_the_step(t: float, t_start: float, dur: float,
                                                        length: float, heading: float) -> None:
    d = partial_step(t, t_start=t_start, t_end=t_start + dur, length_m=length,
                     heading_rad=heading)
    inside = dur > 0.0 and t_start <= t <= t_start + dur
    if not inside:
        assert d.tolist() == [0.0, 0.0]
        return
    frac = (t - t_start) / dur
    assert math.hypot(*d) == pytest.approx(frac * length, abs=1e-12)
    assert math.hypot(*d) <= length + 1e-12
