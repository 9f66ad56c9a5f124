"""The walk filter (issue 19): weak short walks (a shift of weight) are not steps."""

from __future__ import annotations

import itertools
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.synthetic import simulate
from hrtls.gait.walk_steps import (
    DROP,
    KEEP,
    UNDECIDED,
    WalkStepParams,
    WalkStepState,
    add_steps,
    step_status,
    walk_steps,
)

from ._chunks import run_with_restarts


def test_hand_made_weight_shift_walk_and_closing_step() -> None:
    # two weak peaks while standing, a walk of six steps, a weak closing step (1.0 against a
    # level of 2.25: 0.44 < 0.6), a lone weak peak later, and a walk of three weak steps
    # (confirmed by its count)
    t = np.array([1.0, 1.5, 5.0, 5.6, 6.2, 6.8, 7.4, 8.0, 8.6, 12.0, 15.0, 15.6, 16.2])
    peak = np.array([0.6, 0.7, 2.0, 2.4, 2.2, 2.5, 2.3, 2.1, 1.0, 0.6, 0.7, 0.6, 0.7])
    kept = walk_steps(t, peak)
    np.testing.assert_array_equal(kept, [False, False] + [True] * 6 + [False] * 2
                                  + [True] * 3)
    no_closing = walk_steps(t, peak, WalkStepParams(closing_ratio=0.0))
    np.testing.assert_array_equal(no_closing, [False, False] + [True] * 7 + [False]
                                  + [True] * 3)
    # a last step at 0.67 of the level (1.5 / 2.25) is a step
    strong_last = walk_steps(t[:9], np.r_[peak[:8], 1.5])
    np.testing.assert_array_equal(strong_last, [False, False] + [True] * 7)
    # one strong peak confirms a walk at once: nothing is held
    st_ = WalkStepState()
    add_steps(st_, WalkStepParams(), np.array([3.0]), np.array([0.9]))
    assert step_status(st_, np.array([3.0]))[0] == KEEP


def test_weak_step_before_a_pause_is_kept_before_standing_dropped() -> None:
    # a walk of four 2 m/s^2 steps, a weak step (0.5 of the level), then the next step
    # 2.5 s later (a pause inside a walk: kept) or 3.5 s later (the person stood: dropped)
    t = np.array([1.0, 1.5, 2.0, 2.5, 3.0])
    peak = np.array([2.0, 2.0, 2.0, 2.0, 1.0])
    for gap, weak_kept in ((2.5, True), (3.5, False)):
        kept = walk_steps(np.r_[t, 3.0 + gap], np.r_[peak, 2.0])
        np.testing.assert_array_equal(kept, [True] * 4 + [weak_kept, True])
    # the decision waits for the pause: undecided 2.9 s after the weak step, dropped at 3.1 s
    s = WalkStepState()
    add_steps(s, WalkStepParams(), t, peak, complete_s=5.9)
    assert step_status(s, t)[-1] == UNDECIDED
    add_steps(s, WalkStepParams(), np.zeros(0), np.zeros(0), complete_s=6.1)
    assert step_status(s, t)[-1] == DROP


def test_held_steps_wait_for_the_decision() -> None:
    p = WalkStepParams()
    s = WalkStepState()
    add_steps(s, p, np.array([1.0, 1.5]), np.array([0.6, 0.6]), complete_s=3.4)
    assert list(step_status(s, np.array([1.0, 1.5]))) == [UNDECIDED, UNDECIDED]
    # every step up to 2 s after the last one is known: the walk ended unconfirmed
    add_steps(s, p, np.zeros(0), np.zeros(0), complete_s=3.6)
    assert list(step_status(s, np.array([1.0, 1.5]))) == [DROP, DROP]
    assert WalkStepState.from_dict(json.loads(json.dumps(s.to_dict()))).to_dict() == s.to_dict()


def test_parameters_and_state_are_checked() -> None:
    for bad in ({"min_walk_steps": 0}, {"closing_ratio": 1.0}, {"strong_peak_m_s2": -1.0},
                {"level_steps": 1.5}, {"closing_pause_s": 1.5}):
        with pytest.raises(InputError):
            WalkStepParams(**bad)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="one decision per step"):
        WalkStepState.from_dict({"t": [1.0], "status": [], "t_last": None, "n_steps": 0,
                                 "confirmed": False, "level": []})


@settings(max_examples=60, deadline=None)
@given(gaps=st.lists(st.floats(0.3, 4.0), min_size=1, max_size=30),
       peaks=st.lists(st.floats(0.45, 3.0), min_size=30, max_size=30),
       cuts=st.lists(st.integers(0, 30), max_size=4),
       ratio=st.sampled_from([0.0, 0.6]))
def test_batches_equal_whole_and_strong_walks_are_kept(gaps: list[float], peaks: list[float],
                                                       cuts: list[int], ratio: float) -> None:
    t = np.cumsum(gaps)
    a = np.asarray(peaks[: t.size])
    p = WalkStepParams(closing_ratio=ratio)
    whole = walk_steps(t, a, p)
    s = WalkStepState()
    bounds = sorted({0, t.size, *[min(c, t.size) for c in cuts]})
    for i0, i1 in itertools.pairwise(bounds):
        # the detector has reported every step before the next batch's first one
        done = t[i1] if i1 < t.size else t[-1]
        add_steps(s, p, t[i0:i1], a[i0:i1], complete_s=float(done))
        status = step_status(s, t[:i1])
        decided = status != UNDECIDED
        np.testing.assert_array_equal(status[decided] == KEEP, whole[:i1][decided])
    add_steps(s, p, np.zeros(0), np.zeros(0), complete_s=math.inf)
    np.testing.assert_array_equal(step_status(s, t) == KEEP, whole)
    if ratio == 0.0 and np.all(a >= p.strong_peak_m_s2):
        assert whole.all()
    if ratio == 0.0:   # a walk of min_walk_steps steps is always kept
        walk_id = np.concatenate([[0], np.cumsum(np.diff(t) > p.max_gap_s)])
        long_walk = np.bincount(walk_id)[walk_id] >= p.min_walk_steps
        assert whole[long_walk].all()


def _walk_with_weight_shift() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stand 4 s with two weak bumps of the upward acceleration at 1.0 and 1.6 s (peaks of
    0.6-0.7 m/s^2 after the step filter, as in mobgap HA/001), walk 8 s, stand 3 s; device
    axes = body axes (z up)."""
    w = simulate([(int(Activity.STANDING), 4.0), (int(Activity.WALKING), 8.0),
                  (int(Activity.STANDING), 3.0)], seed=4)
    acc = w.acc_d.copy()
    for c in (1.0, 1.6):
        acc[:, 2] += 1.2 * (np.exp(-0.5 * ((w.t - c) / 0.06) ** 2)
                            - np.exp(-0.5 * ((w.t - c - 0.15) / 0.06) ** 2))
    return w.t, acc, w.step_t


def _analyzer(walk: WalkStepParams | None) -> GaitAnalyzer:
    return GaitAnalyzer(rate_hz=100.0, heading="yaw", step_yaw="turns", window_features=False,
                        walk_steps=walk)


def test_analyzer_drops_the_weight_shift_and_keeps_the_walk() -> None:
    t, acc, _ = _walk_with_weight_shift()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        off = _analyzer(None).process(t, acc).steps.t_end
        on = _analyzer(WalkStepParams()).process(t, acc).steps.t_end
        live = run_with_restarts(lambda: _analyzer(WalkStepParams()), t, acc, None,
                                 [0, 120, 170, 500, 901, t.size]).steps.t_end
    assert np.sum(off < 3.0) == 2   # the detector sees the two bumps as steps
    assert np.sum(on < 3.0) == 0
    np.testing.assert_allclose(on, off[off >= 3.0])
    np.testing.assert_allclose(live, on)


def test_state_without_the_walk_filter_restores() -> None:
    # a state written before the walk filter (no "walk" in the held part) still continues
    t, acc, _ = _walk_with_weight_shift()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = _analyzer(WalkStepParams()).process(t, acc).steps.t_end
        ga = _analyzer(WalkStepParams())
        first = ga.update(t[:300], acc[:300]).steps.t_end
        state = json.loads(json.dumps(ga.state()))
        del state["pending"]["walk"]
        ga2 = _analyzer(WalkStepParams())
        ga2.restore(state)
        rest = ga2.update(t[300:], acc[300:]).steps.t_end
        tail = ga2.flush().steps.t_end
    np.testing.assert_allclose(np.concatenate([first, rest, tail]), whole)


@pytest.mark.realdata
def test_mobgap_weight_shift_before_the_walk(shared_data: Path) -> None:
    """HA/001 Test5 Trial1 through `hrtls track`: two peaks of a shift of weight at 0.2 and
    0.7 s (4 s before the walk) were counted as steps (12 steps for 9 INDIP contacts)."""
    from hrtls.datasets import mobgap
    from hrtls.pipeline.config import preset
    from hrtls.pipeline.tracker import Tracker

    trial = mobgap.load_trial(shared_data / "mobgap_lab", "HA/001", "Test5", "Trial1")
    ref = trial.reference.indip
    assert ref is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = Tracker(preset("default")).run(trial.session)
    te = res.steps.t_end - trial.session.imu.accel.t[0]
    ic = np.sort(ref.initial_contacts_s[np.isfinite(ref.initial_contacts_s)])
    assert te.size == ic.size + 1   # the closing step after the walk (Stereophoto has it)
    assert te[0] > ic[0] - 0.2
    assert all(np.min(np.abs(te - r)) <= 0.2 for r in ic)
