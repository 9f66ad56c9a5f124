"""The compiled event loop does exactly what the Python fusion parts do one event at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.fusion.floors import floor_level_update
from hrtls.fusion.gating import chi2_threshold, kalman_update
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.rss import (
    ChannelEstimator,
    PathLossModel,
    RssScan,
    hyperbolic_wls,
    rss_update,
    scan_position,
)
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


def run_kernel(kind: np.ndarray, t: np.ndarray, data: np.ndarray, prm: np.ndarray,
               sc: np.ndarray, chan_cov: np.ndarray, x: np.ndarray, p: np.ndarray, *,
               scan: np.ndarray | None = None, var_t: np.ndarray | None = None,
               var_v: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Call the kernel with fresh output arrays; returns them by name."""
    n = len(kind)
    out = {"t": np.empty(n), "x": np.empty((n, 4)), "p": np.empty((n, 4, 4)),
           "act": np.empty(n, dtype=np.int64), "status": np.empty(n, dtype=np.int64),
           "nis": np.empty(n), "s": np.empty(n), "nu": np.empty(n), "aux": np.empty((n, 5)),
           "recent": np.empty((ev.N_RECENT, 2))}
    ev.event_kernel(kind, t, data, prm, sc, chan_cov, x, p, out["t"], out["x"], out["p"],
                    out["act"], out["status"], out["nis"], out["s"], out["nu"],
                    np.zeros((0, 4)) if scan is None else scan, out["aux"],
                    np.zeros(0) if var_t is None else var_t,
                    np.zeros(0) if var_v is None else var_v, out["recent"])
    return out


step_st = st.tuples(st.floats(0.0, 1.5), st.floats(-math.pi, math.pi), st.floats(-0.2, 0.2),
                    st.sampled_from(ACTS), st.floats(1e-4, 0.1))


small_turn_step_st = st.tuples(st.floats(0.0, 1.5), st.floats(0.0, 0.3), st.floats(-0.2, 0.2),
                              st.sampled_from(ACTS), st.floats(1e-4, 0.1))


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(step_st | small_turn_step_st, min_size=1, max_size=30),
       mode_state=st.booleans(), heading_known=st.booleans())
def test_step_kernel_equals_predict(steps: list[tuple[float, float, float, int, float]],
                                    mode_state: bool, heading_known: bool) -> None:
    prm, sp = params(mode_state, False)
    prm[ev.P_HEAD_KNOWN] = float(heading_known)
    start = FilterState.initial(t=0.0, heading_rad=0.3)
    # Python: the tracker's per-step sequence (a known start heading: the first step's heading
    # is the reference before the step; unknown: the predictor takes or adopts it)
    state = start
    predictor = StepPredictor(sp)
    for i, (length, heading, dz, act, var) in enumerate(steps):
        preset = heading_known and not state.has_input_heading
        if preset:
            state = state.evolve(input_heading_rad=heading, has_input_heading=True)
        state = predictor.predict(state, t=float(i + 1), length_m=length, heading_rad=heading,
                                  dz_m=dz, activity=act, var_heading_rad2=var)
        if preset:   # the preset reference is still one step's heading
            state = state.evolve(reference_pending=True)
        if act in (int(Activity.WALKING), int(Activity.STANDING)):
            state, _ = floor_level_update(state, 3.0, gate_probability=None)
    # kernel
    n = len(steps)
    x, p = start.x.copy(), start.P.copy()
    sc = ev.initial_scalars()
    sc[ev.S_T] = 0.0
    data = np.array([[a, b, c, d, e] for a, b, c, d, e in steps], dtype=np.float64)
    out = run_kernel(np.zeros(n, dtype=np.int64), np.arange(1.0, n + 1), data, prm, sc,
                     np.eye(2), x, p)
    np.testing.assert_allclose(x[:3], state.x[:3], atol=1e-10)
    assert abs(math.remainder(x[3] - state.x[3], 2 * math.pi)) < 1e-10
    np.testing.assert_allclose(p, state.P, atol=1e-10)
    np.testing.assert_allclose(out["p"], np.transpose(out["p"], (0, 2, 1)), atol=0)


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
    sc = ev.initial_scalars()
    sc[ev.S_A], sc[ev.S_ETA], sc[ev.S_SIGMA_DB] = -60.0, 2.5, 5.0
    sc[ev.S_RESVAR] = 25.0
    x, p = start.x.copy(), start.P.copy()
    out = run_kernel(kind, np.arange(1.0, n + 1), data, prm, sc, cstate_cov0(est, model), x, p)
    assert sc[ev.S_N_SOFT] == np.count_nonzero(out["status"] == ev.ST_ACCEPTED)
    assert sc[ev.S_N_STEPS] == 0 and sc[ev.S_N_SCANS] == 0
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


@settings(max_examples=50, deadline=None)
@given(steps=st.lists(step_st, min_size=1, max_size=25), scale=st.floats(0.8, 1.25),
       run_mult=st.floats(0.6, 1.6), yaw_offset=st.floats(-1.0, 1.0),
       with_var=st.booleans())
def test_step_scale_offset_and_variance_in_kernel(
        steps: list[tuple[float, float, float, int, float]], scale: float, run_mult: float,
        yaw_offset: float, with_var: bool) -> None:
    """Scaling, yaw offset and variance lookup inside the kernel = the tracker's old prep."""
    prm, _ = params(True, False)
    n = len(steps)
    t = np.arange(1.0, n + 1)
    raw = np.array([[a, b, c, d, np.nan] for a, b, c, d, _ in steps], dtype=np.float64)
    var_t = np.linspace(-0.3, n + 0.7, 7) if with_var else np.zeros(0)
    var_v = np.linspace(0.001, 0.05, 7) if with_var else np.zeros(0)
    # reference: data prepared in Python (as Tracker._run_kernel did before), neutral scalars
    prep = raw.copy()
    prep[:, 0] *= scale
    run = prep[:, 3] == int(Activity.RUNNING)
    prep[run, 0] *= run_mult
    prep[:, 1] += yaw_offset
    prep[:, 4] = np.interp(t, var_t, var_v) if with_var else np.nan
    start = FilterState.initial(t=0.0, heading_rad=0.3)
    x0, p0 = start.x.copy(), start.P.copy()
    sc0 = ev.initial_scalars()
    run_kernel(np.zeros(n, dtype=np.int64), t, prep, prm, sc0, np.eye(2), x0, p0)
    x1, p1 = start.x.copy(), start.P.copy()
    sc1 = ev.initial_scalars()
    sc1[ev.S_STEP_SCALE], sc1[ev.S_RUN_MULT], sc1[ev.S_YAW_OFFSET] = scale, run_mult, yaw_offset
    run_kernel(np.zeros(n, dtype=np.int64), t, raw, prm, sc1, np.eye(2), x1, p1,
               var_t=var_t, var_v=var_v)
    np.testing.assert_allclose(x1[:3], x0[:3], atol=1e-10)
    assert abs(math.remainder(x1[3] - x0[3], 2 * math.pi)) < 1e-10
    np.testing.assert_allclose(p1, p0, atol=1e-10)
    assert sc1[ev.S_PATH] == pytest.approx(float(np.sum(prep[:, 0])), abs=1e-9)
    assert sc1[ev.S_RUN_PATH] == pytest.approx(float(np.sum(prep[run, 0])), abs=1e-9)


def scan_params(mode: str, wls_cov: bool, model: PathLossModel) -> np.ndarray:
    prm, _ = params(True, False)
    prm[ev.P_SCAN_WLS] = float(mode == "wls")
    prm[ev.P_SCAN_WLS_COV] = float(wls_cov)
    prm[ev.P_SCAN_SIG_P] = 2.0
    prm[ev.P_CHI2_2] = chi2_threshold(2, GATE)
    prm[ev.P_PL_A], prm[ev.P_PL_ETA], prm[ev.P_PL_SIG] = model.a_dbm, model.eta, model.sigma_db
    return prm


def python_scan(state: FilterState, scan: RssScan, model: PathLossModel, mode: str,
                wls_cov: bool) -> tuple[FilterState, str, float]:
    """The tracker's Python scan path (Tarrio eq. 1-2, then jump or eq. 10-12)."""
    if len(scan.anchor) < 3:
        return state, "few", math.nan
    try:
        fix = scan_position(scan, model)
    except InputError:
        return state, "collinear", math.nan
    if mode == "wls":
        x = state.x.copy()
        x[:2] = fix.xy
        p = state.P.copy()
        p[:2, :] = 0.0
        p[:, :2] = 0.0
        p[:2, :2] = fix.cov
        return state.evolve(x=x, P=p), "wls", math.nan
    h = np.zeros((2, 4))
    h[0, 0] = h[1, 1] = 1.0
    r = fix.cov if wls_cov else np.eye(2) * 4.0
    res = kalman_update(state.x, state.P, h, r, fix.xy - state.x[:2], gate_probability=GATE,
                        angle_index=3)
    return state.evolve(x=res.x, P=res.P), res.diagnostics.status, res.diagnostics.nis


GATE = 0.997
anchor_st = st.tuples(st.floats(-5.0, 25.0), st.floats(-5.0, 25.0), st.floats(-95.0, -45.0),
                      st.integers(1, 4))


@settings(max_examples=120, deadline=None)
@given(anchors=st.lists(anchor_st, min_size=0, max_size=8), mode=st.sampled_from(["wls",
                                                                                   "kalman"]),
       wls_cov=st.booleans(), sigma_xy=st.floats(0.3, 20.0), collinear=st.booleans())
def test_scan_kernel_equals_python(anchors: list[tuple[float, float, float, int]], mode: str,
                                   wls_cov: bool, sigma_xy: float, collinear: bool) -> None:
    model = PathLossModel(a_dbm=-58.0, eta=2.3, sigma_db=4.5)
    if collinear:   # every anchor on one line
        anchors = [(a[0], 2.0 * a[0] + 1.0, a[2], a[3]) for a in anchors]
    xy = np.array([[a[0], a[1]] for a in anchors], dtype=np.float64).reshape(-1, 2)
    scan = RssScan(3.0, [f"a{i}" for i in range(len(anchors))],
                   np.column_stack([xy, np.zeros(len(anchors))]),
                   np.array([a[2] for a in anchors], dtype=np.float64),
                   np.array([a[3] for a in anchors], dtype=np.float64))
    start = FilterState.initial(t=1.0, xyz=(8.0, 9.0, 0.0), heading_rad=2.0,
                                sigma_xy_m=sigma_xy)
    ref, status, nis = python_scan(start.evolve(t=3.0), scan, model, mode, wls_cov)
    rows = np.column_stack([xy, scan.rss_dbm, scan.count]).reshape(-1, 4)
    x, p = start.x.copy(), start.P.copy()
    sc = ev.initial_scalars()
    sc[ev.S_T] = 1.0
    sc[ev.S_SCAN_BASE] = 10.0                   # absolute row indices are shifted by it
    data = np.array([[10.0, len(anchors), np.nan, np.nan, np.nan]])
    out = run_kernel(np.array([ev.EV_SCAN]), np.array([3.0]), data,
                     scan_params(mode, wls_cov, model), sc, np.eye(2), x, p, scan=rows)
    code = int(out["status"][0])
    expected = {"few": ev.ST_FEW, "collinear": ev.ST_COLLINEAR, "wls": ev.ST_WLS,
                "accepted": ev.ST_ACCEPTED, "rejected": ev.ST_GATE}[status]
    assert code == expected
    # rounding differences grow with the condition of the WLS normal matrix
    cond = _condition(xy, model.distance(scan.rss_dbm)) if status not in ("few",
                                                                          "collinear") else 1.0
    tol = 1e-13 * cond + 1e-9
    np.testing.assert_allclose(x, ref.x, rtol=tol, atol=tol)
    np.testing.assert_allclose(p, ref.P, rtol=tol, atol=tol)
    assert sc[ev.S_T] == 3.0
    if status in ("accepted", "rejected"):
        assert out["nis"][0] == pytest.approx(nis, rel=tol, abs=1e-9)
        np.testing.assert_allclose(out["aux"][0, :2], scan_position(scan, model).xy - start.x[:2],
                                   rtol=tol, atol=tol)


@settings(max_examples=150, deadline=None)
@given(pts=st.lists(st.tuples(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0),
                              st.floats(0.2, 30.0)), min_size=3, max_size=9),
       sigma_ln=st.floats(0.05, 1.0))
def test_wls_kernel_equals_hyperbolic_wls(pts: list[tuple[float, float, float]],
                                          sigma_ln: float) -> None:
    a = np.array([[p[0], p[1]] for p in pts])
    d = np.array([p[2] for p in pts])
    out = np.empty(5)
    ok = ev.hyperbolic_wls_kernel(a, d, sigma_ln, out)
    try:
        fix = hyperbolic_wls(a, d, sigma_ln=sigma_ln)
    except InputError:
        # the same test on rounding-level different sums: only near-degenerate cases may differ
        assert not ok or _condition(a, d) > 1e10
        return
    if not ok:
        assert _condition(a, d) > 1e10
        return
    scale = max(1.0, float(np.max(np.abs(fix.xy))))
    cond = _condition(a, d)
    tol = 1e-12 * cond * scale + 1e-9
    np.testing.assert_allclose(out[:2], fix.xy, rtol=0, atol=tol)
    np.testing.assert_allclose(out[2:], [fix.cov[0, 0], fix.cov[0, 1], fix.cov[1, 1]],
                               rtol=1e-12 * cond + 1e-9, atol=1e-12)


def _condition(a: np.ndarray, d: np.ndarray) -> float:
    """Condition number of H^T S^-1 H (as hyperbolic_wls forms it)."""
    ref = int(np.argmin(d))
    others = [i for i in range(len(d)) if i != ref]
    h = 2.0 * (a[others] - a[ref])
    s = np.diag(d[others] ** 4) + d[ref] ** 4
    info = h.T @ np.linalg.solve(s, h)
    w = np.linalg.eigvalsh(0.5 * (info + info.T))
    return float(w[-1] / w[0]) if w[0] > 0 else math.inf


@settings(max_examples=60, deadline=None)
@given(headings=st.lists(st.one_of(st.just(math.nan), st.floats(-3.0, 3.0)), min_size=1,
                         max_size=50))
def test_recent_heading_ring(headings: list[float]) -> None:
    """The ring holds the last N_RECENT finite raw headings; counters count steps."""
    prm, _ = params(True, False)
    n = len(headings)
    data = np.array([[0.7, h, 0.0, int(Activity.WALKING), np.nan] for h in headings])
    t = np.arange(1.0, n + 1)
    sc = ev.initial_scalars()
    sc[ev.S_YAW_OFFSET] = 0.4                  # the ring keeps headings before the offset
    start = FilterState.initial(t=0.0)
    out = run_kernel(np.zeros(n, dtype=np.int64), t, data, prm, sc, np.eye(2),
                     start.x.copy(), start.P.copy())
    finite = [(ti, h) for ti, h in zip(t.tolist(), headings, strict=True) if math.isfinite(h)]
    assert sc[ev.S_N_STEPS] == n and sc[ev.S_N_HEADINGS] == len(finite)
    c = len(finite)
    ring = out["recent"].tolist()
    if c > ev.N_RECENT:
        ring = ring[c % ev.N_RECENT:] + ring[:c % ev.N_RECENT]
    assert [tuple(r) for r in ring[:min(c, ev.N_RECENT)]] == finite[-ev.N_RECENT:]
