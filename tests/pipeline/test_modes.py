"""Any mix of inputs tracks and says what was degraded; seeded regressions on the papers' setups."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import ImuStream
from hrtls.evaluate.metrics import checkpoint_errors, position_errors
from hrtls.pipeline import Tracker, preset
from hrtls.sim.scenarios import SimulationResult


def test_imu_only(office: SimulationResult) -> None:
    s = office.session.with_parts(fixes=None, rss=None, tags=None, ranges=None)
    res = Tracker(preset("default")).run(s)
    assert len(res.steps) > 50
    assert not res.report["corrections"]
    assert any("dead reckoning" in n for n in res.report["notes"])


@pytest.mark.parametrize("keep", ["rss", "ranges", "tags"])
def test_infrastructure_only(office: SimulationResult, keep: str) -> None:
    parts = {k: None for k in ("imu", "orientation", "pressure", "fixes", "rss", "tags",
                               "ranges") if k != keep}
    s = office.session.with_parts(**parts)
    res = Tracker(preset("default")).run(s)
    assert any("no IMU" in n for n in res.report["notes"])
    assert len(res.steps) == 0
    assert np.all(np.isfinite(res.trajectory.xyz))
    assert sum(c.get("accepted", 0) for c in res.report["corrections"].values()) > 0
    if keep == "rss":
        assert res.report["corrections"]["rss"]["accepted"] > 100
        assert s.truth is not None
        err = position_errors(res.trajectory, s.truth)[1]
        assert float(np.median(err)) < 6.0


def test_accelerometer_only(office: SimulationResult) -> None:
    imu = office.session.imu
    assert imu is not None
    s = office.session.with_parts(imu=ImuStream(imu.accel, check_units=False))
    res = Tracker(preset("default")).run(s)
    assert len(res.steps) > 50
    assert any("no gyroscope and no magnetometer" in n for n in res.report["notes"])
    assert np.all(np.isfinite(res.trajectory.xyz))


def test_inderst_ring_regression(ring: SimulationResult) -> None:
    cps = ring.session.checkpoints
    assert cps is not None
    res = Tracker(preset("default")).run(ring.session)
    err = checkpoint_errors(res.trajectory, cps)[1]
    # measured 2.11 m (seed 0) when written; the thesis' all-tags figure is 2.62 m
    assert float(np.max(err)) < 3.0
    assert res.report["corrections"]["tag"]["accepted"] >= 20


def test_tarrio_circle_regression(tarrio: SimulationResult) -> None:
    truth = tarrio.session.truth
    assert truth is not None
    res = Tracker(preset("default")).run(tarrio.session)
    err = position_errors(res.trajectory, truth)[1]
    # measured p90 1.26 m (seed 0) when written; Tarrio's figure is 2.4 m, our target 1.8 m
    assert float(np.percentile(err, 90)) < 1.8
    kal = Tracker(preset("tarrio2011")).run(tarrio.session)
    # Tarrio's Kalman fusion as we run it, channel surveyed on the calibration course: p90
    # 2.43 m (seed 0; 1.40 m with the true channel in the session); the paper's figure is 2.4 m
    assert float(np.percentile(position_errors(kal.trajectory, truth)[1], 90)) < 2.6
