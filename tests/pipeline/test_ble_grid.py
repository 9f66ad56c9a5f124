"""RSS alone on the position-annotated BLE tracks: the grid filter through the tracker."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from hrtls.data import Session
from hrtls.datasets.ble_rssi import load_trajectory
from hrtls.evaluate.metrics import position_errors
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.pipeline import Tracker, TrackerConfig
from hrtls.pipeline.chunks import split_session
from hrtls.pipeline.finish import finish_track

pytestmark = pytest.mark.realdata

TRACKS = ("rectangular_with_rotation", "rectangular_without_rotation", "straight_01",
          "straight_02", "straight_03")


def _session(shared_data: Path, name: str) -> Session:
    root = shared_data / "ble_rssi"
    if not root.is_dir():
        pytest.skip("BLE RSSI dataset not available")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_trajectory(root, name).session


def _config(no_imu: str) -> TrackerConfig:
    cfg = TrackerConfig()
    return cfg.model_copy(update={"prediction": cfg.prediction.model_copy(
        update={"no_imu": no_imu})})


def test_grid_beats_the_random_walk_and_starts_where_the_readings_say(shared_data: Path
                                                                     ) -> None:
    p75 = {"grid": [], "random-walk": []}
    for name in TRACKS:
        s = _session(shared_data, name)
        for mode, values in p75.items():
            res = finish_track(Tracker(_config(mode)).run(s), s, _config(mode))
            err = position_errors(res.trajectory, s.truth)[1]
            values.append(float(np.percentile(err, 75)))
            if mode == "grid":
                # the first row is the first scan's estimate: near the walker, not at (0, 0)
                assert err[0] < 5.0, name
                assert res.report["heading"]["observable"] is False
                np.testing.assert_allclose(res.trajectory.var_heading, UNIFORM_ANGLE_VAR_RAD2)
    grid, walk = np.array(p75["grid"]), np.array(p75["random-walk"])
    # default grid: mean 2.31, worst 2.62 m; random walk: mean 3.49, worst 4.52 m
    assert grid.mean() < walk.mean() - 0.2 and grid.max() < walk.max() - 0.5
    assert grid.max() < 2.8


def test_chunks_and_snapshot_give_the_rows_of_one_run(shared_data: Path) -> None:
    s = _session(shared_data, "straight_03")
    whole = Tracker().run(s).trajectory
    tr = Tracker()
    tr.start_session(s)
    chunks = list(split_session(s, 7.0))
    for chunk in chunks[:3]:
        tr.update(chunk)
    tr = Tracker.restore(tr.snapshot())
    for chunk in chunks[3:]:
        tr.update(chunk)
    part = tr.finish().trajectory
    tail = whole.t >= part.t[0]
    np.testing.assert_allclose(part.t, whole.t[tail])
    np.testing.assert_allclose(part.xyz, whole.xyz[tail], atol=1e-9)
    np.testing.assert_allclose(part.cov_xy, whole.cov_xy[tail], atol=1e-9)


# the leave-one-out choice of `python benchmarks/ble_rss.py` for each held-out track (settings
# over the defaults; every fold keeps the default channel, none the surveyed one) and its
# held-out p75, m
HELD_OUT = {
    "rectangular_with_rotation": ({}, 2.58),
    "rectangular_without_rotation": ({"sigma_speed_m_per_sqrt_s": 0.8}, 2.51),
    "straight_01": ({"sigma_speed_m_per_sqrt_s": 0.8}, 1.89),
    "straight_02": ({"sigma_speed_m_per_sqrt_s": 0.8}, 2.71),
    "straight_03": ({}, 2.12),
}


@pytest.mark.parametrize("name", TRACKS)
def test_held_out_p75_with_the_leave_one_out_choice(shared_data: Path, name: str) -> None:
    """The per-track held-out p75 of the leave-one-out choice (every fold: persistent velocity
    and bias state; issue 19 goal 2.5 m: not met on rectangular with rotation, 2.58 m,
    without rotation, 2.51 m, nor straight 02, 2.71 m)."""
    grid, p75 = HELD_OUT[name]
    assert _grid_p75(shared_data, name, grid) == pytest.approx(p75, abs=0.01)


def _grid_p75(shared_data: Path, name: str, grid: dict[str, object]) -> float:
    """p75 of the horizontal error of track ``name`` with the grid settings ``grid``, m."""
    s = _session(shared_data, name)
    cfg = TrackerConfig()
    cfg = cfg.model_copy(update={"prediction": cfg.prediction.model_copy(
        update={"grid": {**cfg.prediction.grid, **grid}})})
    err = position_errors(Tracker(cfg).run(s).trajectory, s.truth)[1]
    return float(np.percentile(err, 75))


# the same with the window statistic among the candidates (`python benchmarks/ble_rss.py
# --default-channel`): every fold takes the median or the mean power; held out it is worse on
# four tracks (p75 mean 2.36 -> 2.44 m), so the default keeps the mean in dBm
HELD_OUT_WINDOW = {
    "rectangular_with_rotation": ({"window_statistic": "median"}, 2.65),
    "rectangular_without_rotation": ({"sigma_speed_m_per_sqrt_s": 0.8, "velocity_time_s": 16.0,
                                      "window_statistic": "mean-power"}, 2.57),
    "straight_01": ({"sigma_speed_m_per_sqrt_s": 0.8, "window_statistic": "median"}, 1.94),
    "straight_02": ({"sigma_speed_m_per_sqrt_s": 0.8, "window_statistic": "median"}, 2.62),
    "straight_03": ({"sigma_speed_m_per_sqrt_s": 2.0, "window_statistic": "mean-power"}, 2.43),
}


@pytest.mark.parametrize("name", TRACKS)
def test_held_out_p75_with_the_window_statistic_among_the_candidates(shared_data: Path,
                                                                     name: str) -> None:
    """Held-out p75 of the leave-one-out choice with ``window_statistic`` a candidate."""
    grid, p75 = HELD_OUT_WINDOW[name]
    assert _grid_p75(shared_data, name, grid) == pytest.approx(p75, abs=0.01)


# the same with the point estimate among the candidates (`python benchmarks/ble_rss.py
# --default-channel --estimate`): every fold takes the per-axis median; held out p75 mean /
# worst 2.36 / 2.71 -> 2.34 / 2.65 m, p95 worse on four tracks, so the default keeps the mean
HELD_OUT_MEDIAN = {
    "rectangular_with_rotation": ({"velocity_time_s": 16.0}, 2.55),
    "rectangular_without_rotation": ({"sigma_speed_m_per_sqrt_s": 0.8}, 2.49),
    "straight_01": ({"sigma_speed_m_per_sqrt_s": 0.8}, 1.79),
    "straight_02": ({"sigma_speed_m_per_sqrt_s": 0.8}, 2.65),
    "straight_03": ({}, 2.20),
}


@pytest.mark.parametrize("name", TRACKS)
def test_held_out_p75_with_the_median_point_estimate(shared_data: Path, name: str) -> None:
    """Held-out p75 of the leave-one-out choice with ``point_estimate`` a candidate."""
    grid, p75 = HELD_OUT_MEDIAN[name]
    p = _grid_p75(shared_data, name, {**grid, "point_estimate": "median"})
    assert p == pytest.approx(p75, abs=0.01)


# the same with the lag compensation among the candidates (`python benchmarks/ble_rss.py
# --default-channel --lag [--window]`, docs/results/ble_rss_lag.txt): every fold takes it;
# held-out p75 mean / worst 2.36 / 2.71 -> 2.36 / 2.59 m (with the window statistic too:
# 2.30 / 2.64 m, rectangular with rotation and straight 03 worse), so it stays off
HELD_OUT_LAG = {
    "rectangular_with_rotation": ({"velocity_time_s": 16.0, "lag_compensation": 1.0}, 2.59),
    "rectangular_without_rotation": ({"sigma_speed_m_per_sqrt_s": 0.8,
                                      "lag_compensation": 0.5}, 2.53),
    "straight_01": ({"sigma_speed_m_per_sqrt_s": 0.8, "lag_compensation": 0.5}, 1.82),
    "straight_02": ({"sigma_speed_m_per_sqrt_s": 0.8, "lag_compensation": 0.5}, 2.59),
    "straight_03": ({"sigma_speed_m_per_sqrt_s": 0.8, "bias_sigma_db": 5.0,
                     "lag_compensation": 0.5}, 2.27),
}
_MEDIAN_16 = {"velocity_time_s": 16.0, "window_statistic": "median"}
HELD_OUT_LAG_WINDOW = {
    "rectangular_with_rotation": ({**_MEDIAN_16, "lag_compensation": 1.0}, 2.64),
    "rectangular_without_rotation": ({**_MEDIAN_16, "lag_compensation": 1.0}, 2.23),
    "straight_01": ({**_MEDIAN_16, "lag_compensation": 1.0}, 1.78),
    "straight_02": ({**_MEDIAN_16, "lag_compensation": 0.5}, 2.44),
    "straight_03": ({"sigma_speed_m_per_sqrt_s": 2.0, "velocity_time_s": 16.0,
                     "window_statistic": "mean-power", "lag_compensation": 1.0}, 2.44),
}


@pytest.mark.parametrize("table", [HELD_OUT_LAG, HELD_OUT_LAG_WINDOW])
@pytest.mark.parametrize("name", TRACKS)
def test_held_out_p75_with_the_lag_compensation_among_the_candidates(
        shared_data: Path, name: str, table: dict[str, tuple[dict[str, object], float]]
) -> None:
    """Held-out p75 of the leave-one-out choice with ``lag_compensation`` a candidate."""
    grid, p75 = table[name]
    assert _grid_p75(shared_data, name, grid) == pytest.approx(p75, abs=0.01)


def _write_survey(shared_data: Path, names: list[str], path: Path) -> str:
    root = shared_data / "ble_rssi"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracks = [load_trajectory(root, n) for n in names]
    rows = ["x_m,y_m,anchor,rss_dbm"] + [
        f"{x!r},{y!r},{a},{r!r}" for tr in tracks
        for x, y, a, r in zip(tr.beacon_xyz[:, 0].tolist(), tr.beacon_xyz[:, 1].tolist(),
                              tr.anchor.tolist(), tr.rss_dbm.tolist(), strict=True)]
    path.write_text("\n".join(rows) + "\n")
    return str(path)


def _map_config(survey: str) -> TrackerConfig:
    cfg = TrackerConfig()
    return cfg.model_copy(update={"prediction": cfg.prediction.model_copy(update={
        "radio_map": {**cfg.prediction.radio_map, "survey": survey, "length_m": 4.0,
                      "prior_sigma_db": 3.0}})})


def test_radio_map_of_the_other_tracks_helps_the_held_out_track(shared_data: Path,
                                                                tmp_path: Path) -> None:
    # held out: rectangular_with_rotation; its fold's choice in `ble_rss.py --map`
    s = _session(shared_data, "rectangular_with_rotation")
    survey = _write_survey(shared_data, list(TRACKS[1:]), tmp_path / "survey.csv")
    res = Tracker(_map_config(survey)).run(s)
    assert any("radio map of" in n for n in res.report["notes"])
    p75 = float(np.percentile(position_errors(res.trajectory, s.truth)[1], 75))
    plain = float(np.percentile(position_errors(Tracker().run(s).trajectory, s.truth)[1], 75))
    # 2.45 m with the map against 2.58 m without
    assert p75 < plain - 0.05 and p75 < 2.5
    # a snapshot rebuilds the map from the file: the rows of one run
    tr = Tracker(_map_config(survey))
    tr.start_session(s)
    chunks = list(split_session(s, 20.0))
    tr.update(chunks[0])
    tr = Tracker.restore(tr.snapshot())
    for chunk in chunks[1:]:
        tr.update(chunk)
    part = tr.finish().trajectory
    tail = res.trajectory.t >= part.t[0]
    np.testing.assert_allclose(part.xyz, res.trajectory.xyz[tail], atol=1e-9)
