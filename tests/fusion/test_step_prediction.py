from __future__ import annotations

import numpy as np
import pytest

from hrtls.data.results import Activity, StepEvents
from hrtls.errors import InputError
from hrtls.fusion.gating import is_spd
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import (
    FIRST_STRIDE_MAX_TURN_RAD,
    StepPredictionParams,
    StepPredictor,
)


def start() -> FilterState:
    return FilterState.initial(sigma_xy_m=0.1, sigma_heading_rad=0.01)


def test_standing_adds_nothing() -> None:
    s0 = start()
    s1 = StepPredictor().predict(s0, t=1.0, length_m=0.7, heading_rad=0.3,
                                 activity=int(Activity.STANDING))
    np.testing.assert_array_equal(s1.x[:3], s0.x[:3])
    np.testing.assert_array_equal(s1.P[:3, :3], s0.P[:3, :3])
    assert s1.t == 1.0


def test_walking_step_hand_computed() -> None:
    prm = StepPredictionParams(q_along=0.01, q_across=0.0, q_vertical=0.0)
    s0 = FilterState(0.0, np.zeros(4), np.zeros((4, 4)))
    s1 = StepPredictor(prm).predict(s0, t=0.5, length_m=2.0, heading_rad=np.pi / 2,
                                    var_heading_rad2=0.0)
    np.testing.assert_allclose(s1.x[:3], [0.0, 2.0, 0.0], atol=1e-12)
    # Q = |l|^2 R diag(q_along, 0, 0) R^T: along y only, 4 * 0.01
    np.testing.assert_allclose(s1.P[:2, :2], [[0.0, 0.0], [0.0, 0.04]], atol=1e-12)
    # heading variance maps to the across-track direction: G var G^T with G = L [-sin, cos]
    s2 = StepPredictor(prm).predict(s0, t=0.5, length_m=2.0, heading_rad=0.0,
                                    var_heading_rad2=0.01)
    assert s2.P[1, 1] == pytest.approx(4.0 * 0.01)
    assert s2.P[0, 0] == pytest.approx(0.04)


def test_stairs_follow_eq_4_25() -> None:
    prm = StepPredictionParams(stair_depth_m=0.3, stair_height_m=0.17)
    pred = StepPredictor(prm)
    s = start()
    for i in range(10):
        s = pred.predict(s, t=float(i + 1), length_m=0.7, heading_rad=0.0,
                         activity=int(Activity.UPSTAIRS))
    assert s.x[2] == pytest.approx(1.7)
    assert s.x[0] == pytest.approx(3.0)
    s = pred.predict(s, t=20.0, length_m=0.7, heading_rad=0.0, activity=int(Activity.DOWNSTAIRS))
    assert s.x[2] == pytest.approx(1.53)
    measured = StepPredictor(StepPredictionParams(stairs_from_model=False))
    s2 = measured.predict(start(), t=1.0, length_m=0.25, heading_rad=0.0, dz_m=0.2,
                          activity=int(Activity.UPSTAIRS))
    assert s2.x[2] == pytest.approx(0.2) and s2.x[0] == pytest.approx(0.25)


def test_run_over_steps_square_and_covariance_growth() -> None:
    n = 40
    heading = np.repeat([0.0, np.pi / 2, np.pi, -np.pi / 2], 10)
    steps = StepEvents.build(t_start=np.arange(n) * 0.5, t_end=np.arange(n) * 0.5 + 0.5,
                             length_m=np.full(n, 1.0), heading_rad=heading)
    res = StepPredictor().run(start(), steps)
    np.testing.assert_allclose(res.xyz[-1], [0.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(res.xyz[9], [10.0, 0.0, 0.0], atol=1e-9)
    traces = np.trace(res.P[:, :2, :2], axis1=1, axis2=2)
    assert np.all(np.diff(traces) > 0)
    assert all(is_spd(p) for p in res.P)


def test_state_mode_keeps_heading_corrections() -> None:
    pred = StepPredictor(StepPredictionParams(heading_mode="state"))
    s = pred.predict(start(), t=1.0, length_m=1.0, heading_rad=0.2)
    assert s.heading == pytest.approx(0.0)          # first step: reference only
    assert s.reference_pending
    s = s.evolve(x=np.array([*s.x[:3], 0.5]))        # a correction to the heading
    s = pred.predict(s, t=2.0, length_m=1.0, heading_rad=0.3)
    assert s.heading == pytest.approx(0.55)          # first stride: half the change 0.1
    assert not s.reference_pending
    s = pred.predict(s, t=3.0, length_m=1.0, heading_rad=0.4)
    assert s.heading == pytest.approx(0.65)          # then every change in full
    inp = StepPredictor().predict(s, t=4.0, length_m=1.0, heading_rad=0.3)
    assert inp.heading == pytest.approx(0.3)         # input mode: heading is the parameter


def test_a_start_into_a_turn_keeps_the_whole_second_step_change() -> None:
    pred = StepPredictor(StepPredictionParams(heading_mode="state"))
    turn = FIRST_STRIDE_MAX_TURN_RAD + 0.05
    s = pred.predict(start(), t=1.0, length_m=1.0, heading_rad=0.2)
    s = pred.predict(s, t=2.0, length_m=1.0, heading_rad=0.2 + turn)
    assert s.heading == pytest.approx(turn)


def test_pending_reference_survives_save_and_restore() -> None:
    pred = StepPredictor(StepPredictionParams(heading_mode="state"))
    s = pred.predict(start(), t=1.0, length_m=1.0, heading_rad=0.2)
    back = FilterState.from_dict(s.to_dict())
    assert back.reference_pending and back.has_input_heading
    assert not FilterState.from_dict({k: v for k, v in s.to_dict().items()
                                      if k != "reference_pending"}).reference_pending


def test_bad_steps_raise() -> None:
    pred = StepPredictor()
    s = start().evolve(t=5.0)
    with pytest.raises(InputError):
        pred.predict(s, t=4.0, length_m=0.7, heading_rad=0.0)
    with pytest.raises(InputError):
        pred.predict(s, t=6.0, length_m=-1.0, heading_rad=0.0)
    with pytest.raises(InputError):
        StepPredictionParams(heading_mode="bogus")  # type: ignore[arg-type]


def test_unknown_heading_uses_state() -> None:
    s = start().evolve(x=np.array([0.0, 0.0, 0.0, 1.0]))
    s1 = StepPredictor().predict(s, t=1.0, length_m=1.0, heading_rad=float("nan"))
    np.testing.assert_allclose(s1.x[:2], [np.cos(1.0), np.sin(1.0)])


def test_state_mode_adopts_first_heading_when_start_heading_unknown() -> None:
    s = FilterState.initial(sigma_heading_rad=np.pi)
    pred = StepPredictor(StepPredictionParams(heading_mode="state", sigma_heading_rad=0.05))
    s1 = pred.predict(s, t=1.0, length_m=1.0, heading_rad=1.0)
    assert s1.heading == pytest.approx(1.0)
    assert s1.var_heading == pytest.approx(0.05**2 + 0.0, rel=1e-9)
    np.testing.assert_allclose(s1.x[:2], [np.cos(1.0), np.sin(1.0)])
