"""Walking and running steps with their own Weinberg K (calibrated at both paces)."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Activity, StepEvents
from hrtls.errors import InputError
from hrtls.gait.pll import StepDetection
from hrtls.gait.step_length_fit import CalibrationWalk
from hrtls.jobs.bench import fit_weinberg_running
from hrtls.pipeline import Tracker, preset
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
    tr = Tracker(preset("default"))
    meta = s.meta.model_copy(update={"user": s.meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45, "k_running": 0.36}})})
    tr._step_model(meta)
    assert tr.running_factor == pytest.approx(0.8)
    bad = meta.model_copy(update={"user": meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45, "k_running": 0.1}})})
    with pytest.raises(InputError, match="running step factor"):
        tr._step_model(bad)
    res = Tracker(preset("default")).run(s.with_parts(meta=meta))
    assert res.report["running_step_factor"] == pytest.approx(0.8)
    # the simulated office walk has no running: the track equals the plain profile's
    plain = meta.model_copy(update={"user": meta.user.model_copy(update={
        "step_model": {"kind": "weinberg", "k": 0.45}})})
    ref = Tracker(preset("default")).run(s.with_parts(meta=plain))
    steps: StepEvents = res.steps
    if not np.any(steps.activity == int(Activity.RUNNING)):
        np.testing.assert_allclose(res.trajectory.xyz, ref.trajectory.xyz, atol=1e-9)


def _started(sim: SimulationResult) -> Tracker:
    s = sim.session
    tr = Tracker(preset("default"))
    tr.start(s.meta, s.landmarks, has_imu=True, has_gyro=True, has_mag=True,
             has_orientation=False, rate_hz=100.0, t0=0.0)
    return tr


@pytest.mark.parametrize(("run_m", "walk_learns", "run_learns"),
                         [(0.0, True, False), (10.0, False, True), (5.0, True, True)])
def test_scale_learned_per_activity(office: SimulationResult, run_m: float, walk_learns: bool,
                                    run_learns: bool) -> None:
    tr = _started(office)
    tr._anchor_xy = np.zeros(2)
    tr._path_since_anchor = 10.0
    tr._run_since_anchor = run_m
    # dead reckoning says 10 m east, the correction says 11 m: steps were 10 % short
    tr._learn_scale(np.array([10.0, 0.0]), np.array([11.0, 0.0]))
    learned = pytest.approx(1.1**0.25)
    assert tr.step_scale == (learned if walk_learns else 1.0)
    assert tr.run_scale == (learned if run_learns else 1.0)
    assert tr._run_since_anchor == 0.0 and tr._path_since_anchor == 0.0
