"""Missed-step filling: hand cases, chunk independence, state, pipeline option."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.missed_steps import MissedStepFiller, MissedStepParams, MissedStepState
from hrtls.gait.pll import StepDetection
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.gait.walking_bouts import WalkingBoutParams

from ._chunks import run_with_restarts


def steps_at(t: list[float]) -> StepDetection:
    te = np.asarray(t, dtype=np.float64)
    ts = np.concatenate([[te[0] - 0.5], te[:-1]]) if te.size else te
    n = te.size
    return StepDetection(ts, te, 1.0 / (te - ts), np.full(n, 2.0), np.full(n, -1.0))


def test_hand_case() -> None:
    # steps every 0.5 s, one missing at 2.0 s; a 3 s pause is not filled; a 1.4 s gap at a
    # 0.5 s rhythm (2.8 periods) is not filled either
    t = [0.0, 0.5, 1.0, 1.5, 2.5, 3.0, 6.0, 6.5, 7.0, 7.5, 8.9]
    out = MissedStepFiller().process(steps_at(t))
    np.testing.assert_allclose(out.t_end, [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 6.0, 6.5, 7.0,
                                           7.5, 8.9])
    k = 4  # the inserted step: starts at the step before, half the gap; shares the amplitude
    assert out.t_start[k] == pytest.approx(1.5)
    assert out.t_start[k + 1] == pytest.approx(2.0)
    assert out.frequency_hz[k] == pytest.approx(2.0)
    assert out.frequency_hz[k + 1] == pytest.approx(2.0)
    assert out.acc_max[k] == 2.0
    # asymmetric rhythm: the period is half the last stride
    out = MissedStepFiller().process(steps_at([0.0, 0.4, 1.0, 1.4, 2.5]))
    np.testing.assert_allclose(out.t_end, [0.0, 0.4, 1.0, 1.4, 1.95, 2.5])


def test_errors_and_state() -> None:
    with pytest.raises(InputError):
        MissedStepParams(min_ratio=2.5, max_ratio=2.0)
    f = MissedStepFiller()
    f.update(steps_at([0.0, 0.5, 1.0]))
    with pytest.raises(InputError):
        f.update(steps_at([0.7]))
    d = json.loads(json.dumps(f.state.to_dict()))
    assert MissedStepState.from_dict(d).t.tolist() == [0.0, 0.5, 1.0]
    with pytest.raises(InputError):
        MissedStepState.from_dict({"t": [1, 2, 3, 4]})


@settings(max_examples=100, deadline=None)
@given(gaps=st.lists(st.floats(0.3, 2.5), min_size=0, max_size=25),
       cuts=st.lists(st.integers(0, 25), max_size=5))
def test_chunks_equal_whole(gaps: list[float], cuts: list[int]) -> None:
    t = (np.cumsum(gaps) if gaps else np.zeros(0)).tolist()
    whole = MissedStepFiller().process(steps_at(t)) if t else None
    f = MissedStepFiller()
    parts = []
    det = steps_at(t) if t else None
    bounds = sorted({0, len(t), *[min(c, len(t)) for c in cuts]})
    for a, b in itertools.pairwise(bounds):
        assert det is not None
        sub = StepDetection(det.t_start[a:b], det.t_end[a:b], det.frequency_hz[a:b],
                            det.acc_max[a:b], det.acc_min[a:b])
        parts.append(f.update(sub))
        f.state = MissedStepState.from_dict(json.loads(json.dumps(f.state.to_dict())))
    if whole is None:
        return
    joined = StepDetection.concat(parts)
    np.testing.assert_allclose(joined.t_end, whole.t_end)
    np.testing.assert_allclose(joined.t_start, whole.t_start)
    # never more than one step per gap, only within the ratio band
    assert len(whole) - len(t) <= max(len(t) - 3, 0)


def test_pipeline_fills_a_dropped_step() -> None:
    rng = np.random.default_rng(3)
    w = simulate([(0, 4), (1, 20), (0, 4)], person=SimPerson.random(rng),
                  q_bd=random_mounting(rng), seed=3)
    kw = {"rate_hz": 100.0, "mounting_q_bd": w.q_bd}
    base = GaitAnalyzer(**kw).process(w.t, w.acc_d, w.q_nd)
    filled = GaitAnalyzer(**kw, missed_steps=MissedStepParams()).process(w.t, w.acc_d,
                                                                         w.q_nd)
    # a regular simulated walk has no gap to fill
    assert len(filled.steps) <= len(base.steps) + 1
    # chunked with save/restore equals the whole run (with walking bouts as well)

    def make() -> GaitAnalyzer:
        return GaitAnalyzer(**kw, missed_steps=MissedStepParams(),
                            walking_bouts=WalkingBoutParams())

    whole = make().process(w.t, w.acc_d, w.q_nd)
    joined = run_with_restarts(make, w.t, w.acc_d, w.q_nd, [0, 333, 1200, 1800, len(w.t)])
    np.testing.assert_allclose(joined.steps.t_end, whole.steps.t_end, atol=1e-9)
    np.testing.assert_array_equal(joined.activity, whole.activity)
    with pytest.raises(InputError):
        GaitAnalyzer(**kw, walking_bouts=WalkingBoutParams()).restore(make().state())
