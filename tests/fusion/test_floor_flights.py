"""The flight rule (floors from stairs steps without a barometer): hand-computed flights,
isolated misclassified stair steps, and the simulated two-floor mission with and without one."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.evaluate.floors import floor_detection
from hrtls.fusion.floors import FLIGHT_STATE, FlightParams, flight_step

H = 3.0
UP, DOWN, FLAT = 0.25, -0.25, 0.0


def run(steps: list[float], *, floor: float = 0.0, params: FlightParams | None = None
        ) -> tuple[list[float], list[bool]]:
    """Floors after each step and the pull flags; ``steps``: dz (0: a step that is no stairs)."""
    fp = params or FlightParams()
    state = np.array([floor, floor, 0.0, 0.0, 0.0, 0.0, 0.0])
    floors, pulls = [], []
    for dz in steps:
        pulls.append(flight_step(state, dz, dz != 0.0, H, fp.change_fraction,
                                 float(fp.end_flat_steps), fp.direction_fraction))
        floors.append(float(state[1]))
    return floors, pulls


def test_state_layout() -> None:
    assert len(FLIGHT_STATE) == 7 and FLIGHT_STATE[1] == "floor"


def test_a_flight_changes_the_floor_at_change_fraction_of_its_height() -> None:
    # 0.6 * 3 m = 1.8 m: 7 steps of 0.25 m (1.75 m) are not enough, the 8th (2.0 m) is
    floors, pulls = run([UP] * 12 + [FLAT] * 12)
    assert floors[:7] == [0.0] * 7 and floors[7:] == [1.0] * 17
    assert pulls[7] and not any(pulls[:7]) and not any(pulls[8:23])
    assert pulls[23]       # the 12th flat step ends the flight: z to floor 1 from then on
    floors, _ = run([DOWN] * 8, floor=2.0)
    assert floors[-1] == 1.0


def test_two_floors_in_one_flight() -> None:
    # (1 + 0.6) * 3 m = 4.8 m: the 20th step of 0.25 m (5.0 m); the 19th is 4.75 m
    floors, _ = run([UP] * 20)
    assert floors[18] == 1.0 and floors[19] == 2.0


def test_steps_missed_inside_a_flight_count_while_half_are_stairs() -> None:
    # 4 up, 3 not labelled stairs, then the 5th up: n = 5, g = 3, climb = 0.25 * 8 = 2.0 m
    floors, pulls = run([UP] * 4 + [FLAT] * 3 + [UP])
    assert floors == [0.0] * 7 + [1.0] and pulls[-1]
    assert not any(pulls[4:7])                     # the landing pulls nothing
    # 2 up, 9 flat, 1 up: n = 3, g = 9 counts as 3 only (half stairs): 1.5 m, no change
    floors, _ = run([UP] * 2 + [FLAT] * 9 + [UP])
    assert floors[-1] == 0.0


def test_up_down_confusion_counts_in_the_majority_direction() -> None:
    # 6 up and 2 down in one flight (three quarters up): 2.0 m up
    floors, _ = run([UP, UP, DOWN, UP, UP, DOWN, UP, UP])
    assert floors[-1] == 1.0
    floors, _ = run([UP, DOWN] * 4)          # 1.75 m after 7 steps, then a tie: no change
    assert set(floors) == {0.0}
    # 8 down change the floor; 9 labelled up after it still count down (17 steps, 4.25 m)
    floors, _ = run([DOWN] * 8 + [UP] * 9, floor=1.0)
    assert floors[7:] == [0.0] * 10


def test_a_flight_ends_after_end_flat_steps() -> None:
    fp = FlightParams(end_flat_steps=3)
    # 4 up (1.0 m), 3 flat end the flight, 4 up again: a new flight of 1.0 m, no change
    floors, pulls = run([UP] * 4 + [FLAT] * 3 + [UP] * 4, params=fp)
    assert set(floors) == {0.0} and pulls[6] and not pulls[5]
    # with the default 12 the same steps are one flight: 2.0 m, floor 1
    floors, _ = run([UP] * 4 + [FLAT] * 3 + [UP] * 4)
    assert floors[-1] == 1.0


def test_params_are_checked() -> None:
    with pytest.raises(InputError, match="change_fraction"):
        FlightParams(change_fraction=0.3)
    with pytest.raises(InputError, match="end_flat_steps"):
        FlightParams(end_flat_steps=0)


cluster = st.lists(st.floats(-0.2, 0.2).filter(lambda v: abs(v) > 1e-3), min_size=1,
                   max_size=3)


@settings(max_examples=80, deadline=None)
@given(clusters=st.lists(cluster, max_size=12),
       gaps=st.lists(st.integers(12, 40), min_size=12, max_size=12),
       start=st.integers(-2, 3))
def test_flat_walking_with_isolated_stair_steps_never_changes_the_floor(
        clusters: list[list[float]], gaps: list[int], start: int) -> None:
    """Up to 3 misclassified stair steps (at most 0.2 m each) between runs of >= 12 flat
    steps: a flight's climb is at most 2 * 3 * 0.2 m = 1.2 m < 0.6 * 3 m."""
    steps: list[float] = [FLAT] * gaps[0]
    for c, gap in zip(clusters, gaps, strict=False):
        steps += c + [FLAT] * gap
    floors, pulls = run(steps, floor=float(start))
    assert set(floors) <= {float(start)}
    assert pulls[-1]        # back on the floor's level after every cluster


# ---------------------------------------------------------------- the simulated mission
def _mission(seed: int, *, barometer: bool, activity: str) -> float:
    from hrtls.pipeline import Tracker, preset
    from hrtls.sim.scenarios import run_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = run_scenario("inderst_multifloor", seed).session
        cfg = preset("default")
        cfg = cfg.model_copy(update={"barometer": barometer, "gait": cfg.gait.model_copy(
            update={"activity": activity})})
        result = Tracker(cfg).run(session)
    f = floor_detection(result.trajectory, session.truth, None,
                        floor_height_m=session.meta.floor_height_m)
    assert f is not None
    return float(f["time_share_correct_on_floors"])


@pytest.mark.parametrize("seed", [0, 2])
def test_stairs_alone_move_the_floor_on_the_two_floor_mission(seed: int) -> None:
    """Development seeds 0 and 2 (LDA labels half of a flight as walking): the floor follows
    the two flights up and the two down without a barometer."""
    assert _mission(seed, barometer=False, activity="lda") >= 0.97


@pytest.mark.parametrize("seed", [100, 116])
def test_barometer_keeps_the_flights_with_door_steps(seed: int) -> None:
    """Seeds 100 and 116 (looked at: a door's pressure step on a flight swallowed the flight,
    0.62 and 0.88 before): every floor right with the barometer and motion activity."""
    assert math.isclose(_mission(seed, barometer=True, activity="motion"), 1.0)


def test_a_snapshot_from_before_the_flight_rule_restores() -> None:
    """Snapshots without the flight rule's and the barometer's step state (taken before they
    were kept) continue; the multi-floor mission with its barometer, split in two chunks."""
    from hrtls.pipeline import Tracker, preset
    from hrtls.pipeline import snapshot as snap
    from hrtls.pipeline.chunks import session_window
    from hrtls.sim.scenarios import run_scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = run_scenario("inderst_multifloor", 1).session
        first, rest = (session_window(session, -np.inf, 150.0),
                       session_window(session, 150.0, np.inf))
        assert first is not None and rest is not None
        tracker = Tracker(preset("default"))
        tracker.start_session(session)
        tracker.update(first)
        d = snap.unpack(tracker.snapshot())
        del d["engine"]["flight"], d["baro"]["step_starts"], d["baro"]["step_dz"]
        old = Tracker.restore(snap.pack(d))
        old.update(rest)
        result = old.finish()
    f = floor_detection(result.trajectory, session.truth, None,
                        floor_height_m=session.meta.floor_height_m)
    assert f is not None and f["time_share_correct_on_floors"] >= 0.99
