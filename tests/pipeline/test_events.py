"""The compiled event loop does exactly what the Python fusion parts do one event at a time.

Both call the same compiled functions of :mod:`hrtls.fusion` (their maths is checked against
readable references in ``tests/fusion/test_compiled_oracles.py``); these tests check the loop's
own work: event order, the start-heading preset, scale / offset / variance handling, counts,
outcome codes and the heading ring.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.fusion.channel import ChannelEstimator
from hrtls.fusion.fixes import FixParams
from hrtls.fusion.floors import FlightParams, flight_step, floor_level_update
from hrtls.fusion.gating import kalman_update
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.random_walk import RandomWalkParams, predict_random_walk
from hrtls.fusion.ranges import RangeParams, range_update
from hrtls.fusion.rss import rss_update
from hrtls.fusion.rss_scans import RssScan, scan_position
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.pipeline import _events as ev
from hrtls.pipeline import _fix_events as fx
from hrtls.pipeline import preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.step_scale import StepScaleParams
from hrtls.pipeline.tracker import Tracker

ACTS = [int(Activity.WALKING), int(Activity.STANDING), int(Activity.UPSTAIRS),
        int(Activity.DOWNSTAIRS), int(Activity.RUNNING)]


def params(mode_state: bool, chan: bool, has_imu: bool = True, *,
           gate_probability: float = 0.999, model: PathLossModel | None = None,
           scan_mode: str = "kalman", wls_cov: bool = False
           ) -> tuple[np.ndarray, StepPredictionParams]:
    """Loop parameters as the tracker builds them (floors of 3 m, 0.1 m snap)."""
    sp = StepPredictionParams(heading_mode="state" if mode_state else "input",
                              sigma_heading_increment_rad=0.01)
    prm = ev.loop_params(
        step=sp, path_loss=model or PathLossModel(), range_params=RangeParams(),
        channel=ChannelEstimator().params if chan else None, random_walk=RandomWalkParams(),
        floor_snap=True, floor_height_m=3.0, floor_sigma_m=0.1,
        gate_probability=gate_probability, heading_known=True, yaw_relative=False,
        has_imu=has_imu,
        rss_min_distance_m=0.5, scan_jump=scan_mode == "wls", scan_wls_covariance=wls_cov,
        scan_sigma_position_m=2.0)
    return prm, sp


def state_record(start: FilterState, **kw: object) -> tuple[np.ndarray, np.ndarray]:
    """Loop state at ``start`` with the default path-loss model unless given."""
    kw.setdefault("path_loss", PathLossModel())
    kw.setdefault("channel", None)
    return ev.loop_state(start, **kw)  # type: ignore[arg-type]


def _no_fix_state() -> np.ndarray:
    """Fix state of a run without fixes."""
    return fx.fix_state(phase_s=None, last_slot=None, rejections=0, corrected_since_fix=False,
                        has_memory=False, run_scale=1.0, anchor_xy=None,
                        path_since_anchor_m=0.0, run_since_anchor_m=0.0,
                        soft_since_anchor=False, last_heading_rad=math.nan,
                        last_row_t=math.nan)


def run_kernel(kind: np.ndarray, t: np.ndarray, data: np.ndarray, prm: np.ndarray,
               sc: np.ndarray, chan_cov: np.ndarray, x: np.ndarray, p: np.ndarray, *,
               scan: np.ndarray | None = None, var_t: np.ndarray | None = None,
               var_v: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Call the kernel with fresh output arrays; returns them by name."""
    n = len(kind)
    out = {"t": np.empty(n), "x": np.empty((n, 4)), "cov": np.empty((n, 2, 2)),
           "var_h": np.empty(n), "jump": np.empty((n, 2)),
           "act": np.empty(n, dtype=np.int64), "status": np.empty(n, dtype=np.int64),
           "nis": np.empty(n), "s": np.empty(n), "nu": np.empty(n), "aux": np.empty((n, 5)),
           "recent": np.empty((ev.N_RECENT, 2)), "pre": np.empty((n, 5))}
    ev.event_kernel(kind, t, data, prm, sc, chan_cov, x, p, out["t"], out["x"], out["cov"],
                    out["var_h"], out["act"], out["status"], out["nis"], out["s"], out["nu"],
                    np.zeros((0, 4)) if scan is None else scan, out["aux"],
                    np.zeros(0) if var_t is None else var_t,
                    np.zeros(0) if var_v is None else var_v, out["recent"],
                    fx.fix_params(TrackerConfig(), FixParams(), StepScaleParams(),
                                  running_factor=1.0), _no_fix_state(), np.zeros((0, 5)),
                    out["jump"], out["pre"])
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
    prm["heading_known"] = heading_known
    start = FilterState.initial(t=0.0, heading_rad=0.3)
    # Python: the tracker's per-step sequence (a known start heading: the first step's heading
    # is the reference before the step; unknown: the predictor takes or adopts it)
    state = start
    predictor = StepPredictor(sp)
    flight, fp = np.array(ev.NO_FLIGHT), FlightParams()
    for i, (length, heading, dz, act, var) in enumerate(steps):
        preset = heading_known and not state.has_input_heading
        if preset:
            state = state.evolve(input_heading_rad=heading, has_input_heading=True)
        state = predictor.predict(state, t=float(i + 1), length_m=length, heading_rad=heading,
                                  dz_m=dz, activity=act, var_heading_rad2=var)
        if preset:   # the preset reference is still one step's heading
            state = state.evolve(reference_pending=True)
        if i == 0:
            flight[0] = flight[1] = round((state.x[2] - dz) / 3.0)
        stairs = act in (int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS))
        pull = flight_step(flight, dz, stairs, 3.0, fp.change_fraction, fp.end_flat_steps,
                           fp.direction_fraction)
        if pull and (stairs or act in (int(Activity.WALKING), int(Activity.STANDING))):
            state, _ = floor_level_update(state, 3.0, gate_probability=None,
                                          floor=int(flight[1]))
    # kernel
    n = len(steps)
    x, p = start.x.copy(), start.P.copy()
    sc, cov = state_record(start)
    data = np.array([[a, b, c, d, e] for a, b, c, d, e in steps], dtype=np.float64)
    out = run_kernel(np.zeros(n, dtype=np.int64), np.arange(1.0, n + 1), data, prm, sc,
                     cov, x, p)
    np.testing.assert_allclose(x[:3], state.x[:3], atol=1e-12)
    assert abs(math.remainder(x[3] - state.x[3], 2 * math.pi)) < 1e-12
    np.testing.assert_allclose(p, state.P, atol=1e-12)
    np.testing.assert_allclose(out["cov"], np.transpose(out["cov"], (0, 2, 1)), atol=0)


def test_relative_input_yaw_is_aligned_to_the_start_heading() -> None:
    """Gyro-only yaw in heading_mode "input": its zero is arbitrary, so the first step's heading
    is mapped onto the known start heading (pi/2) and later headings keep their changes."""
    prm, _ = params(False, False)
    prm["yaw_relative"] = True
    start = FilterState.initial(t=0.0, heading_rad=math.pi / 2)
    x, p = start.x.copy(), start.P.copy()
    sc, cov = state_record(start)
    walk = int(Activity.WALKING)
    data = np.array([[1.0, 0.3, 0.0, walk, 1e-4], [1.0, 0.3 + math.pi / 2, 0.0, walk, 1e-4]])
    out = run_kernel(np.zeros(2, dtype=np.int64), np.array([1.0, 2.0]), data, prm, sc, cov, x, p)
    np.testing.assert_allclose(out["x"][0, :2], [0.0, 1.0], atol=1e-12)     # north, not 0.3 rad
    np.testing.assert_allclose(out["x"][1, :2], [-1.0, 1.0], atol=1e-12)    # then west
    assert sc[0]["yaw_offset_rad"] == pytest.approx(math.pi / 2 - 0.3)
    prm["yaw_relative"] = False                      # an absolute yaw is used as it is
    x, p = start.x.copy(), start.P.copy()
    sc, cov = state_record(start)
    out = run_kernel(np.zeros(1, dtype=np.int64), np.array([1.0]), data[:1], prm, sc, cov, x, p)
    np.testing.assert_allclose(out["x"][0, :2], [math.cos(0.3), math.sin(0.3)], atol=1e-12)


obs_st = st.tuples(st.booleans(), st.floats(0.0, 20.0), st.floats(0.0, 20.0),
                   st.floats(-90.0, -40.0), st.floats(0.2, 25.0))


@settings(max_examples=60, deadline=None)
@given(obs=st.lists(obs_st, min_size=1, max_size=20), chan=st.booleans(),
       has_imu=st.booleans())
def test_observation_kernel_equals_python(obs: list[tuple[bool, float, float, float, float]],
                                          chan: bool, has_imu: bool) -> None:
    gate = 1 - 1e-3 * 1.0000001
    model = PathLossModel(a_dbm=-60.0, eta=2.5, sigma_db=5.0)
    prm, _ = params(True, chan, has_imu, gate_probability=gate, model=model)
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
            state = rss_update(state, a, value, m, gate_probability=gate).state
        else:
            state = range_update(state, a, rng, float("nan"),
                                 params=RangeParams(gate_probability=gate)).state
    n = len(obs)
    kind = np.array([ev.EV_RSS if o[0] else ev.EV_RANGE for o in obs], dtype=np.int64)
    data = np.full((n, 5), np.nan)
    for k, (is_rss, ax, ay, value, rng) in enumerate(obs):
        data[k, :3] = (ax, ay, 1.0)
        data[k, 3] = value if is_rss else rng
    sc, cov = state_record(start, path_loss=model, channel=est.start(model))
    x, p = start.x.copy(), start.P.copy()
    out = run_kernel(kind, np.arange(1.0, n + 1), data, prm, sc, cov, x, p)
    assert sc["n_soft"][0] == np.count_nonzero(out["status"] == ev.ST_ACCEPTED)
    assert sc["n_steps"][0] == 0 and sc["n_scans"][0] == 0
    np.testing.assert_allclose(x, state.x, atol=1e-12)
    np.testing.assert_allclose(p, state.P, atol=1e-12)


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
    sc0, cov0 = state_record(start)
    run_kernel(np.zeros(n, dtype=np.int64), t, prep, prm, sc0, cov0, x0, p0)
    x1, p1 = start.x.copy(), start.P.copy()
    sc1, cov1 = state_record(start, step_scale=scale, running_multiplier=run_mult,
                             yaw_offset_rad=yaw_offset)
    run_kernel(np.zeros(n, dtype=np.int64), t, raw, prm, sc1, cov1, x1, p1,
               var_t=var_t, var_v=var_v)
    np.testing.assert_allclose(x1[:3], x0[:3], atol=1e-10)
    assert abs(math.remainder(x1[3] - x0[3], 2 * math.pi)) < 1e-10
    np.testing.assert_allclose(p1, p0, atol=1e-10)
    assert sc1["path_m"][0] == pytest.approx(float(np.sum(prep[:, 0])), abs=1e-9)
    assert sc1["running_path_m"][0] == pytest.approx(float(np.sum(prep[run, 0])), abs=1e-9)


def scan_params(mode: str, wls_cov: bool, model: PathLossModel) -> np.ndarray:
    return params(True, False, gate_probability=GATE, model=model, scan_mode=mode,
                  wls_cov=wls_cov)[0]


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
    sc, cov = state_record(start, scan_base=10)   # absolute row indices are shifted by it
    data = np.array([[10.0, len(anchors), np.nan, np.nan, np.nan]])
    out = run_kernel(np.array([ev.EV_SCAN]), np.array([3.0]), data,
                     scan_params(mode, wls_cov, model), sc, cov, x, p, scan=rows)
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
    assert sc["t"][0] == 3.0
    if status in ("accepted", "rejected"):
        assert out["nis"][0] == pytest.approx(nis, rel=tol, abs=1e-9)
        np.testing.assert_allclose(out["aux"][0, :2], scan_position(scan, model).xy - start.x[:2],
                                   rtol=tol, atol=tol)


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
    start = FilterState.initial(t=0.0)
    # the ring keeps headings before the offset
    sc, cov = state_record(start, yaw_offset_rad=0.4)
    out = run_kernel(np.zeros(n, dtype=np.int64), t, data, prm, sc, cov,
                     start.x.copy(), start.P.copy())
    finite = [(ti, h) for ti, h in zip(t.tolist(), headings, strict=True) if math.isfinite(h)]
    assert sc["n_steps"][0] == n and sc["n_headings"][0] == len(finite)
    c = len(finite)
    ring = out["recent"].tolist()
    if c > ev.N_RECENT:
        ring = ring[c % ev.N_RECENT:] + ring[:c % ev.N_RECENT]
    assert [tuple(r) for r in ring[:min(c, ev.N_RECENT)]] == finite[-ev.N_RECENT:]
