"""Step-sequence walking bouts: hand cases, streaming == offline, pipeline integration."""

from __future__ import annotations

import itertools
import json
import math
import warnings
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import DegradedInputWarning, InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.pll import PllStepDetector
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.gait.walking_bouts import (
    IN_BOUT,
    NOT_IN_BOUT,
    UNDECIDED,
    WalkingBoutDetector,
    WalkingBoutParams,
    WalkingBoutState,
    decide_chains,
    walking_bouts,
    walking_mask,
)

from ._chunks import run_with_restarts


def slow_in_bout(t: list[float], gap: float, n: int) -> list[bool]:
    """Reference: each step's chain (gaps <= gap) counted by a plain loop."""
    out = []
    for i in range(len(t)):
        a = i
        while a > 0 and t[a] - t[a - 1] <= gap:
            a -= 1
        b = i
        while b + 1 < len(t) and t[b + 1] - t[b] <= gap:
            b += 1
        out.append(b - a + 1 >= n)
    return out


def slow_walking(tau: float, t: list[float], yes: list[bool], gap: float, m0: float,
                 m1: float) -> bool:
    ty = [x for x, y in zip(t, yes, strict=True) if y]
    if any(s - m0 <= tau <= s + m1 for s in ty):
        return True
    return any(a <= tau <= b and b - a <= gap for a, b in itertools.pairwise(ty))


def test_hand_case() -> None:
    # two isolated events, a 4-step walk, a pair, a 3-step walk with a 1.9 s gap
    t = np.array([0.0, 5.0, 10.0, 10.5, 11.0, 11.5, 20.0, 20.6, 30.0, 31.9, 32.4])
    yes, bouts = walking_bouts(t, WalkingBoutParams(max_gap_s=2.0, min_steps=3))
    np.testing.assert_array_equal(yes, [0, 0, 1, 1, 1, 1, 0, 0, 1, 1, 1])
    np.testing.assert_allclose(bouts, [[10.0, 11.5], [30.0, 32.4]])
    st_ = np.where(yes, IN_BOUT, NOT_IN_BOUT)
    w = walking_mask(np.array([9.9, 10.0, 10.7, 11.5, 11.6, 20.3, 31.0, 32.5]), t, st_,
                     max_gap_s=2.0, margin_before_s=0.0, margin_after_s=0.0)
    np.testing.assert_array_equal(w, [0, 1, 1, 1, 0, 0, 1, 0])
    w = walking_mask(np.array([9.9, 11.6, 11.8]), t, st_, max_gap_s=2.0,
                     margin_before_s=0.2, margin_after_s=0.2)
    np.testing.assert_array_equal(w, [1, 1, 0])


def test_decisions_wait_for_certainty() -> None:
    t = np.array([0.0, 1.0])
    st_ = decide_chains(t, np.full(2, UNDECIDED), 2.5, max_gap_s=2.0, min_steps=3)
    np.testing.assert_array_equal(st_, [UNDECIDED, UNDECIDED])  # a third step may come
    st_ = decide_chains(t, np.full(2, UNDECIDED), 3.01, max_gap_s=2.0, min_steps=3)
    np.testing.assert_array_equal(st_, [NOT_IN_BOUT, NOT_IN_BOUT])
    # a step chained to one already in a bout is in the bout at once
    st_ = decide_chains(np.array([0.0, 1.0]), np.array([IN_BOUT, UNDECIDED]), 1.0,
                        max_gap_s=2.0, min_steps=3)
    np.testing.assert_array_equal(st_, [IN_BOUT, IN_BOUT])


def test_params_and_input_errors() -> None:
    with pytest.raises(InputError):
        WalkingBoutParams(min_steps=0)
    with pytest.raises(InputError):
        WalkingBoutParams(max_gap_s=-1.0)
    with pytest.raises(InputError):
        WalkingBoutParams(margin_after_s=math.nan)
    det = WalkingBoutDetector()
    det.add(np.array([1.0, 2.0]), 2.5)
    with pytest.raises(InputError):
        det.add(np.array([1.5]), 3.0)
    with pytest.raises(InputError):
        det.add(np.zeros(0), math.nan)
    with pytest.raises(InputError):
        WalkingBoutDetector().from_dict({"t": [1.0], "status": [], "complete_s": None})
    assert WalkingBoutParams(max_gap_s=2.0, min_steps=3, margin_before_s=0.5).max_delay_s \
        == pytest.approx(4.5)


@settings(max_examples=80, deadline=None)
@given(gaps=st.lists(st.floats(0.2, 4.0), min_size=0, max_size=30),
       cuts=st.lists(st.floats(0.0, 1.0), min_size=0, max_size=6),
       n=st.integers(1, 5), gap=st.floats(0.5, 3.0), m0=st.floats(0.0, 1.0),
       m1=st.floats(0.0, 1.0), lag=st.floats(0.0, 0.5))
def test_streaming_equals_offline_and_reference(gaps: list[float], cuts: list[float], n: int,
                                                gap: float, m0: float, m1: float,
                                                lag: float) -> None:
    t = np.cumsum(np.asarray(gaps, dtype=np.float64)) if gaps else np.zeros(0)
    p = WalkingBoutParams(max_gap_s=gap, min_steps=n, margin_before_s=m0, margin_after_s=m1)
    yes, _ = walking_bouts(t, p)
    assert yes.tolist() == slow_in_bout(t.tolist(), gap, n)
    # stream: the detector learns each step ``lag`` after it; states read when final
    end = (float(t[-1]) if t.size else 0.0) + 6.0
    clock = np.sort(np.concatenate([[0.0, end], np.asarray(cuts) * end]))
    det = WalkingBoutDetector(p, history_s=1.0)
    tau = np.arange(-1.0, end, 0.05)
    got = np.full(tau.shape, -1)
    decided: dict[float, bool] = {}
    done = 0
    for now in clock:
        known = t[(t + lag <= now) & (t >= (det.state.t[-1] if det.state.t.size else -1.0))]
        known = known[~np.isin(known, det.state.t)]
        det.add(known, now - lag)
        tt = det.state.t
        for x, d, y in zip(tt, det.decided(tt), det.in_bout(tt), strict=True):
            if d:
                decided.setdefault(float(x), bool(y))
        k = int(np.searchsorted(tau, det.final_until_s, side="left"))
        if k > done:
            got[done:k] = det.walking(tau[done:k])
            done = k
        det.trim(math.inf)
    det.finish()
    for x, y in zip(det.state.t, det.in_bout(det.state.t), strict=True):
        decided.setdefault(float(x), bool(y))
    got[done:] = det.walking(tau[done:])
    assert [decided.get(float(x)) for x in t] == yes.tolist()
    ref = [slow_walking(x, t.tolist(), yes.tolist(), gap, m0, m1) for x in tau]
    assert got.astype(bool).tolist() == ref


def test_state_round_trip() -> None:
    det = WalkingBoutDetector()
    det.add(np.array([1.0, 1.5, 2.0, 9.0]), 9.1)
    d = json.loads(json.dumps(det.to_dict(), allow_nan=False))
    other = WalkingBoutDetector()
    other.from_dict(d)
    np.testing.assert_array_equal(other.state.t, det.state.t)
    np.testing.assert_array_equal(other.state.status, det.state.status)
    assert other.final_until_s == det.final_until_s


@pytest.fixture(scope="module")
def walk():
    rng = np.random.default_rng(21)
    return simulate([(0, 6), (1, 25), (0, 8), (1, 12), (0, 5)], person=SimPerson.random(rng),
                    q_bd=random_mounting(rng), heading0_rad=0.3, seed=21)


@pytest.mark.parametrize("detector", ["peak", "pll"])
def test_pipeline_chunked_with_state_equals_offline(walk, detector: str) -> None:
    def make() -> GaitAnalyzer:
        return GaitAnalyzer(rate_hz=100.0, mounting_q_bd=walk.q_bd,
                            walking_bouts=WalkingBoutParams(margin_after_s=0.3),
                            step_detector=PllStepDetector() if detector == "pll" else None)

    whole = make().process(walk.t, walk.acc_d, walk.q_nd)
    bounds = [0, 90, 1234, 1235, 2600, 4100, 5000, len(walk.t)]
    joined = run_with_restarts(make, walk.t, walk.acc_d, walk.q_nd, bounds)
    np.testing.assert_allclose(joined.steps.t_end, whole.steps.t_end, atol=1e-9)
    np.testing.assert_array_equal(joined.steps.activity, whole.steps.activity)
    np.testing.assert_array_equal(joined.activity_t, whole.activity_t)
    np.testing.assert_array_equal(joined.activity, whole.activity)
    np.testing.assert_array_equal(whole.activity_t, walk.t)
    # a bouts state does not restore into an analyzer without bouts
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0).restore(make().state())


def test_pipeline_bouts_activity_and_steps(walk) -> None:
    ga = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=walk.q_bd, walking_bouts=WalkingBoutParams())
    res = ga.process(walk.t, walk.acc_d, walk.q_nd)
    base = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=walk.q_bd).process(walk.t, walk.acc_d,
                                                                          walk.q_nd)
    # steps of the two walks are kept (nothing but isolated events is dropped)
    assert len(res.steps) >= len(base.steps) - 2
    assert abs(len(res.steps) - len(walk.step_t)) <= 3
    # windows fully inside a walk are walking, fully standing windows are standing
    walking = res.activity == int(Activity.WALKING)
    truth = walk.activity == int(Activity.WALKING)
    j = 200
    nw = walk.t.size // j
    pure_w = truth[: nw * j].reshape(nw, j).all(axis=1)
    pure_s = (~truth[: nw * j]).reshape(nw, j).all(axis=1)
    pred = walking[: nw * j].reshape(nw, j).mean(axis=1) > 0.5
    assert np.mean(pred[pure_w]) >= 0.95
    assert np.mean(~pred[pure_s]) >= 0.95


def test_isolated_events_are_dropped() -> None:
    # standing with three isolated bumps 5 s apart: the peak detector reports them as steps,
    # the bouts drop them and the activity stays standing
    t = np.arange(0.0, 20.0, 0.01)
    acc = np.zeros((t.size, 3))
    acc[:, 2] = 9.81
    for c in (5.0, 10.0, 15.0):
        acc[:, 2] += 3.0 * np.exp(-0.5 * ((t - c) / 0.08) ** 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        plain = GaitAnalyzer(rate_hz=100.0).process(t, acc)
        res = GaitAnalyzer(rate_hz=100.0, walking_bouts=WalkingBoutParams()).process(t, acc)
    assert len(plain.steps) >= 3
    assert len(res.steps) == 0
    assert np.all(res.activity != int(Activity.WALKING))


def test_real_mobgap_daily_life_walking_windows(shared_data) -> None:
    """MS/001 daily life: bouts raise the walking/not-walking window accuracy vs INDIP."""
    from hrtls.attitude.complementary import ComplementaryFilter, ComplementaryParams
    from hrtls.datasets import mobgap
    from hrtls.gait.features import window_labels
    from hrtls.gait.session_analysis import session_inputs

    trial = mobgap.load_trial(shared_data / "mobgap_lab", "MS/001", "Test11", "Trial1")
    t, acc, _, mount, rate = session_inputs(trial.session)
    gyr = trial.session.imu.gyro.values
    q = ComplementaryFilter(ComplementaryParams(init_heading_from_mag=False)).update(
        t, acc, gyr).q
    lab = np.zeros(t.shape, dtype=np.int64)
    ref = trial.reference.indip
    for b0, b1 in zip(ref.bout_start_s, ref.bout_end_s, strict=True):
        lab[(t >= b0) & (t < b1)] = 1
    y = window_labels(lab, 200)
    ok = y >= 0
    acc_w = {}
    n_steps = {}
    for name, wb in (("plain", None), ("bouts", WalkingBoutParams())):
        res = GaitAnalyzer(rate_hz=rate, mounting_q_bd=mount, walking_bouts=wb).process(
            t, acc, q)
        walk = res.activity == int(Activity.WALKING)
        pred = walk[: y.size * 200].reshape(y.size, 200).mean(axis=1) > 0.5
        acc_w[name] = float(np.mean(pred[ok] == (y[ok] == 1)))
        n_steps[name] = len(res.steps)
    # measured: 0.83 plain, 0.94 with bouts (109 windows)
    assert acc_w["bouts"] >= 0.9
    assert acc_w["bouts"] > acc_w["plain"] + 0.05
    assert n_steps["bouts"] <= n_steps["plain"]


@pytest.mark.parametrize("data", [{"status": [], "complete_s": None, "t_last": None},
                                  {"t": [1.0], "status": ["x"], "complete_s": None},
                                  {"t": [1.0, 2.0], "status": [1]}])
def test_bad_decision_states_name_their_class(data: dict[str, Any]) -> None:
    from hrtls.gait.walk_steps import WalkStepState

    with pytest.raises(InputError, match="WalkingBoutState"):
        WalkingBoutState.from_dict(data)
    with pytest.raises(InputError, match="WalkStepState"):
        WalkStepState.from_dict(data)
