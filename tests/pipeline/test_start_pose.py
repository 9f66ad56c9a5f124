"""The start pose's time: attitude and gait run from the first sample, position from the pose."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Session
from hrtls.evaluate.metrics import position_errors
from hrtls.pipeline import Tracker, preset
from hrtls.sim.scenarios import SimulationResult


def _posed(sim: SimulationResult, t_pose: float, **parts: object) -> tuple[Session, np.ndarray]:
    s = sim.session
    tr = s.truth
    assert tr is not None and tr.heading_rad is not None and s.meta.start_pose is not None
    i = int(np.searchsorted(tr.t, t_pose))
    pose = s.meta.start_pose.model_copy(update={
        "t": float(tr.t[i]), "x": float(tr.xyz[i, 0]), "y": float(tr.xyz[i, 1]),
        "z": float(tr.xyz[i, 2]), "heading": float(tr.heading_rad[i])})
    meta = s.meta.model_copy(update={"start_pose": pose})
    return s.with_parts(meta=meta, **parts), tr.xyz[i]


def test_position_starts_at_pose_time(office: SimulationResult) -> None:
    s, xyz = _posed(office, 40.0, fixes=None, rss=None, tags=None, ranges=None)
    res = Tracker(preset("default")).run(s)
    traj = res.trajectory
    assert traj.t[0] == pytest.approx(40.0, abs=0.02)
    np.testing.assert_allclose(traj.xyz[0], xyz, atol=1e-9)
    assert any("start pose holds at t = 40" in n and "steps" in n for n in res.report["notes"])
    # every step of the recording is detected (gait ran from the first sample) ...
    assert float(res.steps.t_end[0]) < 10.0
    # ... but the track starts at the pose and dead-reckons well from there
    t, err = position_errors(traj, s.truth)  # every truth sample; before the pose: held
    after = (t >= 40.0) & (t < 55.0)
    assert float(np.max(err[after])) < 1.5


def test_observations_before_pose_ignored(office: SimulationResult) -> None:
    s, _ = _posed(office, 30.0)
    res = Tracker(preset("default")).run(s)
    assert res.trajectory.t[0] == pytest.approx(30.0, abs=0.02)
    assert all(d.t >= 30.0 - 0.02 for d in res.diagnostics)
    note = next(n for n in res.report["notes"] if "start pose holds" in n)
    assert "rss" in note or "fixes" in note or "tags" in note


def test_pose_time_before_recording_is_start(office: SimulationResult) -> None:
    s, _ = _posed(office, 0.0)
    pose = s.meta.start_pose
    assert pose is not None
    s = s.with_parts(meta=s.meta.model_copy(update={
        "start_pose": pose.model_copy(update={"t": -5.0})}))
    res = Tracker(preset("default")).run(s)
    assert res.trajectory.t[0] == pytest.approx(s.time_span()[0])
    assert not any("start pose holds" in n for n in res.report["notes"])
