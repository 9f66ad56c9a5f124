"""Walking and running steps with their own Weinberg K (calibrated at both paces)."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Activity, StepEvents
from hrtls.errors import InputError
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length_fit import CalibrationWalk, fit_weinberg_running
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.build import step_model
from hrtls.pipeline.step_scale import StepScaleLearner
from hrtls.sim.scenarios import SimulationResult


def _walk(n: int, span: float, dist: float) -> CalibrationWalk:
    t = np.arange(n) * 0.5
    det = StepDetection(t, t + 0.5, np.full(n, 2.0), np.full(n, span), np.zeros(n))
    return CalibrationWalk(det, dist)


def test_fit_weinberg_running_recovers_two_constants() -> None:
    # walk: span 16 -> q = 2; run: span 81 -> q = 3; K_walk 0.45, K_run 0.38
    walks, runs = [], []
    for n_walk, n_run in ((40, 0), (10, 30), (30, 10), (0, 40)):
        n = n_walk + n_run
        span = np.r_[np.full(n_walk, 16.0), np.full(n_run, 81.0)]
        dist = 0.45 * 2 * n_walk + 0.38 * 3 * n_run
        w = _walk(n, 1.0, dist)
        det = StepDetection(w.steps.t_start, w.steps.t_end, w.steps.frequency_hz, span,
                            np.zeros(n))
        walks.append(CalibrationWalk(det, dist))
        runs.append(np.r_[np.zeros(n_walk, bool), np.ones(n_run, bool)])
    k = fit_weinberg_running(walks, runs)
    assert k is not None
    assert k[0] == pytest.approx(0.45) and k[1] == pytest.approx(0.38)
    # walking only: no running constant
    assert fit_weinberg_running(walks[:1] * 3, [np.zeros(40, bool)] * 3) is None


def test_running_steps_scaled(office: SimulationResult) -> None:
    s = office.session.with_parts(fixes=None, rss=None, tags=None, ranges=None)
    cfg = preset("default")
    meta = s.meta.model_copy(update={"user": s.meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45, "k_running": 0.36}})})
    assert step_model(cfg.gait, meta)[1] == pytest.approx(0.8)
    bad = meta.model_copy(update={"user": meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45, "k_running": 0.1}})})
    with pytest.raises(InputError, match="running step factor"):
        step_model(cfg.gait, bad)
    res = Tracker(preset("default")).run(s.with_parts(meta=meta))
    assert res.report["running_step_factor"] == pytest.approx(0.8)
    # the simulated office walk has no running: the track equals the plain profile's
    plain = meta.model_copy(update={"user": meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45}})})
    ref = Tracker(preset("default")).run(s.with_parts(meta=plain))
    steps: StepEvents = res.steps
    if not np.any(steps.activity == int(Activity.RUNNING)):
        np.testing.assert_allclose(res.trajectory.xyz, ref.trajectory.xyz, atol=1e-9)


@pytest.mark.parametrize(("run_m", "walk_learns", "run_learns"),
                         [(0.0, True, False), (10.0, False, True), (5.0, True, True)])
def test_scale_learned_per_activity(run_m: float, walk_learns: bool, run_learns: bool) -> None:
    sc = StepScaleLearner()
    sc.anchor_xy = np.zeros(2)
    sc.walked(10.0, run_m)
    # dead reckoning says 10 m east, the correction says 11 m: steps were 10 % short
    sc.correct(np.array([10.0, 0.0]), np.array([11.0, 0.0]), learn=True)
    learned = pytest.approx(1.1**0.25)
    assert sc.step_scale == (learned if walk_learns else 1.0)
    assert sc.run_scale == (learned if run_learns else 1.0)
    assert sc.run_since_anchor == 0.0 and sc.path_since_anchor == 0.0
    np.testing.assert_array_equal(sc.anchor_xy, [11.0, 0.0])


def test_scale_not_learned_when_off_or_after_soft_corrections() -> None:
    for learn, soft in ((False, False), (True, True)):
        sc = StepScaleLearner()
        sc.anchor_xy = np.zeros(2)
        sc.walked(10.0)
        sc.soft_since_anchor = soft
        sc.correct(np.array([10.0, 0.0]), np.array([11.0, 0.0]), learn=learn)
        assert sc.step_scale == 1.0 and sc.run_scale == 1.0
