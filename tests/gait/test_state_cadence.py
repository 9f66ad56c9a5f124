"""GaitAnalyzer save/restore, the cadence (periodicity) walking detector and the step gate."""

from __future__ import annotations

import itertools
import json
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import DegradedInputWarning, InputError
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.analyzer import GaitAnalyzer, GaitResult
from hrtls.gait.cadence import CadenceDetector, CadenceParams
from hrtls.gait.motion_detector import RUN, STILL, WALK
from hrtls.gait.pll import PllStepDetector
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.gait.velocity_automaton import VelocityAutomaton

from ._chunks import run_with_restarts


@pytest.fixture(scope="module")
def walk():
    rng = np.random.default_rng(21)
    return simulate([(0, 4), (1, 25), (0, 4), (2, 8), (0, 3)], person=SimPerson.random(rng),
                    q_bd=random_mounting(rng), heading0_rad=0.3, turn_rate_rad_s=0.02,
                    seed=21)


def assert_same(a: GaitResult, b: GaitResult) -> None:
    for col in ("t_start", "t_end", "length_m", "heading_rad", "dz_m", "frequency_hz",
                "acc_max", "acc_min"):
        np.testing.assert_allclose(getattr(a.steps, col), getattr(b.steps, col), atol=1e-9,
                                   err_msg=col)
    np.testing.assert_array_equal(a.steps.activity, b.steps.activity)
    np.testing.assert_array_equal(a.activity, b.activity)
    np.testing.assert_allclose(a.activity_t, b.activity_t)
    np.testing.assert_allclose(a.velocity_m_s, b.velocity_m_s, atol=1e-9)
    np.testing.assert_allclose(a.step_excursion_m, b.step_excursion_m, atol=1e-12)


def _kwargs(walk, detector: str, gate: bool, heading: str = "fourier") -> dict:
    return {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "activity": LdaModel.default(),
            "velocity": VelocityAutomaton(), "gate_steps_with_motion": gate,
            "step_detector": PllStepDetector() if detector == "pll" else None,
            "heading": heading}


@pytest.mark.parametrize(("detector", "gate", "with_q", "heading"),
                         [("peak", False, True, "fourier"), ("pll", True, True, "yaw"),
                          ("peak", True, False, "fourier")])
def test_state_restore_mid_recording_continues_identically(walk, detector, gate, with_q,
                                                           heading) -> None:
    q = walk.q_nd if with_q else None
    whole = GaitAnalyzer(**_kwargs(walk, detector, gate, heading))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DegradedInputWarning)
        ref = whole.process(walk.t, walk.acc_d, q)
    cuts = [0, 1234, 2501, 3777, len(walk.t)]
    ga = GaitAnalyzer(**_kwargs(walk, detector, gate, heading))
    parts = []
    for a, b in itertools.pairwise(cuts):
        parts.append(ga.update(walk.t[a:b], walk.acc_d[a:b], None if q is None else q[a:b]))
        # save as strict JSON text and continue in a brand-new analyzer
        text = json.dumps(ga.state(), allow_nan=False)
        ga = GaitAnalyzer(**_kwargs(walk, detector, gate, heading))
        ga.restore(json.loads(text))
    parts.append(ga.flush())
    assert_same(GaitResult.concat(parts), ref)


def test_restore_rejects_foreign_or_mismatched_state(walk) -> None:
    ga = GaitAnalyzer(rate_hz=100.0)
    ga.update(walk.t[:500], walk.acc_d[:500], walk.q_nd[:500])
    s = ga.state()
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0).restore({"format": "something else"})
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0, step_detector=PllStepDetector()).restore(s)
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0, cadence=None).restore(s)
    bad = dict(s)
    del bad["pending"]
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0).restore(bad)


# ------------------------------------------------------------------------------ cadence
def slow_autocorr(y: np.ndarray, lmin: int, lmax: int) -> dict[int, float]:
    """Pure-Python reference of the kernel's normalized autocorrelation per lag."""
    y = y - y.mean()
    out = {}
    for lag in range(lmin, lmax + 1):
        a, b = y[lag:], y[:-lag]
        out[lag] = float(np.sum(a * b) / np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return out


def test_cadence_sinusoid_frequency_and_reference() -> None:
    rate = 100.0
    # 1200 samples = 300 blocks of 4: evaluations at blocks 60, 72, ..., 300 (every 12
    # blocks once the 60-block window is full), the last one on the last block
    t = np.arange(1200) / rate
    for f in (0.9, 1.8, 2.9):
        x = 1.5 * np.sin(2 * np.pi * f * t)
        det = CadenceDetector(rate_hz=rate)
        walk, freq, r = det.periodicity(x)
        assert np.all(walk[t > 4.0] == 1)
        np.testing.assert_allclose(freq[t > 4.0], f, rtol=0.03)
        dec, wn, lmin, lmax, hop = (int(v) for v in det._ipars)
        assert (dec, wn, hop) == (4, 60, 12)
        blocks = x.reshape(-1, dec).mean(axis=1)
        ref = slow_autocorr(blocks[-wn:], lmin, lmax)
        # the reported r is the slow r at the lag nearest the step period, and close to
        # the best r over all lags
        lag = 25.0 / freq[-1]
        near = [ref[k] for k in (int(np.floor(lag)), int(np.ceil(lag))) if k in ref]
        assert min(abs(r[-1] - v) for v in near) < 1e-9
        assert r[-1] >= 0.85 * max(ref.values())


def test_cadence_stride_periodicity_gives_step_frequency() -> None:
    # steps alternate in amplitude (left/right): the autocorrelation peaks at the stride
    t = np.arange(0, 12.0, 0.01)
    x = np.sin(2 * np.pi * 1.6 * t) * (1.0 + 0.3 * np.sin(2 * np.pi * 0.8 * t))
    _, freq, _ = CadenceDetector().periodicity(x)
    np.testing.assert_allclose(freq[t > 5], 1.6, rtol=0.05)


def test_cadence_noise_and_stillness_are_not_walking() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(0, 20.0, 0.01)
    noise = rng.normal(0.0, 0.5, t.size)  # white: no periodicity
    walk, _, _ = CadenceDetector().periodicity(noise)
    # chance level: the best of ~25 lags of a 60-sample autocorrelation of white noise
    # (sd ~ 1/sqrt(60)) rarely reaches r_threshold = 0.4
    assert np.mean(walk[t > 4]) < 0.15
    tiny = 0.02 * np.sin(2 * np.pi * 1.8 * t)  # periodic but far below min_std
    walk, _, _ = CadenceDetector().periodicity(tiny)
    assert not np.any(walk)


def test_cadence_combined_state_slow_walk_and_pocket_walk() -> None:
    t = np.arange(0, 10.0, 0.01)
    slow = 1.0 * np.sin(2 * np.pi * 1.5 * t)
    det = CadenceDetector()
    res = det.update(slow, np.full(t.size, 0.7), still_threshold_m_s2=1.5,
                     run_threshold_m_s2=5.0)
    assert np.all(res.state[t > 4] == WALK)  # Basso alone says still
    pocket = 8.0 * np.sin(2 * np.pi * 1.9 * t)
    res = CadenceDetector().update(pocket, np.full(t.size, 5.6), still_threshold_m_s2=1.5,
                                   run_threshold_m_s2=5.0)
    assert np.all(res.state[t > 4] == WALK)  # Basso alone says running
    run = 8.0 * np.sin(2 * np.pi * 2.9 * t)
    res = CadenceDetector().update(run, np.full(t.size, 5.6), still_threshold_m_s2=1.5,
                                   run_threshold_m_s2=5.0)
    assert np.all(res.state[t > 4] == RUN)
    res = CadenceDetector().update(np.zeros(t.size), np.zeros(t.size),
                                   still_threshold_m_s2=1.5, run_threshold_m_s2=5.0)
    assert np.all(res.state == STILL)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), split=st.integers(1, 1199))
def test_cadence_chunked_equals_whole_and_state_roundtrip(seed: int, split: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0, 12.0, 0.01)
    x = rng.uniform(0.3, 2.0) * np.sin(2 * np.pi * rng.uniform(0.8, 3.0) * t) + rng.normal(
        0, 0.2, t.size)
    whole = CadenceDetector().periodicity(x)
    a = CadenceDetector()
    first = a.periodicity(x[:split])
    b = CadenceDetector()
    b.from_dict(json.loads(json.dumps(a.to_dict())))
    second = b.periodicity(x[split:])
    for w, p1, p2 in zip(whole, first, second, strict=True):
        np.testing.assert_array_equal(w, np.concatenate([p1, p2]))


def test_cadence_bad_parameters() -> None:
    with pytest.raises(InputError):
        CadenceDetector(CadenceParams(window_s=1.0, max_step_s=1.2))
    with pytest.raises(InputError):
        CadenceDetector(CadenceParams(r_threshold=0.0))
    with pytest.raises(InputError):
        CadenceDetector().from_dict({"buf": [0.0], "ints": [0, 0, 0, 0, 0],
                                     "floats": [0.0, None, -1.0]})


def test_gate_keeps_slow_walker_steps() -> None:
    """A slow walker (vertical spread below Basso's 1.5 m/s^2) keeps the steps when gated."""
    rng = np.random.default_rng(3)
    p = SimPerson.random(rng)
    w = simulate([(0, 5), (1, 30), (0, 5)], person=p, q_bd=random_mounting(rng), seed=3)
    scale = 0.6  # shrink the dynamic part: a shuffling, slow walk
    g = np.median(w.acc_d[w.t < 4], axis=0)
    acc = g + scale * (w.acc_d - g)
    base = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=w.q_bd).process(w.t, acc, w.q_nd)
    gated = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=w.q_bd,
                         gate_steps_with_motion=True).process(w.t, acc, w.q_nd)
    assert len(base.steps) > 40
    assert len(gated.steps) >= len(base.steps) - 2
    # without the periodicity test Basso's threshold drops the steps of this walk
    sigma = base.motion_sigma_m_s2[(w.t > 10) & (w.t < 30)]
    if np.median(sigma) < 1.5:
        basso = GaitAnalyzer(rate_hz=100.0, mounting_q_bd=w.q_bd, cadence=None,
                             gate_steps_with_motion=True).process(w.t, acc, w.q_nd)
        assert len(basso.steps) < len(gated.steps)
    # no steps kept in the still parts
    te = gated.steps.t_end
    assert np.sum(te < 3.0) == 0


def test_yaw_heading_chunked_equals_offline(walk) -> None:
    """Steps whose start or end lies before a chunk read the yaw kept from earlier chunks."""
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "heading": "yaw"}
    whole = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd)
    ga = GaitAnalyzer(**kw)
    parts = []
    bounds = [*range(0, len(walk.t), 97), len(walk.t)]
    for a, b in itertools.pairwise(bounds):
        parts.append(ga.update(walk.t[a:b], walk.acc_d[a:b], walk.q_nd[a:b]))
    parts.append(ga.flush())
    joined = GaitResult.concat(parts)
    np.testing.assert_allclose(joined.steps.t_end, whole.steps.t_end, atol=1e-9)
    np.testing.assert_allclose(np.cos(joined.steps.heading_rad),
                               np.cos(whole.steps.heading_rad), atol=1e-9)
    np.testing.assert_allclose(np.sin(joined.steps.heading_rad),
                               np.sin(whole.steps.heading_rad), atol=1e-9)
    np.testing.assert_allclose(joined.step_excursion_m, whole.step_excursion_m, atol=1e-12)


def test_gated_peak_steps_chunked_equals_offline(walk) -> None:
    """Small chunks: steps reported after the chunk holding their end still see the gate."""
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "gate_steps_with_motion": True}
    whole = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd)
    ga = GaitAnalyzer(**kw)
    parts = []
    bounds = [*range(0, len(walk.t), 23), len(walk.t)]
    for a, b in itertools.pairwise(bounds):
        parts.append(ga.update(walk.t[a:b], walk.acc_d[a:b], walk.q_nd[a:b]))
    parts.append(ga.flush())
    assert_same(GaitResult.concat(parts), whole)


def test_pll_enable_floor_runs_the_loop_early_and_stays_chunk_exact(walk) -> None:
    kw = {"rate_hz": 100.0, "mounting_q_bd": walk.q_bd, "step_detector": PllStepDetector(),
          "pll_enable_m_s2": 0.3}
    whole = GaitAnalyzer(**kw).process(walk.t, walk.acc_d, walk.q_nd)
    te = whole.steps.t_end
    true = walk.step_t
    walking = (true > 4.0) & (true < 29.0)
    assert abs(int(np.sum((te > 4.0) & (te < 29.0))) - int(np.sum(walking))) <= 4
    assert np.sum(te < 3.5) == 0  # standing still at the start: no steps
    kw["step_detector"] = PllStepDetector()
    joined = run_with_restarts(lambda: GaitAnalyzer(**{**kw, "step_detector": PllStepDetector()}),
                               walk.t, walk.acc_d, walk.q_nd, [0, 700, 701, 2222, len(walk.t)])
    assert_same(joined, whole)
    with pytest.raises(InputError):
        GaitAnalyzer(rate_hz=100.0, pll_enable_m_s2=-1.0)
