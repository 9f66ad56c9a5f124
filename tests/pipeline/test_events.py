"""The compiled event loop does exactly what the Python fusion parts do one event at a time."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.fusion.floors import floor_level_update
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.rss import ChannelEstimator, PathLossModel, rss_update
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.pipeline import _events as ev
from hrtls.pipeline import preset
from hrtls.pipeline.tracker import Tracker

ACTS = [int(Activity.WALKING), int(Activity.STANDING), int(Activity.UPSTAIRS),
        int(Activity.DOWNSTAIRS), int(Activity.RUNNING)]


def params(mode_state: bool, chan: bool, has_imu: bool = True) -> np.ndarray:
    sp = StepPredictionParams(heading_mode="state" if mode_state else "input",
                              sigma_heading_increment_rad=0.01)
    prm = np.zeros(ev.N_PARAMS)
    prm[ev.P_Q_ALONG], prm[ev.P_Q_ACROSS], prm[ev.P_Q_VERT] = (sp.q_along, sp.q_across,
                                                               sp.q_vertical)
    prm[ev.P_STAIR_D], prm[ev.P_STAIR_H] = sp.stair_depth_m, sp.stair_height_m
    prm[ev.P_STAIRS_MODEL] = 1.0
    prm[ev.P_MODE_STATE] = float(mode_state)
    prm[ev.P_SIG_HEAD], prm[ev.P_SIG_HEAD_INC] = sp.sigma_heading_rad, 0.01
    prm[ev.P_FLOOR_SNAP], prm[ev.P_FLOOR_H], prm[ev.P_FLOOR_SIG] = 1.0, 3.0, 0.1
    prm[ev.P_CHI2_1], prm[ev.P_USE_CHI2] = 10.8, 1.0
    prm[ev.P_HEAD_KNOWN], prm[ev.P_HAS_IMU] = 1.0, float(has_imu)
    prm[ev.P_RW_SPEED], prm[ev.P_RW_VERT], prm[ev.P_RW_HEAD] = 1.0, 0.05, 0.5
    prm[ev.P_RSS_MIN_D], prm[ev.P_D0] = 0.5, 1.0
    prm[ev.P_RANGE_SIG], prm[ev.P_RANGE_MIN_D] = 0.5, 0.1
    cp = ChannelEstimator().params
    prm[ev.P_CHAN_EST] = float(chan)
    prm[ev.P_FORGET], prm[ev.P_CHAN_MIN_D] = cp.forgetting, cp.min_distance_m
    prm[ev.P_CHAN_MAX_VAR] = cp.max_position_var_m2
    prm[ev.P_ETA_LO], prm[ev.P_ETA_HI] = cp.eta_bounds
    prm[ev.P_CAP_A], prm[ev.P_CAP_ETA] = cp.sigma_a_prior_db**2, cp.sigma_eta_prior**2
    return prm, sp


step_st = st.tuples(st.floats(0.0, 1.5), st.floats(-math.pi, math.pi), st.floats(-0.2, 0.2),
                    st.sampled_from(ACTS), st.floats(1e-4, 0.1))


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(step_st, min_size=1, max_size=30), mode_state=st.booleans())
def test_step_kernel_equals_predict(steps: list[tuple[float, float, float, int, float]],
                                    mode_state: bool) -> None:
    prm, sp = params(mode_state, False)
    start = FilterState.initial(t=0.0, heading_rad=0.3)
    # Python: the tracker's per-step sequence
    state = start
    predictor = StepPredictor(sp)
    for i, (length, heading, dz, act, var) in enumerate(steps):
        if not state.has_input_heading:
            state = state.evolve(input_heading_rad=heading, has_input_heading=True)
        state = predictor.predict(state, t=float(i + 1), length_m=length, heading_rad=heading,
                                  dz_m=dz, activity=act, var_heading_rad2=var)
        if act in (int(Activity.WALKING), int(Activity.STANDING)):
            state, _ = floor_level_update(state, 3.0, gate_probability=None)
    # kernel
    n = len(steps)
    x, p = start.x.copy(), start.P.copy()
    sc = np.zeros(ev.N_SCALARS)
    sc[ev.S_T] = 0.0
    data = np.array([[a, b, c, d, e] for a, b, c, d, e in steps], dtype=np.float64)
    out = [np.empty(n), np.empty((n, 4)), np.empty((n, 4, 4)), np.empty(n, dtype=np.int64),
           np.empty(n, dtype=np.int64), np.empty(n), np.empty(n), np.empty(n)]
    ev.event_kernel(np.zeros(n, dtype=np.int64), np.arange(1.0, n + 1), data, prm, sc,
                    np.eye(2), x, p, *out)
    np.testing.assert_allclose(x[:3], state.x[:3], atol=1e-10)
    assert abs(math.remainder(x[3] - state.x[3], 2 * math.pi)) < 1e-10
    np.testing.assert_allclose(p, state.P, atol=1e-10)
    np.testing.assert_allclose(out[2], np.transpose(out[2], (0, 2, 1)), atol=0)


obs_st = st.tuples(st.booleans(), st.floats(0.0, 20.0), st.floats(0.0, 20.0),
                   st.floats(-90.0, -40.0), st.floats(0.2, 25.0))


@settings(max_examples=60, deadline=None)
@given(obs=st.lists(obs_st, min_size=1, max_size=20), chan=st.booleans(),
       has_imu=st.booleans())
def test_observation_kernel_equals_python(obs: list[tuple[bool, float, float, float, float]],
                                          chan: bool, has_imu: bool) -> None:
    from hrtls.fusion.random_walk import predict_random_walk

    prm, _ = params(True, chan, has_imu)
    model = PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=5.0)
    est = ChannelEstimator()
    cstate = est.start(model)
    start = FilterState.initial(t=0.0, xyz=(5.0, 5.0, 0.0), sigma_xy_m=2.0)
    state = start
    for i, (is_rss, ax, ay, value, rng) in enumerate(obs):
        t = float(i + 1)
        state = predict_random_walk(state, t) if not has_imu else state.evolve(t=t)
        a = np.array([ax, ay, 1.0])
        if is_rss:
            m = model
            if chan:
                d = float(np.linalg.norm(state.x[:2] - a[:2]))
                cstate, _ = est.update(cstate, rss_dbm=[value], distance_m=[d],
                                       distance_var_m2=float(np.trace(state.P[:2, :2])))
                m = cstate.model()
            state = rss_update(state, a, value, m, gate_probability=1 - 1e-3 * 1.0000001).state
        else:
            state = range_update(state, a, rng, float("nan"),
                                 params=RangeParams(gate_probability=1 - 1e-3 * 1.0000001)
                                 ).state
    n = len(obs)
    kind = np.array([ev.EV_RSS if o[0] else ev.EV_RANGE for o in obs], dtype=np.int64)
    data = np.full((n, 5), np.nan)
    for k, (is_rss, ax, ay, value, rng) in enumerate(obs):
        data[k, :3] = (ax, ay, 1.0)
        data[k, 3] = value if is_rss else rng
    prm[ev.P_CHI2_1] = float(__import__("scipy.stats", fromlist=["chi2"]).chi2.ppf(
        1 - 1e-3 * 1.0000001, 1))
    sc = np.zeros(ev.N_SCALARS)
    sc[ev.S_A], sc[ev.S_ETA], sc[ev.S_SIGMA_DB] = -60.0, 2.5, 5.0
    sc[ev.S_RESVAR] = 25.0
    x, p = start.x.copy(), start.P.copy()
    out = [np.empty(n), np.empty((n, 4)), np.empty((n, 4, 4)), np.empty(n, dtype=np.int64),
           np.empty(n, dtype=np.int64), np.empty(n), np.empty(n), np.empty(n)]
    ev.event_kernel(kind, np.arange(1.0, n + 1), data, prm, sc, cstate_cov0(est, model), x, p,
                    *out)
    np.testing.assert_allclose(x, state.x, atol=1e-8)
    np.testing.assert_allclose(p, state.P, atol=1e-8)


def cstate_cov0(est: ChannelEstimator, model: PathLossModel) -> np.ndarray:
    return est.start(model).cov.copy()


def test_tracker_uses_kernel_and_reports(office) -> None:  # type: ignore[no-untyped-def]
    res = Tracker(preset("default")).run(office.session)
    counts = res.report["corrections"]
    assert counts["rss"]["accepted"] > 100
    assert counts["range"]["accepted"] > 10
    kinds = {d.kind for d in res.diagnostics}
    assert {"rss", "range"} <= kinds
