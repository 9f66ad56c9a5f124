from __future__ import annotations

import json

import numpy as np
import pytest

from hrtls.data.observations import PositionFixes
from hrtls.fusion.fixes import FixCorrector, FixParams, FixSchedule, run_velocity_with_fixes
from hrtls.fusion.gating import is_spd, summarize
from hrtls.fusion.state import FilterState
from hrtls.fusion.velocity_prediction import VelocityPredictionParams, VelocityPredictor
from hrtls.fusion.yaw_stretch import YawStretchParams


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


def circle_scenario(bias: float = 0.15, seed: int = 0) -> dict[str, object]:
    fs, duration, r, v = 100.0, 120.0, 3.0, 1.0
    rng = np.random.default_rng(seed)
    t = np.arange(1, int(duration * fs) + 1) / fs
    w = v / r
    truth = np.column_stack([r * np.sin(w * t), r - r * np.cos(w * t)])
    yaw = w * t + bias + rng.normal(0, 0.02, t.size)
    speed = v + rng.normal(0, 0.05, t.size)
    tf = np.arange(0.1, duration, 0.1)
    fx = np.column_stack([r * np.sin(w * tf), r - r * np.cos(w * tf), 0 * tf])
    fx[:, :2] += rng.normal(0, 0.05, (tf.size, 2))
    return {"t": t, "truth": truth, "yaw": yaw, "speed": speed,
                "fixes": PositionFixes(tf, fx, np.full(tf.size, 0.05))}


def run(sc: dict[str, object], tp: float, **kw: object) -> tuple[float, float, object]:
    t = sc["t"]
    res = run_velocity_with_fixes(FilterState.initial(sigma_xy_m=0.3, sigma_heading_rad=0.02),
                                  t=t,  # type: ignore[arg-type]
                                  speed_m_s=sc["speed"], yaw_rad=sc["yaw"],  # type: ignore[arg-type]
                                  moving=np.ones(len(t), bool),  # type: ignore[arg-type]
                                  fixes=sc["fixes"],  # type: ignore[arg-type]
                                  corrector=FixCorrector(FixParams(period_s=tp, sigma_m=0.05)),
                                  **kw)  # type: ignore[arg-type]
    err = np.linalg.norm(res.xyz[:, :2] - sc["truth"], axis=1)  # type: ignore[operator]
    return float(np.sqrt(np.mean(err**2))), float(np.percentile(err, 97)), res


def test_colombo_loop_yaw_stretch_feedback_reduces_error() -> None:
    sc = circle_scenario()
    base_rmse, _, _base = run(sc, 10.0)
    fb_rmse, _, fb = run(sc, 10.0, stretch=YawStretchParams(), yaw_feedback_gain=1.0)
    assert fb_rmse < 0.7 * base_rmse
    assert fb.yaw_offset_rad == pytest.approx(-0.15, abs=0.06)    # learned the yaw bias
    assert len(fb.yaw_pseudo) >= 8
    assert all(p.var_yaw_rad2 > 0 for p in fb.yaw_pseudo)
    counts = summarize(fb.diagnostics)["fix"]
    assert counts["accepted"] >= 10
    assert is_spd(fb.state.P)


def test_colombo_loop_heading_state_mode_meets_50cm() -> None:
    sc = circle_scenario(seed=1)
    pred = VelocityPredictor(VelocityPredictionParams(heading_mode="state",
                                                      heading_rate_var_rad2_s=1e-3))
    _, p97, res = run(sc, 16.0, predictor=pred)
    assert p97 < 0.5
    assert "rejected" not in summarize(res.diagnostics)["fix"]


def test_loop_chunked_equals_batch() -> None:
    from hrtls.fusion.fixes import StretchMemory

    sc = circle_scenario()
    t = np.asarray(sc["t"])
    yaw = np.asarray(sc["yaw"])
    speed = np.asarray(sc["speed"])
    n = t.size
    common = {"fixes": sc["fixes"], "stretch": YawStretchParams(), "yaw_feedback_gain": 1.0,
              "corrector": FixCorrector(FixParams(period_s=4.0, sigma_m=0.05))}
    full = run_velocity_with_fixes(FilterState.initial(), t=t, yaw_rad=yaw, speed_m_s=speed,
                                   moving=np.ones(n, bool), **common)  # type: ignore[arg-type]
    k = 5003
    a = run_velocity_with_fixes(FilterState.initial(), t=t[:k], yaw_rad=yaw[:k],
                                speed_m_s=speed[:k], moving=np.ones(k, bool),
                                **common)  # type: ignore[arg-type]
    assert a.memory is not None
    mem = StretchMemory.from_dict(json.loads(json.dumps(a.memory.to_dict())))
    b = run_velocity_with_fixes(a.state, t=t[k:], yaw_rad=yaw[k:], speed_m_s=speed[k:],
                                moving=np.ones(n - k, bool), schedule=a.schedule,
                                yaw_offset_rad=a.yaw_offset_rad, memory=mem,
                                **common)  # type: ignore[arg-type]
    np.testing.assert_allclose(np.concatenate([a.xyz, b.xyz]), full.xyz, atol=1e-9)
    assert len(a.yaw_pseudo) + len(b.yaw_pseudo) == len(full.yaw_pseudo)
    assert b.yaw_offset_rad == pytest.approx(full.yaw_offset_rad)


def test_full_covariance_fix() -> None:
    s = FilterState.initial(sigma_xy_m=1.0)
    cov = np.array([[1.0, 0.0], [0.0, 1e6]])                  # y is not measured
    upd = FixCorrector(FixParams(period_s=None)).update(s, FixSchedule(), t=0.0,
                                                        xyz=[2.0, 50.0, 0.0], sigma_m=1.0,
                                                        cov_xy=cov)
    assert upd.state.x[0] == pytest.approx(1.0)
    assert abs(upd.state.x[1]) < 1e-3
