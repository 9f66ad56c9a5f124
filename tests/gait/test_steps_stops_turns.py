"""Steps at stops and turns (issue 19): weak steps on the walking rhythm are counted."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.peak_steps import PeakStepDetector, PeakStepParams
from hrtls.gait.synthetic import SimWalk, short_walk_u_turn, simulate
from hrtls.gait.walk_steps import WalkStepParams

from ._chunks import run_with_restarts

OLD_RULE = PeakStepParams(rhythm_relative_threshold=PeakStepParams().relative_threshold)
"""The detector before the rhythm rule: one relative threshold for every peak."""


def _lobes(t: np.ndarray, times: np.ndarray, amp: float) -> np.ndarray:
    """A positive lobe at each time followed 0.1 s later by a negative one (zero mean)."""
    x = np.zeros_like(t)
    for c in times:
        x += amp * (np.exp(-0.5 * ((t - c) / 0.04) ** 2)
                    - np.exp(-0.5 * ((t - c - 0.1) / 0.04) ** 2))
    return x


def test_weak_steps_on_the_rhythm_count_secondary_lobes_do_not() -> None:
    # nine steps of 4 m/s^2 every 0.5 s, a secondary lobe of 0.7 m/s^2 0.2 s after each (off
    # the rhythm), then two weak steps of 0.8 m/s^2 on the rhythm before standing. The 2 s
    # deviation is about 1.8 m/s^2: the old level 0.5 sigma = 0.9 drops the weak steps, the
    # rhythm level 0.4 sigma = 0.72 keeps them; the secondary lobes stay under 0.5 sigma.
    t = np.arange(0.0, 8.0, 0.01)
    main = np.arange(1.0, 5.01, 0.5)
    weak = np.array([5.5, 6.0])
    x = _lobes(t, main, 4.0) + _lobes(t, main + 0.2, 0.7) + _lobes(t, weak, 0.8)
    new = PeakStepDetector().process(t, x)
    np.testing.assert_allclose(new.t_end, np.concatenate([main, weak]), atol=0.015)
    old = PeakStepDetector(OLD_RULE).process(t, x)
    np.testing.assert_allclose(old.t_end, main, atol=0.015)


def test_rhythm_parameters_are_checked() -> None:
    with pytest.raises(InputError, match="rhythm"):
        PeakStepDetector(PeakStepParams(rhythm_min_ratio=1.5, rhythm_max_ratio=1.4))
    with pytest.raises(InputError, match="rhythm"):
        PeakStepDetector(PeakStepParams(rhythm_relative_threshold=-0.1))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), lo=st.floats(0.3, 0.95), width=st.floats(0.1, 1.5))
def test_rhythm_window_is_inert_when_both_levels_are_equal(seed: int, lo: float,
                                                           width: float) -> None:
    # the rule only changes the relative level on the rhythm: with equal levels the window
    # of the rhythm cannot change a single step
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 20.0, 0.01)
    f = rng.uniform(1.4, 2.4)
    amp = 2.0 + 1.5 * np.sin(2 * np.pi * rng.uniform(0.02, 0.2) * t)
    x = amp * np.cos(2 * np.pi * f * t + rng.uniform(0, 6)) + rng.normal(0, 0.4, t.size)
    ref = PeakStepDetector(OLD_RULE).process(t, x)
    other = PeakStepDetector(PeakStepParams(
        rhythm_relative_threshold=OLD_RULE.relative_threshold, rhythm_min_ratio=lo,
        rhythm_max_ratio=lo + width)).process(t, x)
    np.testing.assert_array_equal(ref.t_end, other.t_end)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), split=st.integers(1, 1999))
def test_rhythm_rule_chunked_equals_batch(seed: int, split: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 20.0, 0.01)
    env = np.clip(np.sin(np.pi * t / 10.0), 0.1, 1.0)  # slows down and speeds up
    x = 4.0 * env * np.cos(2 * np.pi * 1.8 * t) + rng.normal(0, 0.3, t.size)
    whole = PeakStepDetector().process(t, x)
    det = PeakStepDetector()
    a = det.update(t[:split], x[:split])
    b = det.update(t[split:], x[split:])
    np.testing.assert_allclose(np.concatenate([a.t_end, b.t_end]), whole.t_end)


def _count(walk: SimWalk, params: PeakStepParams | None = None,
           walk_steps: WalkStepParams | None = None) -> int:
    # the tracker's gait settings (default preset), accelerometer only
    ga = GaitAnalyzer(rate_hz=100.0, step_detector=PeakStepDetector(params), heading="yaw",
                      step_yaw="turns", window_features=False,
                      walk_steps=WalkStepParams() if walk_steps is None else walk_steps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return len(ga.process(walk.t, walk.acc_d).steps)


def test_short_simulated_walks_with_stops_and_a_u_turn() -> None:
    # held-out seeds (the rules were chosen on seeds 0-19 and the Oxford pocket files)
    walks = [short_walk_u_turn(seed) for seed in range(100, 130)]
    truth = sum(len(w.step_t) for w in walks)
    new = [_count(w) for w in walks]
    assert abs(sum(new) - truth) <= 0.01 * truth
    off = [abs(n - len(w.step_t)) for n, w in zip(new, walks, strict=True)]
    assert sum(e > 1 for e in off) <= 1 and max(off) <= 2
    # without the closing-step rule the closing movements count as steps
    no_closing = [_count(w, walk_steps=WalkStepParams(closing_ratio=0.0)) for w in walks]
    assert sum(no_closing) > truth + 0.01 * truth


def test_closing_movement_is_not_counted_a_real_last_step_is() -> None:
    # one person walking 8 s between two standing parts; the end ramp ends at 0.9 of the
    # walking amplitude. A closing movement of 0.35 of the walk's peak 1.1 step periods after
    # the last step adds one detected peak (about half the walk's level after the low-pass);
    # the walk filter drops it and keeps the last true step. Without it the last step
    # (about 0.85 of the level) is kept as well.
    segs = [(int(Activity.STANDING), 3.0), (int(Activity.WALKING), 8.0),
            (int(Activity.STANDING), 4.0)]
    ends = simulate(segs, seed=5, stop_amplitude=0.5, end_amplitude=0.9)
    closes = simulate(segs, seed=5, stop_amplitude=0.5, end_amplitude=0.9,
                      closing=(0.35, 1.1))
    np.testing.assert_array_equal(ends.step_t, closes.step_t)
    off = WalkStepParams(closing_ratio=0.0)
    n = _count(ends, walk_steps=off)
    assert _count(closes, walk_steps=off) == n + 1
    assert _count(closes) == _count(ends) == n
    ga = GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns", window_features=False,
                      walk_steps=WalkStepParams())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        last = ga.process(closes.t, closes.acc_d).steps.t_end[-1]
    assert abs(last - closes.step_t[-1]) < 0.1


def test_sim_options_off_leave_the_walk_unchanged() -> None:
    segs = [(Activity.STANDING, 2.0), (Activity.WALKING, 8.0), (Activity.STANDING, 2.0)]
    a = simulate(segs, seed=3)
    b = simulate(segs, seed=3, stop_amplitude=None, turns=(), end_amplitude=None, closing=None)
    np.testing.assert_array_equal(a.acc_d, b.acc_d)
    # an end amplitude equal to the start one changes nothing
    c0 = simulate(segs, seed=3, stop_amplitude=0.3)
    c1 = simulate(segs, seed=3, stop_amplitude=0.3, end_amplitude=0.3)
    np.testing.assert_array_equal(c0.acc_d, c1.acc_d)
    c = simulate(segs, seed=3, turns=((5.0, 2.0, np.pi),))
    heading = np.unwrap(c.step_heading_rad)
    assert heading[-1] - heading[0] == pytest.approx(np.pi, abs=0.05)


@pytest.mark.realdata
def test_mobgap_short_walks_counted_with_the_standing_parts(shared_data: Path) -> None:
    """`hrtls track` (default preset) on the Test5 walks, whole trials including standing.

    Every INDIP contact is found (within 0.2 s) and the count inside the INDIP bouts is
    exact. The whole-trial count is 37 for 36 INDIP contacts: the closing step after HA/001
    Trial1's walk, which Stereophoto has as a contact (0.86 of the walk's peaks); the closing-
    step rule drops the four others (41 without it), the walk filter the 2 steps of a shift of
    weight at the start of HA/001 Trial1 (43 without it).
    """
    from hrtls.datasets import mobgap
    from hrtls.pipeline.config import preset
    from hrtls.pipeline.tracker import Tracker

    root = shared_data / "mobgap_lab"
    n_det = n_ref = 0
    for trial_id in mobgap.list_trials(root):
        if trial_id.test != "Test5":
            continue
        trial = mobgap.load_trial(root, trial_id.participant, trial_id.test, trial_id.trial)
        ref = trial.reference.indip
        if ref is None or len(ref.bout_start_s) == 0:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = Tracker(preset("default")).run(trial.session)
        te = res.steps.t_end - trial.session.imu.accel.t[0]
        ic = np.sort(ref.initial_contacts_s[np.isfinite(ref.initial_contacts_s)])
        assert all(np.min(np.abs(te - r)) <= 0.2 for r in ic)
        inside = (te > ref.bout_start_s[0] - 0.3) & (te < ref.bout_end_s[-1] + 0.3)
        assert int(inside.sum()) == len(ic)
        n_det += len(te)
        n_ref += len(ic)
    assert n_ref == 36
    assert n_det == 37


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(100, 129), cuts=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=4))
def test_short_walk_live_with_restarts_equals_offline(seed: int, cuts: list[float]) -> None:
    # the live path: chunks, each state through JSON into a fresh analyzer
    walk = short_walk_u_turn(seed)
    n = walk.t.size
    bounds = [0, *sorted({int(c * (n - 1)) + 1 for c in cuts}), n]
    bounds = sorted(set(bounds))

    def make() -> GaitAnalyzer:
        return GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns",
                            window_features=False)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = make().process(walk.t, walk.acc_d)
        live = run_with_restarts(make, walk.t, walk.acc_d, None, bounds)
    np.testing.assert_allclose(live.steps.t_end, whole.steps.t_end)
