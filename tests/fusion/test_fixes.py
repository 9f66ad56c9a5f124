from __future__ import annotations

import json

import numpy as np
import pytest

from hrtls.fusion.fixes import FixCorrector, FixParams, FixSchedule
from hrtls.fusion.state import FilterState


def test_policy_eq_19() -> None:
    corr = FixCorrector(FixParams(period_s=10.0, slot_tolerance_s=0.5))
    sched = FixSchedule()
    assert corr.due(sched, 10.2, True) == (True, "")
    assert not corr.due(sched, 10.2, False)[0]
    assert not corr.due(sched, 10.7, True)[0]
    assert not corr.due(FixSchedule(1), 10.2, True)[0]
    assert corr.due(FixSchedule(1), 20.0, True)[0]
    every = FixCorrector(FixParams(period_s=None, require_motion=False))
    assert every.due(sched, 3.3, False)[0]
    assert FixSchedule.from_dict(json.loads(json.dumps(FixSchedule(3, 1).to_dict()))) == \
        FixSchedule(3, 1)


def test_update_hand_computed_and_skip() -> None:
    s = FilterState.initial(sigma_xy_m=1.0).evolve(t=10.0)
    corr = FixCorrector(FixParams(period_s=10.0))
    upd = corr.update(s, FixSchedule(), t=10.0, xyz=[2.0, -2.0, 5.0], sigma_m=1.0, moving=True)
    assert upd.diagnostics.accepted
    np.testing.assert_allclose(upd.state.x[:3], [1.0, -1.0, 0.0])        # z not measured
    np.testing.assert_allclose(upd.state.P[:2, :2], np.eye(2) * 0.5)
    assert upd.schedule.last_slot == 1
    still = corr.update(s, FixSchedule(), t=10.0, xyz=[2.0, -2.0, 0.0], sigma_m=1.0,
                        moving=False)                                   # eq. 23
    assert still.diagnostics.status == "skipped"
    np.testing.assert_array_equal(still.state.x, s.x)


def test_outlier_rejected_then_recovery() -> None:
    s = FilterState.initial(sigma_xy_m=0.1)
    corr = FixCorrector(FixParams(period_s=None, max_consecutive_rejections=2))
    sched = FixSchedule()
    far = [2.0 + 20 * 0.1, 0.0, 0.0]
    out = corr.update(s, sched, t=1.0, xyz=[20 * np.hypot(0.1, 0.1), 0, 0], sigma_m=0.1)
    assert out.diagnostics.status == "rejected"
    sched = out.schedule
    out = corr.update(s, sched, t=2.0, xyz=far, sigma_m=0.1)
    assert out.diagnostics.status == "rejected" and out.schedule.rejections == 2
    out = corr.update(s, out.schedule, t=3.0, xyz=far, sigma_m=0.1)
    assert out.diagnostics.accepted and "without gate" in out.diagnostics.reason


def test_full_covariance_fix() -> None:
    s = FilterState.initial(sigma_xy_m=1.0)
    cov = np.array([[1.0, 0.0], [0.0, 1e6]])                  # y is not measured
    upd = FixCorrector(FixParams(period_s=None)).update(s, FixSchedule(), t=0.0,
                                                        xyz=[2.0, 50.0, 0.0], sigma_m=1.0,
                                                        cov_xy=cov)
    assert upd.state.x[0] == pytest.approx(1.0)
    assert abs(upd.state.x[1]) < 1e-3
