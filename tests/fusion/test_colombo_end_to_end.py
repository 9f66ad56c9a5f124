"""Colombo's circle with camera fixes through the tracker: targets, speed metric, live = offline."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from hrtls.data import Trajectory
from hrtls.data.observations import GroundTruth
from hrtls.jobs.bench import (
    _track,
    calibrated_session,
    p97_axis,
    predicted_track,
    speed_rmse,
)
from hrtls.jobs.bench_cases import fixes_every
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.chunks import split_session
from hrtls.pipeline.diagnostics import DiagnosticsLog
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult, run_scenario


@pytest.fixture(scope="module")
def circle() -> SimulationResult:
    return run_scenario("colombo_circle", 0, tp_s=10.0)


def test_predicted_track_removes_the_fix_jumps() -> None:
    t = np.arange(0.0, 5.0, 1.0)
    xyz = np.column_stack([t, np.zeros(5), np.zeros(5)])
    xyz[2:, 0] += 0.5                      # a fix at t = 2 moved the track by +0.5 m east
    xyz[4:, 1] -= 0.2                      # another at t = 4, -0.2 m north
    res = TrackResult(Trajectory.build(t=t, xyz=xyz), None, None, DiagnosticsLog(),  # type: ignore[arg-type]
                      {"fix_jumps": [[2.0, 0.5, 0.0], [4.0, 0.0, -0.2]]})
    np.testing.assert_allclose(predicted_track(res).xyz[:, :2], np.column_stack([t, 0 * t]))
    res.report.pop("fix_jumps")
    assert predicted_track(res) is res.trajectory


def test_speed_rmse_scores_the_walk_only() -> None:
    """Standing before and after does not dilute the RMSE; a 10 % fast estimate scores 0.1."""
    t = np.arange(0.0, 40.0, 0.01)
    walking = (t >= 10.0) & (t <= 30.0)
    x_true = np.clip(t - 10.0, 0.0, 20.0)                       # 1 m/s from 10 s to 30 s
    truth = GroundTruth(t=t, xyz=np.column_stack([x_true, 0 * t, 0 * t]))
    est = Trajectory.build(t=t, xyz=np.column_stack([1.1 * x_true, 0 * t, 0 * t]))
    res = TrackResult(est, None, None, DiagnosticsLog(), {})  # type: ignore[arg-type]
    sim = SimpleNamespace(session=SimpleNamespace(truth=truth))
    assert walking.any()
    assert speed_rmse(res, sim) == pytest.approx(0.1, abs=0.01)  # type: ignore[arg-type]


def test_default_meets_the_targets_on_one_circle(circle: SimulationResult) -> None:
    """As the bench runs it: no truth in the session, the step model from the user's
    calibration course (the simulator's step law is not the estimator's)."""
    cfg = fixes_every(10.0)(preset("default"))
    cal = run_scenario("colombo_circle", 0, calibration=True, tp_s=10.0)
    blind = circle.session.with_parts(truth=None, checkpoints=None)
    res = _track(cfg, calibrated_session(cfg, blind, cal))
    accepted = [d for d in res.diagnostics if d.kind == "fix" and d.accepted]
    assert len(res.report["fix_jumps"]) == len(accepted) >= 2
    assert p97_axis(res, circle) < 0.5
    assert speed_rmse(res, circle) < 0.17


def test_step_model_stretching_gives_yaw_pseudo_measurements(circle: SimulationResult) -> None:
    tracker = Tracker(fixes_every(10.0)(preset("default")))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracker.run(circle.session)
    # a loop's chord over Tp used to look slower than min_speed_m_s and was dropped
    assert tracker.yaw_pseudo
    assert all(np.isfinite(p.var_yaw_rad2) and p.var_yaw_rad2 > 0 for p in tracker.yaw_pseudo)


@pytest.mark.parametrize("name", ["default", "colombo2014"])
def test_chunked_equals_offline_with_fixes(circle: SimulationResult, name: str) -> None:
    cfg = fixes_every(10.0)(preset(name))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        offline = Tracker(cfg).run(circle.session)
        s = circle.session
        live = Tracker(cfg)
        live.start_session(s)
        for part in split_session(s, 5.0):
            live.update(part)
        res = live.finish()
    a, b = offline.trajectory, res.trajectory
    assert len(a) == len(b)
    np.testing.assert_allclose(a.t, b.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(a.xyz, b.xyz, atol=1e-6, rtol=0)


def test_paper_preset_stretching_on_the_square() -> None:
    """colombo2014 (velocity model, eq. 24-28 fed back with gain 1) on the square: the
    stretching runs in the product path and yields usable yaw pseudo-measurements; on the
    circle the chords between 10 s fixes are mostly shorter than ``min_chord_m``."""
    sim = run_scenario("colombo_square", 0, tp_s=10.0)
    tracker = Tracker(fixes_every(10.0)(preset("colombo2014")))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracker.run(sim.session.with_parts(truth=None, checkpoints=None))
    assert tracker.yaw_pseudo
    for p in tracker.yaw_pseudo:
        assert np.isfinite(p.yaw_rad) and p.var_yaw_rad2 > 0
        assert abs(p.correction_rad) <= 0.5
