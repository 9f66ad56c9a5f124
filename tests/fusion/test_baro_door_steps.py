"""Door pressure steps against the barometric floor machine: a door step comes back, a floor
change needs a sustained climb (issue 19)."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.fusion.baro_floors import (
    BaroFloorParams,
    BaroFloors,
    baro_floors,
    baro_floors_update,
)
from hrtls.sim.barometer import altitude_to_pressure

RATE_HZ = 10.0
FIXTURE = Path(__file__).parent / "data" / "baro_door_step_walking_flat.npz"


def door(t: np.ndarray, *, t0_s: float, size_m: float, duration_s: float,
         rise_s: float = 1.0) -> np.ndarray:
    """Apparent height of a door step: ramps up over ``rise_s``, back down ``duration_s`` later."""
    up = np.clip((t - t0_s) / rise_s, 0.0, 1.0)
    down = np.clip((t - t0_s - duration_s) / rise_s, 0.0, 1.0)
    return np.asarray(size_m * (up - down))


def flat_walk(t: np.ndarray) -> np.ndarray:
    """Step end times of a walk at 1.8 steps/s over all of ``t``."""
    return np.arange(t[0] + 0.55, t[-1], 0.55)


def track(t: np.ndarray, z: np.ndarray, *, walk: np.ndarray | None,
          stairs_dz_m: float = 0.0, height_m: float = 3.0) -> BaroFloors:
    ends = None if walk is None else walk
    starts = None if walk is None else walk - 0.55
    dz = None if walk is None else np.full(len(walk), stairs_dz_m)
    return baro_floors(t, altitude_to_pressure(z + 300.0),
                       params=BaroFloorParams(floor_height_m=height_m),
                       step_times_s=ends, step_starts_s=starts, step_dz_m=dz)


def recorded_door_step() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.load(FIXTURE)
    n = len(d["half_pa"])
    t = float(d["t0_s"]) + float(d["dt_s"]) * np.arange(n)
    return t, float(d["p0_pa"]) + d["half_pa"] / 2.0, d["walking"]


def test_recorded_door_step_while_walking_flat_keeps_the_floor() -> None:
    """R1 of the two-floor hybrid mission, development seed 0, 130-200 s: a door step of about
    1.7 m for 3 s at 164 s while walking on floor 0 (pressure in the simulated barometer's
    0.5 Pa counts, walking flags from the tracker's steps); it used to raise the floor for good."""
    t, p, walking = recorded_door_step()
    _, r = baro_floors_update(None, t, p, walking, params=BaroFloorParams(floor_height_m=3.3))
    assert r.changes == 0
    assert np.abs(r.z_m[t > 172.0]).max() < 0.5  # the altitude came back with the door
    assert 1.2 < r.z_m.max() < 1.98               # the step itself is seen, below 0.6 floors


def test_recorded_door_step_any_split_gives_the_same_floors() -> None:
    t, p, walking = recorded_door_step()
    params = BaroFloorParams(floor_height_m=3.3)
    _, whole = baro_floors_update(None, t, p, walking, params=params)
    for cuts in ([0, 340, 345, 365, len(t)], [0, 1, 355, 356, len(t)]):
        state, zs = None, []
        for a, b in pairwise(cuts):
            state, out = baro_floors_update(state, t[a:b], p[a:b], walking[a:b], params=params)
            zs.append(out.z_m)
        assert np.array_equal(np.concatenate(zs), whole.z_m)


def test_a_short_door_step_walking_flat_is_no_floor() -> None:
    """1.3 m for 3 s, rising within 1 s (1.3 m/s: not removed while walking): 0.43 floors."""
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    r = track(t, door(t, t0_s=20.0, size_m=1.3, duration_s=3.0), walk=flat_walk(t))
    assert r.changes == 0
    assert r.z_m.max() > 1.0                   # kept while walking: seen, then gone
    assert np.abs(r.z_m[t > 27.0]).max() < 0.2


def test_a_door_step_while_standing_is_removed() -> None:
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    r = track(t, door(t, t0_s=20.0, size_m=1.3, duration_s=3.0), walk=None)
    assert r.changes == 0
    assert r.pressure_steps == 2                # opening and closing
    assert np.abs(r.z_m).max() < 0.5


def test_a_flight_is_one_floor_with_and_without_stair_steps() -> None:
    """3 m in 10 s (0.3 m/s) walking; the step model calls the steps stairs (dz 0.165 m) or
    misses them (dz 0)."""
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    z = np.clip((t - 20.0) * 0.3, 0.0, 3.0)
    for dz in (0.165, 0.0):
        r = track(t, z, walk=flat_walk(t), stairs_dz_m=dz)
        assert r.changes == 1 and r.floor[-1] == 1, dz
        assert r.z_m[-1] == pytest.approx(3.0, abs=0.1)


def test_a_door_step_on_a_flight_keeps_the_flight() -> None:
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    z = np.clip((t - 20.0) * 0.3, 0.0, 3.0) + door(t, t0_s=24.0, size_m=-1.0, duration_s=3.0,
                                                   rise_s=0.3)
    r = track(t, z, walk=flat_walk(t), stairs_dz_m=0.165)
    assert r.changes == 1 and r.floor[-1] == 1


def test_an_elevator_ride_is_two_floors() -> None:
    """Standing, 6 m at 1.2 m/s (5 s: longer than a door step's ``max_step_s``)."""
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    r = track(t, np.clip((t - 20.0) * 1.2, 0.0, 6.0), walk=None)
    assert r.floor[-1] == 2 and r.floor[t < 20.0].max() == 0
    assert r.z_m[-1] == pytest.approx(6.0, abs=0.1)


@settings(max_examples=30, deadline=None)
@given(doors=st.lists(st.tuples(st.floats(-0.45, 0.45), st.floats(0.3, 5.0),
                                 st.floats(0.2, 1.0)), min_size=1, max_size=3),
       height=st.floats(2.8, 4.0), seed=st.integers(0, 2**16))
def test_door_steps_on_a_flat_walk_never_change_the_floor(
        doors: list[tuple[float, float, float]], height: float, seed: int) -> None:
    """Door steps of up to 0.45 floor heights lasting up to 5 s, 25 s apart, 2 Pa of noise."""
    t = np.arange(0.0, 30.0 + 25.0 * len(doors), 1.0 / RATE_HZ)
    z = np.zeros(len(t))
    rng = np.random.default_rng(seed)
    for k, (frac, duration, rise) in enumerate(doors):
        z += door(t, t0_s=10.0 + 25.0 * k + rng.uniform(0.0, 10.0), size_m=frac * height,
                  duration_s=duration, rise_s=rise)
    p = altitude_to_pressure(z + 300.0) + rng.normal(0.0, 2.0, len(t))
    ends = flat_walk(t)
    r = baro_floors(t, p, params=BaroFloorParams(floor_height_m=height), step_times_s=ends,
                    step_starts_s=ends - 0.55, step_dz_m=np.zeros(len(ends)))
    assert r.changes == 0
    assert np.abs(r.z_m[-50:]).max() < 0.25 * height


def test_a_state_saved_before_the_kept_excursion_is_continued() -> None:
    """A state of 11 scalars (snapshots from before) goes on as one with no kept excursion."""
    from dataclasses import replace

    t, p, walking = recorded_door_step()
    params = BaroFloorParams(floor_height_m=3.3)
    state, _ = baro_floors_update(None, t[:100], p[:100], walking[:100], params=params)
    assert state is not None and np.isnan(state.scalars[11]) and state.scalars[12] == 0.0
    old = replace(state, scalars=state.scalars[:11].copy())
    _, new_out = baro_floors_update(state, t[100:], p[100:], walking[100:], params=params)
    _, old_out = baro_floors_update(old, t[100:], p[100:], walking[100:], params=params)
    assert np.array_equal(new_out.z_m, old_out.z_m)
