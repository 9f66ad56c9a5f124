"""Stairs from the vertical climb per step: a hand-made climb, chunks and old states, the
simulated two-floor mission without a barometer, real flat walks."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from tests.gait._chunks import run_with_restarts

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.analyzer_state import PendingGait
from hrtls.gait.pll import StepDetection
from hrtls.gait.stairs_climb import ClimbParams, climb_height_kernel, climb_labels
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.pipeline import Tracker, preset

STEP_S = 0.55
CLIMB_M_S = 0.3  # 0.165 m a step of 0.55 s


def climb_profile() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertical acceleration: still 10 s, a 2 cm bob a step: level 20 s, 11 steps up, level 15 s.

    The climb starts and stops at heel strikes; the velocity ramps over 0.2 s around them.
    Returns sample times, acceleration plus a 0.15 m/s^2 bias, and the step boundaries.
    """
    dt = 0.01
    t = np.arange(0.0, 30.0 + 11 * STEP_S + 15.0, dt)
    t0, t1 = 30.0, 30.0 + 11 * STEP_S
    ramp = 0.1
    vz = CLIMB_M_S * np.clip((t - t0 + ramp) / (2 * ramp), 0, 1) * np.clip(
        (t1 + ramp - t) / (2 * ramp), 0, 1)
    w = 2 * np.pi / STEP_S
    bob = 0.02 * np.sin(w * t) * (t >= 10.0)  # standing 10 s, then walking from a heel strike
    a = np.gradient(vz + np.gradient(bob, t), t) + 0.15
    bounds = 30.0 + STEP_S * np.arange(-34, 37)
    return t, a, bounds


def test_climb_per_step_hand_computed() -> None:
    t, a, bounds = climb_profile()
    st = PendingGait().climb
    h = np.empty_like(t)
    p = ClimbParams()
    climb_height_kernel(t, a, st, p.bias_s, p.leak_s, p.max_gap_s, h)
    dh = np.interp(bounds + STEP_S, t, h) - np.interp(bounds, t, h)
    on = (bounds >= 30.0 - 1e-9) & (bounds < 30.0 + 11 * STEP_S - 1e-9)
    # 0.3 m/s for 0.55 s: 0.165 m a step above the level steps before it; the running mean
    # of the bias (20 s) takes 0.3 m/s / 20 s of the velocity a second: the 11th step
    # (5.5 s on) keeps 0.165 (1 - 5.5 / 20) = 0.12 m
    before = np.mean(dh[(bounds > 25.0) & (bounds < 30.0 - 1e-9)])
    rel = dh[on] - before
    assert rel[0] == pytest.approx(CLIMB_M_S * STEP_S, abs=0.015)  # half a ramp before it
    # (the last step also holds half the ramp down)
    np.testing.assert_allclose(rel[:-1], CLIMB_M_S * STEP_S * (1 - (bounds[on][:-1] - 30.0)
                                                              / 20.0), atol=0.015)
    assert np.ptp(dh[bounds < 30.0 - 1e-9]) < 0.01  # level: the bob cancels step by step
    steps = StepDetection(bounds, bounds + STEP_S, np.full(len(bounds), 1 / STEP_S),
                          np.zeros(len(bounds)), np.zeros(len(bounds)))
    act = np.full(len(bounds), int(Activity.WALKING))
    labels = climb_labels(act, steps, dh, st, p)
    expected = np.where(on, int(Activity.UPSTAIRS), int(Activity.WALKING))
    np.testing.assert_array_equal(labels, expected)


def test_parameters_are_checked() -> None:
    with pytest.raises(InputError, match="threshold_m"):
        ClimbParams(threshold_m=0.0)


def test_chunks_and_restored_states_equal_offline() -> None:
    rng = np.random.default_rng(3)
    w = simulate([(0, 4), (1, 20), (3, 10), (1, 10), (4, 10), (0, 4)],
                 person=SimPerson.random(rng), q_bd=random_mounting(rng), seed=3)

    def make() -> GaitAnalyzer:
        return GaitAnalyzer(rate_hz=100.0, mounting_q_bd=w.q_bd, climb=ClimbParams())

    whole = make().process(w.t, w.acc_d, w.q_nd)
    joined = run_with_restarts(make, w.t, w.acc_d, w.q_nd,
                               [0, 137, 1500, 1501, 4000, 5555, len(w.t)])
    np.testing.assert_array_equal(joined.steps.activity, whole.steps.activity)
    np.testing.assert_array_equal(joined.steps.dz_m, whole.steps.dz_m)
    # a state written before the climb detector restores (its held steps: no climb)
    ga = make()
    ga.update(w.t[:3000], w.acc_d[:3000], w.q_nd[:3000])
    state = json.loads(json.dumps(ga.state()))
    for key in ("vb_h", "climb", "climbs"):
        del state["pending"][key]
    old = make()
    old.restore(state)
    rest = old.update(w.t[3000:], w.acc_d[3000:], w.q_nd[3000:])
    assert len(rest.steps) > 0


def test_two_floor_mission_without_barometer() -> None:
    """Seed 101 (not a development seed of the detector; figures: benchmarks/floors.py)."""
    from hrtls.evaluate.floors import floor_detection
    from hrtls.sim.scenarios import run_scenario

    session = run_scenario("inderst_multifloor", 101).session
    assert session.meta.placement in preset("default").gait.climb_placements
    for climb in (True, False):
        cfg = preset("default")
        cfg = cfg.model_copy(update={"barometer": False, "gait": cfg.gait.model_copy(
            update={"climb_stairs": climb})})
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = Tracker(cfg).run(session)
        f = floor_detection(result.trajectory, session.truth, session.checkpoints,
                            floor_height_m=session.meta.floor_height_m)
        assert f is not None
        act = result.steps.activity
        stairs = (act == Activity.UPSTAIRS) | (act == Activity.DOWNSTAIRS)
        if climb:
            assert f["time_share_correct_on_floors"] >= 0.95
            assert 30 <= np.sum(stairs) <= 50  # 40 stairs: two flights of 10 up, two down
        else:  # the motion activity alone labels no stairs: the floor never changes
            assert not np.any(stairs)
            assert f["time_share_correct_on_floors"] < 0.6


def longest_run(flags: np.ndarray) -> int:
    run = best = 0
    for v in flags:
        run = run + 1 if v else 0
        best = max(best, run)
    return best


def test_flat_real_walks_change_no_floor(shared_data: Path) -> None:
    """Mobilise-D lab trials (lower back, flat; straight walks and simulated daily life)."""
    from hrtls.datasets.mobgap import list_trials, load_trial
    from hrtls.fusion.floors import floor_index

    root = shared_data / "mobgap_lab"
    if not root.exists():
        pytest.skip("mobgap recordings not available")
    cfg = preset("default").model_copy(update={"barometer": False})
    trials = list_trials(root)
    assert len(trials) >= 9
    for trial in trials:
        session = load_trial(root, trial.participant, trial.test, trial.trial).session
        assert session.meta.placement in cfg.gait.climb_placements
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = Tracker(cfg).run(session)
        act = result.steps.activity
        stairs = (act == Activity.UPSTAIRS) | (act == Activity.DOWNSTAIRS)
        floors = floor_index(result.trajectory.xyz[:, 2], session.meta.floor_height_m or 3.0)
        assert np.all(floors == floors[0]), trial
        if trial.test == "Test5":  # straight walks: no stair step
            assert not np.any(stairs), trial
        assert longest_run(stairs) <= 3, trial


def test_hand_held_phone_has_no_climb_detector(shared_data: Path) -> None:
    path = shared_data / "ipin2023" / "IPIN2023_T3_TrainingTrial04_repetition01.txt"
    if not path.exists():
        pytest.skip("ipin2023 recordings not available")
    from hrtls.recordings import read_any

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        session = read_any(path)
        cfg = preset("default").model_copy(update={"barometer": False})
        act = Tracker(cfg).run(session).steps.activity
    assert session.meta.placement == "hand"
    assert not np.any((act == Activity.UPSTAIRS) | (act == Activity.DOWNSTAIRS))
