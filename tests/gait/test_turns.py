"""Turn segmentation on the vertical-axis rate (hrtls.gait.turns)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.frames import quat_from_euler, quat_multiply
from hrtls.gait.turns import TurnDetector, TurnParams, TurnState


def yaw_profile(t: np.ndarray, turns: list[tuple[float, float, float]]) -> np.ndarray:
    """Yaw (rad) with smooth (raised-cosine rate) turns ``(t_start, duration, angle_rad)``."""
    rate = np.zeros_like(t)
    for t0, dur, ang in turns:
        inside = (t >= t0) & (t < t0 + dur)
        rate[inside] += ang / dur * (1 - np.cos(2 * np.pi * (t[inside] - t0) / dur))
    return np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])


def tilted_attitude(t: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """q_nd = yaw about ENU z, then a fixed tilted mounting plus a small pelvis sway."""
    # sway of whole periods over the test spans (10 s, 20 s, 30 s): its own rotation about
    # the vertical integrates to zero
    sway = 0.08 * np.sin(2 * np.pi * 1.0 * t)
    q_yaw = quat_from_euler(sway, 0.3 + 0.5 * sway, yaw)
    tilt = quat_from_euler(0.4, -0.2, 1.0)
    return quat_multiply(q_yaw, np.broadcast_to(tilt, q_yaw.shape))


def test_vertical_rate_ignores_tilt_and_sums_to_the_yaw_change() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    yaw = yaw_profile(t, [(2.0, 2.0, np.pi / 2)])
    q = tilted_attitude(t, yaw)
    w = TurnDetector().vertical_rate(t, q)
    # the rotation about the vertical integrates to the yaw change despite tilt and sway
    total = float(np.sum(w[1:] * np.diff(t)))
    assert total == pytest.approx(yaw[-1] - yaw[0], abs=np.deg2rad(0.5))


def test_turns_hand_case_angles_and_times() -> None:
    t = np.arange(0.0, 30.0, 0.01)
    truth = [(3.0, 2.0, np.pi / 2), (10.0, 1.5, -np.pi), (20.0, 3.0, np.deg2rad(45))]
    q = tilted_attitude(t, yaw_profile(t, truth))
    ev = TurnDetector().process(t, q)
    assert len(ev) == 3
    for k, (t0, dur, ang) in enumerate(truth):
        assert ev.angle_rad[k] == pytest.approx(ang, abs=np.deg2rad(4.0))
        # the slow edges of a turn (rate below rate_low_rad_s) are outside it
        assert t0 - 0.2 <= ev.t_start[k] <= t0 + 0.6
        assert t0 + dur - 0.6 <= ev.t_end[k] <= t0 + dur + 0.2


def test_small_wobble_is_not_a_turn() -> None:
    t = np.arange(0.0, 20.0, 0.01)
    yaw = np.deg2rad(4.0) * np.sin(2 * np.pi * 0.9 * t)  # pelvis rotation while walking
    assert len(TurnDetector().process(t, tilted_attitude(t, yaw))) == 0


@settings(max_examples=25, deadline=None)
@given(split=st.integers(1, 2999), seed=st.integers(0, 1000))
def test_chunked_equals_whole_with_state_roundtrip(split: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 30.0, 0.01)
    turns = [(float(rng.uniform(2, 8)), 2.0, float(rng.uniform(-3, 3))),
             (float(rng.uniform(12, 25)), 1.5, float(rng.uniform(-3, 3)))]
    q = tilted_attitude(t, yaw_profile(t, turns))
    whole = TurnDetector().process(t, q)
    a = TurnDetector()
    first = a.update(t[:split], q[:split])
    b = TurnDetector()
    b.state = TurnState.from_dict(json.loads(json.dumps(a.state.to_dict())))
    second = b.update(t[split:], q[split:])
    for name in ("t_start", "t_end", "angle_rad"):
        np.testing.assert_allclose(np.concatenate([getattr(first, name),
                                                   getattr(second, name)]),
                                   getattr(whole, name), atol=1e-12)


def test_turn_input_errors() -> None:
    with pytest.raises(InputError):
        TurnDetector(TurnParams(rate_low_rad_s=1.0, rate_high_rad_s=0.5))
    det = TurnDetector()
    t = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(InputError):
        det.update_rate(t, np.full(t.size - 1, 0.1))
    with pytest.raises(InputError):
        det.update(t, np.zeros((t.size, 3)))
    with pytest.raises(InputError):
        TurnState.from_dict({"prev": [1.0]})


def test_reference_definition_keeps_only_turns_of_45_deg_and_0_5_to_10_s() -> None:
    t = np.arange(0.0, 60.0, 0.01)
    truth = [(3.0, 2.0, np.deg2rad(90.0)),    # kept
             (10.0, 1.0, np.deg2rad(30.0)),   # too small
             (15.0, 20.0, np.deg2rad(720.0)),  # too long (two slow spins)
             (45.0, 1.5, np.deg2rad(-60.0))]  # kept
    q = tilted_attitude(t, yaw_profile(t, truth))
    loose = TurnDetector().process(t, q)
    ref = TurnDetector(TurnParams.reference()).process(t, q)
    assert len(loose) == 4
    assert len(ref) == 2
    np.testing.assert_allclose(np.rad2deg(ref.angle_rad), [90.0, -60.0], atol=5.0)
    assert np.all((ref.t_end - ref.t_start >= 0.5) & (ref.t_end - ref.t_start <= 10.0))


def test_duration_parameters_validated() -> None:
    with pytest.raises(InputError):
        TurnDetector(TurnParams(min_duration_s=2.0, max_duration_s=1.0))
    with pytest.raises(InputError):
        TurnDetector(TurnParams(min_duration_s=-1.0))
    with pytest.raises(InputError):
        TurnDetector(TurnParams(max_duration_s=0.0))


def test_real_mobgap_turns_match_stereophoto(shared_data: Path) -> None:
    """MS/001 daily life: every Stereophoto turn >= 45 deg is found, angles mostly close."""
    from hrtls.attitude.complementary import ComplementaryFilter, ComplementaryParams
    from hrtls.datasets import mobgap

    folder = shared_data / "mobgap_lab"
    if not (folder / "MS" / "001" / "data.mat").is_file():
        pytest.skip("mobgap MS/001 not available")
    trial = mobgap.load_trial(folder, "MS/001", "Test11", "Trial1")
    s = trial.session
    assert s.imu is not None and s.imu.gyro is not None
    t = s.imu.accel.t
    q = ComplementaryFilter(ComplementaryParams(init_heading_from_mag=False)).update(
        t, s.imu.accel.values, s.imu.gyro.values).q
    ev = TurnDetector(TurnParams.reference()).process(t, q)
    ref = trial.reference.stereophoto
    assert ref is not None
    keep = np.abs(ref.turn_angle_deg) >= 45.0
    errs = []
    for a, b, ang in ref.turns[keep]:
        ov = np.minimum(b, ev.t_end) - np.maximum(a, ev.t_start)
        assert ov.size and ov.max() > 0, f"reference turn at {a:.1f} s not found"
        # signs agree: Turn_Angle > 0 is counter-clockwise seen from above, like hrtls
        errs.append(np.rad2deg(ev.angle_rad[int(np.argmax(ov))]) - ang)
    e = np.abs(np.asarray(errs))
    assert e.size >= 10
    assert np.median(e) < 12.0
    assert np.mean(e <= 25.0) >= 0.8


def test_flush_reports_the_turn_in_progress() -> None:
    t = np.arange(0.0, 5.0, 0.01)
    q = tilted_attitude(t, yaw_profile(t, [(3.0, 3.0, np.pi)]))  # still turning at the end
    det = TurnDetector()
    assert len(det.update(t, q)) == 0
    ev = det.flush()
    assert len(ev) == 1
    assert 0 < ev.angle_rad[0] < np.pi
    assert len(det.flush()) == 0  # flushing reset the state


def test_process_bouts_cuts_turns_at_bout_limits() -> None:
    t = np.arange(0.0, 20.0, 0.01)
    truth = [(3.0, 2.0, np.pi / 2), (12.0, 2.0, -np.pi / 2)]
    yaw = yaw_profile(t, truth)
    q = tilted_attitude(t, yaw)
    ev = TurnDetector().process_bouts(t, q, np.array([[0.0, 4.0], [6.0, 20.0]]))
    assert len(ev) == 2
    # first turn cut at the bout end: the angle is the yaw change up to 4 s
    assert ev.t_end[0] <= 4.0
    assert ev.angle_rad[0] == pytest.approx(yaw[400] - yaw[round(ev.t_start[0] * 100)],
                                            abs=np.deg2rad(3.0))
    assert ev.angle_rad[1] == pytest.approx(-np.pi / 2, abs=np.deg2rad(4.0))
    assert ev.t_start[1] >= 6.0 and ev.t_end[1] <= 20.0
    # nothing outside the bouts; empty bout list
    assert len(TurnDetector().process_bouts(t, q, np.array([[6.0, 10.0]]))) == 0
    assert len(TurnDetector().process_bouts(t, q, np.zeros((0, 2)))) == 0
    # the batch helper agrees with process() when one bout covers everything
    whole = TurnDetector().process(t, q)
    one = TurnDetector().process_bouts(t, q, np.array([[0.0, 20.0]]))
    np.testing.assert_allclose(one.t_start, whole.t_start, atol=1e-9)
    np.testing.assert_allclose(one.angle_rad, whole.angle_rad, atol=np.deg2rad(3.0))


def test_process_bouts_input_errors() -> None:
    t = np.arange(0.0, 5.0, 0.01)
    q = tilted_attitude(t, np.zeros_like(t))
    det = TurnDetector()
    with pytest.raises(InputError):
        det.process_bouts(t, q, np.array([[2.0, 1.0]]))
    with pytest.raises(InputError):
        det.process_bouts(t, q, np.array([[0.0, 3.0], [2.0, 4.0]]))
    with pytest.raises(InputError):
        det.process_bouts(t, q, np.array([0.0, 3.0]))
