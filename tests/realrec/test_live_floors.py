"""The barometric floor stage inside the causal tracker: live estimates carry height and floor."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from hrtls.evaluate.floors import floor_detection
from hrtls.fusion.baro_floors import (
    BaroFloorParams,
    baro_floors,
    baro_floors_update,
    walking_flags,
)
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.chunks import split_session
from hrtls.sim.barometer import altitude_to_pressure


def test_any_split_of_the_pressure_gives_the_same_floors() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 240.0, 0.04)
    z = np.clip((t - 60.0) * 0.3, 0.0, 3.0) + np.clip((t - 160.0) * 0.3, 0.0, 3.0)
    p = altitude_to_pressure(z + 250.0) + rng.normal(0.0, 3.0, len(t)) + np.where(t > 120, 40, 0)
    ends = t[::25][(t[::25] > 55) & (t[::25] < 75)]
    whole = baro_floors(t, p, step_times_s=ends)
    cuts = np.r_[0, np.sort(rng.choice(np.arange(1, len(t)), 30, replace=False)), len(t)]
    state = None
    parts = []
    for a, b in pairwise(cuts):
        state, out = baro_floors_update(state, t[a:b], p[a:b], walking_flags(t[a:b], ends),
                                        params=BaroFloorParams())
        parts.append(out)
    assert np.array_equal(np.concatenate([o.z_m for o in parts]), whole.z_m)
    assert np.array_equal(np.concatenate([o.floor for o in parts]), whole.floor)
    assert whole.changes == 2 and whole.floor[-1] == 2
    assert parts[-1].pressure_steps == whole.pressure_steps >= 1


@pytest.fixture(scope="module")
def mission():  # type: ignore[no-untyped-def]
    from hrtls.sim.scenarios import run_scenario

    return run_scenario("inderst_multifloor", 103).session


def test_live_rows_climb_with_the_barometer_and_match_the_offline_result(mission) -> None:  # type: ignore[no-untyped-def]
    """Seed 103 (not a development seed): chunks of 20 s, estimates read as they come."""
    session = mission
    assert session.pressure is not None and session.truth is not None
    cfg = preset("default")
    offline = Tracker(cfg).run(session)
    assert offline.report["floors"]["source"] == "barometer"
    assert offline.report["floors"]["floor_changes"] == 2
    fh = session.meta.floor_height_m
    floors = floor_detection(offline.trajectory, session.truth, session.checkpoints,
                             floor_height_m=fh)
    assert floors is not None and floors["time_share_correct_on_floors"] >= 0.99

    live = Tracker(cfg)
    live.start_session(session)
    t_read = -np.inf
    rows_t, rows_z, rows_floor = [], [], []
    for chunk in split_session(session, 20.0):
        live.update(chunk)
        est = live.estimates_since(t_read)
        if len(est) > 1:   # the last row may still be replaced
            rows_t.append(est.t[:-1])
            rows_z.append(est.xyz[:-1, 2])
            rows_floor.append(est.floor[:-1])
            t_read = float(est.t[-2])
    t = np.concatenate(rows_t)
    z = np.concatenate(rows_z)
    floor = np.concatenate(rows_floor)
    # the live rows themselves go up a floor and back down (0 -> 1 -> 0)
    assert floor[0] == 0 and floor.max() == 1 and floor[-1] == 0
    assert np.count_nonzero(np.diff(floor)) >= 2
    tr = offline.trajectory
    idx = np.searchsorted(tr.t, t)
    assert np.array_equal(tr.t[idx], t)
    np.testing.assert_allclose(z, tr.xyz[idx, 2], atol=1e-9)
    assert np.array_equal(floor, np.rint(tr.xyz[idx, 2] / fh).astype(np.int64))


def test_snapshot_mid_climb_continues_the_floor_filter(mission) -> None:  # type: ignore[no-untyped-def]
    session = mission
    cfg = preset("default")
    chunks = list(split_session(session, 20.0))
    whole = Tracker(cfg)
    whole.start_session(session)
    half = len(chunks) // 2
    for chunk in chunks[:half]:
        whole.update(chunk)
    restored = Tracker.restore(whole.snapshot())
    assert restored.baro is not None and restored.baro.filter is not None
    for chunk in chunks[half:]:
        whole.update(chunk)
        restored.update(chunk)
    a, b = whole.finish(), restored.finish()
    t0 = b.trajectory.t[0]
    sel = a.trajectory.t >= t0
    np.testing.assert_array_equal(a.trajectory.xyz[sel, 2], b.trajectory.xyz[:, 2])
    assert a.report["floors"]["floor_changes"] == 2


def test_barometer_off_keeps_the_step_model_heights(mission) -> None:  # type: ignore[no-untyped-def]
    cfg = preset("default").model_copy(update={"barometer": False})
    result = Tracker(cfg).run(mission)
    assert result.report["floors"]["source"] == "step model (barometer off)"
