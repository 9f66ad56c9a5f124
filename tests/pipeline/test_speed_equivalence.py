"""The compiled paths added for speed give the results of the Python paths they replace.

RSS scans (``[rss] mode = "kalman" | "wls"``) used to be queued one by one and applied by
``Tracker._apply_rss`` (Python WLS + ``kalman_update``); they are now rows of the compiled
event loop. The reference tracker below queues them the old way (the Python path is still the
one used with the velocity-driven prediction); both must give the same trajectory and
diagnostics.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.fusion.rss_scans import group_scans
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.schedule import RSS, EventSchedule
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult


class PythonScanSchedule(EventSchedule):
    """Scans through the heap and ``apply_rss`` (the Python reference path)."""

    def flush_scans(self, t_seen: float) -> None:
        readings = self._take_closed_scans(t_seen)
        if readings is None:
            return
        for scan in group_scans(readings, self.landmarks, window_s=self.config.rss.window_s,
                                sensitivity_dbm=self.config.rss.sensitivity_dbm,
                                t_origin=self.t0):
            self.push(scan.t, RSS, ("scan", scan))


class PythonScanTracker(Tracker):
    """A tracker with the Python reference path for scans."""

    schedule_class = PythonScanSchedule


def with_rss(cfg: TrackerConfig, **changes: object) -> TrackerConfig:
    return cfg.model_copy(update={"rss": cfg.rss.model_copy(update=changes)})


def assert_same(a: TrackResult, b: TrackResult) -> None:
    ta, tb = a.trajectory, b.trajectory
    assert len(ta) == len(tb)
    np.testing.assert_allclose(ta.t, tb.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.xyz, tb.xyz, atol=1e-7, rtol=0)
    np.testing.assert_allclose(ta.cov_xy, tb.cov_xy, atol=1e-7, rtol=0)
    np.testing.assert_array_equal(ta.activity, tb.activity)
    assert a.report["corrections"] == b.report["corrections"]
    assert len(a.diagnostics) == len(b.diagnostics)
    for da, db in zip(a.diagnostics, b.diagnostics, strict=True):
        assert (da.kind, da.status, da.dof, da.source, da.reason) == (
            db.kind, db.status, db.dof, db.source, db.reason)
        assert da.t == pytest.approx(db.t, abs=1e-9)
        if math.isfinite(da.nis) or math.isfinite(db.nis):
            assert da.nis == pytest.approx(db.nis, rel=1e-6, abs=1e-9)
        assert da.threshold == pytest.approx(db.threshold)
        np.testing.assert_allclose(np.asarray(da.innovation), np.asarray(db.innovation),
                                   rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(np.asarray(da.innovation_cov),
                                   np.asarray(db.innovation_cov), rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize(("mode", "wls_cov"), [("kalman", False), ("kalman", True),
                                               ("wls", False)])
def test_scans_in_kernel_equal_python_path(tarrio: SimulationResult, mode: str,
                                           wls_cov: bool) -> None:
    cfg = with_rss(preset("tarrio2011"), mode=mode, use_wls_covariance=wls_cov)
    fast = Tracker(cfg).run(tarrio.session)
    ref = PythonScanTracker(cfg).run(tarrio.session)
    assert fast.report["corrections"]["rss"]["accepted"] > 20
    assert_same(fast, ref)


def test_scans_with_every_correction_equal_python_path(office: SimulationResult) -> None:
    """Scans mixed with steps, fixes, tags and ranges (default preset, RSS in Kalman mode)."""
    cfg = with_rss(preset("default"), mode="kalman", use_wls_covariance=True)
    assert_same(Tracker(cfg).run(office.session), PythonScanTracker(cfg).run(office.session))


def test_scans_without_imu_equal_python_path(office: SimulationResult) -> None:
    s = office.session.with_parts(imu=None, orientation=None, pressure=None)
    for mode in ("kalman", "wls"):
        cfg = with_rss(preset("tarrio2011"), mode=mode)
        assert_same(Tracker(cfg).run(s), PythonScanTracker(cfg).run(s))


def test_scans_with_few_anchors_equal_python_path(office: SimulationResult) -> None:
    """A high sensitivity floor leaves scans with fewer than 3 anchors (skipped, with reason)."""
    cfg = with_rss(preset("tarrio2011"), sensitivity_dbm=-75.0)
    fast = Tracker(cfg).run(office.session)
    assert_same(fast, PythonScanTracker(cfg).run(office.session))
    assert any("(WLS needs 3)" in d.reason for d in fast.diagnostics)


def test_scan_store_trimmed_in_chunked_run(office: SimulationResult,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Live chunks with the scan store trimmed after every run = the offline run."""
    from hrtls.pipeline import schedule as schedule_module
    from hrtls.pipeline.chunks import split_session

    cfg = preset("tarrio2011")
    offline = Tracker(cfg).run(office.session)
    monkeypatch.setattr(schedule_module, "SCAN_ROWS_TRIM", 1)
    s = office.session
    tr = Tracker(cfg)
    tr.start_session(s)
    for part in split_session(s, 7.0):
        tr.update(part)
        assert len(tr.schedule.scan_rows) < 200        # trimmed: only the queued scans' anchors
    live = tr.finish()
    assert_same(offline, live)


def test_velocity_mode_scans_use_the_python_path(office: SimulationResult) -> None:
    """With the velocity-driven prediction, scans stay Python events (and still work)."""
    cfg = with_rss(preset("colombo2014"), mode="kalman")
    res = Tracker(cfg).run(office.session)
    rss = [d for d in res.diagnostics if d.kind == "rss"]
    assert len(rss) > 20 and all(d.dof in (0, 2) for d in rss)
    assert res.report["corrections"]["rss"].get("accepted", 0) > 0
