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


def test_unknown_start_is_the_anchors_centroid_with_their_spread() -> None:
    from hrtls.data.landmarks import Landmark
    from hrtls.pipeline import build
    from hrtls.pipeline.build import Notes

    lms = {k: Landmark(id=k, kind="anchor", position=p) for k, p in
           {"a": (0.0, 0.0, 1.0), "b": (6.0, 0.0, 1.0), "c": (0.0, 8.0, 1.0),
            "d": (6.0, 8.0, 1.0)}.items()}
    lms["tag"] = Landmark(id="tag", kind="rfid", position=(100.0, 100.0, 0.0))  # not RSS
    notes = Notes()
    pose = build.unknown_start(preset("default"), lms, notes)
    assert (pose.x, pose.y) == (3.0, 4.0)
    assert pose.sigma_xy_m == pytest.approx(5.0)          # every anchor 5 m from the centre
    assert pose.heading is None
    assert any("no start pose" in n for n in notes.items)
    off = preset("default").model_copy(update={
        "rss": preset("default").rss.model_copy(update={"mode": "off"})})
    assert build.unknown_start(off, lms, Notes()).sigma_xy_m == 0.5   # nothing places it
    # without an IMU the grid stage publishes the rows: the note says so, the prior is the same
    grid_notes = Notes()
    grid_pose = build.unknown_start(preset("default"), lms, grid_notes, has_imu=False)
    assert (grid_pose.x, grid_pose.y, grid_pose.sigma_xy_m) == (pose.x, pose.y, pose.sigma_xy_m)
    assert any("grid filter starts from the first scan" in n for n in grid_notes.items)
    assert not any("starting at the centroid" in n for n in grid_notes.items)
    assert any("starting at the centroid of 4 anchors" in n for n in notes.items)


@pytest.mark.realdata
def test_ble_track_without_start_pose_starts_among_the_anchors(shared_data) -> None:  # type: ignore[no-untyped-def]
    """Real BLE RSS (no IMU, no start pose): the track used to start at (0, 0) with 0.5 m
    while the walker was 19 m away (p75 11.3 m on straight_02)."""
    import warnings

    from hrtls.recordings import read_any

    path = shared_data / "ble_rssi" / "trk" / "straight_02_all_sensors.mbd"
    if not path.is_file():
        pytest.skip("ble_rssi not present")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = read_any(path, repair=True)
        res = Tracker(preset("default")).run(s)
    tr = res.trajectory
    assert tr.cov_xy is not None
    _, err = position_errors(tr, s.truth)
    notes = res.report["notes"]
    assert any("grid filter starts from the first scan" in n for n in notes)
    assert not any("starting at the centroid" in n for n in notes)
    # the first row is the first scan's estimate (grid filter), its spread covers the error
    assert err[0] < 3.0 * np.sqrt(np.trace(tr.cov_xy[0]) / 2.0)
    assert float(np.percentile(err, 75)) < 3.5
