"""The grid stage on simulated infrastructure-only sessions: when it runs, when it steps aside."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.evaluate.metrics import position_errors
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.rss_grid import GridParams, causal_scans
from hrtls.pipeline import Tracker, TrackerConfig
from hrtls.pipeline.build import Notes
from hrtls.pipeline.grid_stage import GridStage
from hrtls.sim.simulation_result import SimulationResult

from .test_chunked import track_in_parts

NO_IMU = ("imu", "orientation", "pressure", "fixes", "tags", "ranges")


def _config(no_imu: str) -> TrackerConfig:
    cfg = TrackerConfig()
    return cfg.model_copy(update={"prediction": cfg.prediction.model_copy(
        update={"no_imu": no_imu})})


def test_rss_alone_runs_the_grid_one_row_per_scan(office: SimulationResult) -> None:
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    res = Tracker().run(s)
    assert any("grid filter" in n for n in res.report["notes"])
    # without a start pose the note names the grid filter's start, not the anchors' centroid
    unposed = s.with_parts(meta=s.meta.model_copy(update={"start_pose": None}))
    notes = Tracker().run(unposed).report["notes"]
    assert any("grid filter starts from the first scan" in n for n in notes)
    assert not any("starting at the centroid" in n for n in notes)
    tr = res.trajectory
    assert s.rss is not None and s.truth is not None
    assert len(tr) <= int((s.rss.t[-1] - s.rss.t[0]) / 0.5) + 2   # one row per 0.5 s scan
    np.testing.assert_allclose(tr.var_heading, UNIFORM_ANGLE_VAR_RAD2)
    grid = position_errors(tr, s.truth)[1]
    walk = position_errors(Tracker(_config("random-walk")).run(s).trajectory, s.truth)[1]
    # office_random_walk seed 3: p75 6.4 m against 10.5 m, p95 9.6 m against 34.0 m
    assert np.percentile(grid, 75) < 0.8 * np.percentile(walk, 75)
    assert np.percentile(grid, 95) < 0.5 * np.percentile(walk, 95)


def test_other_observations_keep_the_kalman_track(office: SimulationResult) -> None:
    s = office.session.with_parts(**{k: None for k in NO_IMU if k != "ranges"})
    res = Tracker().run(s)
    assert any("grid filter uses RSS only" in n for n in res.report["notes"])
    ref = Tracker(_config("random-walk")).run(s)
    np.testing.assert_allclose(res.trajectory.xyz, ref.trajectory.xyz)


def test_live_rows_are_the_final_rows(office: SimulationResult) -> None:
    from hrtls.pipeline.chunks import split_session

    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    tr = Tracker()
    tr.start_session(s)
    live_t, live_xy = [], []
    t_seen = -np.inf
    for chunk in split_session(s, 10.0):
        tr.update(chunk)
        est = tr.estimates_since(t_seen)
        live_t.append(est.t)
        live_xy.append(est.xyz[:, :2])
        if len(est.t):
            t_seen = float(est.t[-1])
    final = tr.finish().trajectory
    t = np.concatenate(live_t)
    assert len(t) > 100 and np.all(np.diff(t) > 0)
    k = np.searchsorted(final.t, t)
    np.testing.assert_allclose(final.t[k], t)
    np.testing.assert_allclose(final.xyz[k, :2], np.concatenate(live_xy), atol=1e-9)


def test_shadowing_discount_chunked_and_restored_equal_offline(office: SimulationResult) -> None:
    """``[prediction.grid] shadowing_time_s``: the last reading per anchor survives chunks and
    snapshots; tau > 0 changes the track."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, "shadowing_time_s": 1.0}})})
    offline = Tracker(cfg).run(s).trajectory
    plain = Tracker().run(s).trajectory
    assert len(plain) == len(offline) and not np.allclose(plain.xyz, offline.xyz)
    live = track_in_parts(cfg, s, chunk_s=7.0, restore_after=4).trajectory
    n = len(live)
    np.testing.assert_allclose(live.xyz, offline.xyz[-n:], atol=1e-9, rtol=0)


def test_bench_rss_alone_is_the_wls_kalman_track(office: SimulationResult) -> None:
    """Tarrio's "RSS alone" baseline (bench papers) is the WLS track, not the grid filter."""
    from hrtls.jobs.bench_metrics import rss_alone_config, rss_alone_session

    s = rss_alone_session(office.session).with_parts(fixes=None, tags=None, ranges=None)
    res = Tracker(rss_alone_config(TrackerConfig())).run(s)
    assert not any("grid filter" in n for n in res.report["notes"])
    wls = _config("random-walk")
    wls = wls.model_copy(update={"rss": wls.rss.model_copy(update={"mode": "wls"})})
    np.testing.assert_allclose(res.trajectory.xyz, Tracker(wls).run(s).trajectory.xyz)
    grid = Tracker(TrackerConfig().model_copy(update={"rss": wls.rss})).run(s)
    assert any("grid filter" in n for n in grid.report["notes"])


def test_bias_state_and_surveyed_offsets_chunked_and_restored_equal_offline(
        office: SimulationResult) -> None:
    """``[prediction.grid] bias_sigma_db`` and the anchors' ``rss_offset_db``: the offsets and
    their variances survive chunks and snapshots; each changes the track."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, "bias_sigma_db": 3.0,
                 "attenuation_probability": 0.2}})})
    lms = {k: lm.model_copy(update={"rss_offset_db": 2.0 if i % 2 else -1.0})
           if lm.kind in ("anchor", "beacon") else lm
           for i, (k, lm) in enumerate(s.landmarks.items())}
    surveyed = s.with_parts(landmarks=lms)
    plain = Tracker().run(s).trajectory
    offline = Tracker(cfg).run(s).trajectory
    offset = Tracker().run(surveyed).trajectory
    assert not np.allclose(plain.xyz, offline.xyz) and not np.allclose(plain.xyz, offset.xyz)
    for session in (s, surveyed):
        whole = Tracker(cfg).run(session).trajectory
        live = track_in_parts(cfg, session, chunk_s=7.0, restore_after=4).trajectory
        n = len(live)
        np.testing.assert_allclose(live.xyz, whole.xyz[-n:], atol=1e-9, rtol=0)


def test_persistent_velocity_chunked_and_restored_equal_offline(office: SimulationResult
                                                                ) -> None:
    """``[prediction.grid] velocity_time_s``: the velocity survives chunks and snapshots and
    changes the track; a snapshot without it (older) restores with a zero velocity."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, "velocity_time_s": 4.0}})})
    plain = Tracker().run(s).trajectory
    offline = Tracker(cfg).run(s).trajectory
    assert len(plain) == len(offline) and not np.allclose(plain.xyz, offline.xyz)
    live = track_in_parts(cfg, s, chunk_s=7.0, restore_after=4).trajectory
    n = len(live)
    np.testing.assert_allclose(live.xyz, offline.xyz[-n:], atol=1e-9, rtol=0)
    anchors = {k: lm for k, lm in s.landmarks.items() if lm.kind in ("anchor", "beacon")}
    stage = GridStage(anchors, model=PathLossModel(), params=GridParams(velocity_time_s=4.0),
                      t0=0.0, z_m=0.0, notes=Notes())
    stage.state.velocity_m_per_s[:] = (0.5, -0.25)
    d = stage.state_dict()
    assert d is not None
    stage.restore(d)
    np.testing.assert_array_equal(stage.state.velocity_m_per_s, [0.5, -0.25])
    stage.restore({k: v for k, v in d.items() if k != "velocity_m_per_s"})
    np.testing.assert_array_equal(stage.state.velocity_m_per_s, [0.0, 0.0])


def test_velocity_modes_and_burst_state_chunked_and_restored_equal_offline(
        office: SimulationResult) -> None:
    """``[prediction.grid]`` velocity modes and burst state survive chunks and snapshots and
    change the track; an older snapshot (one-mode density, no burst probabilities) restores
    as the modes sharing its density and the burst chain's stationary probability."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    cfg = TrackerConfig()
    keys = {"mode_turn_deg": 90.0, "stopped_mode": True, "burst_sigma_db": 10.0}
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, **keys}})})
    plain = Tracker().run(s).trajectory
    offline = Tracker(cfg).run(s).trajectory
    assert len(plain) == len(offline) and not np.allclose(plain.xyz, offline.xyz)
    live = track_in_parts(cfg, s, chunk_s=7.0, restore_after=4).trajectory
    n = len(live)
    np.testing.assert_allclose(live.xyz, offline.xyz[-n:], atol=1e-9, rtol=0)
    anchors = {k: lm for k, lm in s.landmarks.items() if lm.kind in ("anchor", "beacon")}
    params = GridParams(mode_turn_deg=90.0, stopped_mode=True, burst_sigma_db=10.0)
    stage = GridStage(anchors, model=PathLossModel(), params=params, t0=0.0, z_m=0.0,
                      notes=Notes())
    assert stage.state.density.shape[0] == params.n_modes == 5
    d = stage.state_dict()
    assert d is not None
    old = {k: v for k, v in d.items() if k != "burst_probability"}
    old["density"] = np.asarray(d["density"]).sum(axis=0)
    stage.restore(old)
    assert stage.state.burst_probability is None
    np.testing.assert_allclose(stage.state.modes(5), d["density"], rtol=1e-12)
    assert stage.filter is not None
    _, state = stage.filter.update(stage.state, causal_scans(
        np.array([0.2]), np.array([0]), np.array([-60.0]), n_anchors=len(anchors),
        scan_s=0.5, average_s=2.0, t_origin=0.0))
    assert state.burst_probability is not None and state.density.shape[0] == 5
    assert state.burst_probability[1] == pytest.approx(params.burst_start)


def test_lag_compensation_chunked_and_restored_equal_offline(office: SimulationResult) -> None:
    """``[prediction.grid] lag_compensation``: the scans' reading ages come from the buffered
    readings (no new state), so chunks and snapshots give the offline rows; it changes the
    track."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "grid": {**cfg.prediction.grid, "lag_compensation": 1.0}})})
    plain = Tracker().run(s).trajectory
    offline = Tracker(cfg).run(s).trajectory
    assert len(plain) == len(offline) and not np.allclose(plain.xyz, offline.xyz)
    live = track_in_parts(cfg, s, chunk_s=7.0, restore_after=4).trajectory
    n = len(live)
    np.testing.assert_allclose(live.xyz, offline.xyz[-n:], atol=1e-9, rtol=0)


def test_fixed_lag_smoother_chunked_and_restored_equal_offline(office: SimulationResult
                                                               ) -> None:
    """``[prediction.grid] smoother_lag_s``: the pending scans' densities survive chunks and
    snapshots; the rows are those of one run, late by the lag (fewer rows out before
    ``finish``); a lag longer than the recording gives the offline smoother's rows; velocity
    modes are refused."""
    s = office.session.with_parts(**dict.fromkeys(NO_IMU))

    def config(lag_s: float, smoother: bool = False, **grid: object) -> TrackerConfig:
        cfg = TrackerConfig()
        return cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
            "grid": {**cfg.prediction.grid, "smoother_lag_s": lag_s, **grid}}),
            "offline": cfg.offline.model_copy(update={"grid_smoother": smoother})})

    plain = Tracker().run(s).trajectory
    offline = Tracker(config(2.0)).run(s).trajectory
    np.testing.assert_allclose(offline.t, plain.t)
    assert not np.allclose(plain.xyz, offline.xyz)
    live = track_in_parts(config(2.0), s, chunk_s=7.0, restore_after=4).trajectory
    n = len(live)
    assert n < len(offline)
    np.testing.assert_allclose(live.xyz, offline.xyz[-n:], atol=1e-9, rtol=0)
    np.testing.assert_allclose(live.cov_xy, offline.cov_xy[-n:], atol=1e-9, rtol=0)
    tr = Tracker(config(2.0))
    tr.start_session(s)
    tr.update(s)
    # rows wait for a scan more than 2 s after them
    shown = tr.estimates_since()
    assert len(shown) < len(plain) and shown.t[-1] < plain.t[-1] - 2.0
    whole = Tracker(config(1e6)).run(s)
    smoothed = Tracker(config(0.0, smoother=True)).run(s)
    np.testing.assert_allclose(whole.trajectory.xyz, smoothed.trajectory.xyz, atol=1e-9)
    assert smoothed.report["offline"]["grid_smoother"] is True
    with pytest.raises(InputError, match=r"smoother_lag_s.*velocity mode"):
        Tracker(config(2.0, mode_turn_deg=90.0)).run(s)
