"""GaitAnalyzer end to end on simulated walks: offline, chunked, degraded inputs."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

from hrtls.data import Activity
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.frames import wrap_angle
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.analyzer import GaitAnalyzer, GaitResult
from hrtls.gait.motion_detector import MotionParams
from hrtls.gait.pll import PllStepDetector, StepDetection
from hrtls.gait.step_length import WeinbergModel
from hrtls.gait.step_length_fit import CalibrationWalk, fit_weinberg
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.gait.velocity_automaton import VelocityAutomaton


def match_count(det: np.ndarray, ref: np.ndarray, tol: float = 0.2) -> int:
    return int(sum(np.any(np.abs(det - r) <= tol) for r in ref))


@pytest.fixture(scope="module")
def walk():
    rng = np.random.default_rng(11)
    return simulate([(0, 4), (1, 40), (0, 4), (3, 12), (4, 12), (0, 4)],
                    person=SimPerson.random(rng), q_bd=random_mounting(rng),
                    heading0_rad=0.7, turn_rate_rad_s=0.03, seed=11)


def calibrated_weinberg(walk) -> WeinbergModel:
    """Weinberg's K fitted on another walk of the same person (distance known, as in a survey)."""
    cal = simulate([(0, 3), (1, 30), (0, 3)], person=walk.person, q_bd=walk.q_bd, seed=12)
    steps = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=cal.q_bd,
                         activity=LdaModel.default()).process(cal.t, cal.acc_d, cal.q_nd).steps
    det = StepDetection(steps.t_start, steps.t_end, steps.frequency_hz, steps.acc_max,
                        steps.acc_min)
    return fit_weinberg([CalibrationWalk(det, float(np.sum(cal.step_length_m)))])


def test_offline_steps_heading_activity(walk) -> None:
    ga = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=walk.q_bd, activity=LdaModel.default(),
                      velocity=VelocityAutomaton(), step_model=calibrated_weinberg(walk))
    res = ga.process(walk.t, walk.acc_d, walk.q_nd)
    te = res.steps.t_end
    assert abs(len(te) - len(walk.step_t)) <= 0.03 * len(walk.step_t) + 2
    assert match_count(te, walk.step_t) >= 0.95 * len(walk.step_t)
    true_h = np.interp(te, walk.step_t, np.unwrap(walk.step_heading_rad))
    err = wrap_angle(res.steps.heading_rad - true_h)
    sel = np.isfinite(err) & (te > 6) & (te < 43)
    assert np.sqrt(np.mean(err[sel] ** 2)) < np.deg2rad(5.0)
    # per-sample activity covers every sample once, in order
    np.testing.assert_array_equal(res.activity_t, walk.t)
    # the default model mixes two simulators whose stairs differ: score stairs as one class
    stairs = (Activity.UPSTAIRS, Activity.DOWNSTAIRS)
    merge = np.vectorize(lambda c: 3 if c in stairs else c)
    assert np.mean(merge(res.activity) == merge(walk.activity)) > 0.8
    # stairs steps carry a height change of one stair
    up = res.steps.activity == Activity.UPSTAIRS
    assert np.all(res.steps.dz_m[up] > 0)
    # walking distance with K calibrated on another walk of the person is close to the truth
    walking = (te > 4.5) & (te < 44)
    true_len = np.sum(walk.step_length_m[(walk.step_t > 4.5) & (walk.step_t < 44)])
    assert abs(np.sum(res.steps.length_m[walking]) - true_len) < 0.1 * true_len
    assert res.velocity_m_s.shape == walk.t.shape
    assert np.all(np.isfinite(res.velocity_m_s))


def test_chunked_equals_offline(walk) -> None:
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "activity": LdaModel.default()}
    whole = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd)
    ga = GaitAnalyzer(**kw)
    parts = []
    bounds = [0, 137, 1500, 1501, 4000, 7777, len(walk.t)]
    for a, b in itertools.pairwise(bounds):
        parts.append(ga.update(walk.t[a:b], walk.acc_d[a:b], walk.q_nd[a:b]))
    parts.append(ga.flush())
    joined = GaitResult.concat(parts)
    np.testing.assert_allclose(joined.steps.t_end, whole.steps.t_end, atol=1e-9)
    np.testing.assert_allclose(joined.steps.heading_rad, whole.steps.heading_rad, atol=1e-9)
    np.testing.assert_array_equal(joined.steps.activity, whole.steps.activity)
    np.testing.assert_array_equal(joined.activity, whole.activity)
    np.testing.assert_allclose(joined.steps.length_m, whole.steps.length_m)


def test_accelerometer_only_and_pll(walk) -> None:
    with pytest.warns(DegradedInputWarning):
        res = GaitAnalyzer(rate_hz=100.0).process(walk.t, walk.acc_d)
    assert match_count(res.steps.t_end, walk.step_t) >= 0.9 * len(walk.step_t)
    assert res.heading_frame == "levelled"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        # Basso's 1.5 m/s^2 still threshold is above this person's walking spread
        pll = GaitAnalyzer(rate_hz=100.0, step_detector=PllStepDetector(),
                           motion=MotionParams(still_threshold_m_s2=0.6)).process(
            walk.t, walk.acc_d)
    walking = (walk.step_t > 8) & (walk.step_t < 44)
    te = pll.steps.t_end
    assert abs(np.sum((te > 8) & (te < 44)) - np.sum(walking)) <= 3


def test_placement_change_keeps_counting() -> None:
    rng = np.random.default_rng(5)
    p = SimPerson.random(rng)
    a = simulate([(1, 20)], person=p, q_bd=random_mounting(rng), seed=1)
    b = simulate([(1, 20)], person=p, q_bd=random_mounting(rng), seed=2)
    t = np.concatenate([a.t, b.t + a.t[-1] + 0.01])
    acc = np.concatenate([a.acc_d, b.acc_d])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        res = GaitAnalyzer(rate_hz=100.0).process(t, acc)
    te = res.steps.t_end
    gaps = np.diff(te[(te > 5) & (te < 35)])
    assert np.max(gaps) < 4 * (1 / p.walk_hz)  # at most a few steps lost


def test_input_errors(walk) -> None:
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0, heading="compass")  # type: ignore[arg-type]
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0, mounting_q_bd=np.array([2.0, 0, 0, 0]))
    ga = GaitAnalyzer(rate_hz=100.0)
    with pytest.raises(InputError):
        ga.update(walk.t[:10], walk.acc_d[:9])
    ga.update(walk.t[:10], walk.acc_d[:10], walk.q_nd[:10])
    with pytest.raises(InputError):
        ga.update(walk.t[:10], walk.acc_d[:10])  # time goes back


@pytest.mark.parametrize("step_yaw", ["endpoints", "mean"])
def test_motion_labels_do_not_need_features(walk, step_yaw: str) -> None:
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "heading": "yaw", "step_yaw": step_yaw}
    full = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd)
    lean = GaitAnalyzer(**kw, window_features=False).process(walk.t, walk.acc_d, walk.q_nd)
    np.testing.assert_array_equal(full.activity, lean.activity)
    np.testing.assert_array_equal(full.steps.t_end, lean.steps.t_end)
    np.testing.assert_array_equal(full.steps.heading_rad, lean.steps.heading_rad)
    np.testing.assert_array_equal(full.features.t_end, lean.features.t_end)
    assert np.all(np.isfinite(full.features.lda)) and np.all(np.isnan(lean.features.lda))


def test_step_yaw_mean_follows_a_turn_within_the_step(walk) -> None:
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "heading": "yaw"}
    ends = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd).steps
    mean = GaitAnalyzer(**kw, step_yaw="mean").process(walk.t, walk.acc_d, walk.q_nd).steps
    # the walk turns slowly (0.03 rad/s): both readings agree to well under a degree
    np.testing.assert_array_equal(ends.t_end, mean.t_end)
    d = wrap_angle(ends.heading_rad - mean.heading_rad)
    assert np.nanmax(np.abs(d)) < np.deg2rad(3.0)
    # no step turns by 20 deg: "turns" keeps every endpoint heading
    turns = GaitAnalyzer(**kw, step_yaw="turns").process(walk.t, walk.acc_d, walk.q_nd).steps
    np.testing.assert_array_equal(turns.heading_rad, ends.heading_rad)
    with pytest.raises(InputError, match="step_yaw"):
        GaitAnalyzer(**kw, step_yaw="middle")  # type: ignore[arg-type]
