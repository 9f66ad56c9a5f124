"""Clock jumps, dropouts, resets and disagreeing streams (hrtls.data.clocks)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import ImuStream, SensorSeries, Session
from hrtls.data.clocks import (
    ClockJump,
    ClockParams,
    ClockStream,
    check_clocks,
    check_session_clocks,
    find_jumps,
    remove_jumps,
    repair_backward_jumps,
)
from hrtls.errors import InputError, RepairWarning


def test_find_and_remove_jumps_hand_computed() -> None:
    t = np.array([0.0, 0.1, 0.2, 5.2, 5.3, 5.4, 1.0, 1.1])
    jumps = find_jumps(t)
    assert [(j.index, round(j.step_s, 9)) for j in jumps] == [(3, 5.0), (6, -4.4)]
    assert all(j.nominal_dt_s == pytest.approx(0.1) for j in jumps)
    fixed = remove_jumps(t, jumps)
    np.testing.assert_allclose(fixed, np.arange(8) * 0.1, atol=1e-12)


def test_small_steps_are_not_jumps() -> None:
    t = np.array([0.0, 0.01, 0.02, 0.25, 0.26, 0.259, 0.27])  # 230 ms gap, 1 ms back: jitter
    assert find_jumps(t) == []


@settings(max_examples=60, deadline=None)
# n >= 20: at most 4 jumps stay a minority of the steps, so the median step is the nominal one
# (with n = 5 two jumps are half the steps and no nominal step exists)
@given(n=st.integers(20, 200), dt=st.floats(0.005, 0.2),
       jumps=st.lists(st.tuples(st.floats(0.05, 0.95), st.floats(-5000.0, 5000.0)),
                      min_size=1, max_size=4))
def test_remove_jumps_restores_a_regular_clock(n: int, dt: float,
                                               jumps: list[tuple[float, float]]) -> None:
    base = np.arange(n) * dt
    t = base.copy()
    where = sorted({max(1, min(n - 1, int(f * n))) for f, _ in jumps})
    limit = max(1.0, 20.0 * dt)
    sizes = []
    for i, (_, size) in zip(where, jumps, strict=False):
        if abs(size) <= limit + dt or (size < 0 and -size <= 0.05 + dt):
            size = np.copysign(limit + 10.0, size)
        t[i:] += size
        sizes.append(size)
    found = find_jumps(t)
    assert [j.index for j in found] == where[:len(sizes)]
    fixed = remove_jumps(t, found)
    np.testing.assert_allclose(fixed, base, atol=1e-6 * max(1.0, float(np.abs(t).max())))
    assert np.all(np.diff(fixed) > 0)


def _imu(t_acc: np.ndarray, t_gyr: np.ndarray | None = None) -> ImuStream:
    acc = np.tile([0.0, 0.0, 9.81], (len(t_acc), 1))
    gyro = None if t_gyr is None else SensorSeries(t_gyr, np.zeros((len(t_gyr), 3)), "gyro")
    return ImuStream(SensorSeries(t_acc, acc, "accel"), gyro)


def test_jump_in_accelerometer_only_is_refused_then_removed() -> None:
    t = np.arange(1000) * 0.01
    t_acc = t.copy()
    t_acc[400:] += 3600.0
    session = Session(imu=_imu(t_acc, t))
    with pytest.raises(InputError, match="--repair") as err:
        check_session_clocks(session)
    assert "accel sample 400" in str(err.value)
    with pytest.warns(RepairWarning, match="shifted by -3600.000 s"):
        fixed, repairs = check_session_clocks(session, repair=True)
    assert fixed.imu is not None
    np.testing.assert_allclose(fixed.imu.accel.t, t, atol=1e-9)
    assert [r.action for r in repairs] == ["jump removed"]


def test_jump_in_every_stream_is_kept_as_a_gap_with_a_warning() -> None:
    t = np.arange(1000) * 0.01
    t[400:] += 3600.0
    pressure = SensorSeries(t[::10], np.full(100, 1e5), "pressure")
    session = Session(imu=_imu(t, t.copy()), pressure=pressure)
    with pytest.warns(RepairWarning, match="kept as gaps"):
        fixed, repairs = check_session_clocks(session)
    assert fixed is session
    assert {r.action for r in repairs} == {"gap kept"}


def test_dropout_of_one_stream_is_a_gap_not_a_jump() -> None:
    t = np.arange(3000) * 0.01
    t_p = np.delete(t[::10], np.arange(100, 150))  # 5 s without pressure
    session = Session(imu=_imu(t), pressure=SensorSeries(t_p, np.full(len(t_p), 1e5), "p"))
    with pytest.warns(RepairWarning, match="no samples for 5.100 s"):
        fixed, repairs = check_session_clocks(session)
    assert fixed is session and repairs[0].action == "gap kept"


def test_streams_that_disagree_are_refused_or_shifted() -> None:
    t = np.arange(1000) * 0.01
    p_t = t[::10] + 7200.0
    session = Session(imu=_imu(t), pressure=SensorSeries(p_t, np.full(100, 1e5), "pressure"))
    with pytest.raises(InputError, match=r"streams disagree: pressure spans 7200\.000"):
        check_session_clocks(session)
    with pytest.warns(RepairWarning, match="shifted by -7200.000 s"):
        fixed, _ = check_session_clocks(session, repair=True)
    assert fixed.pressure is not None and fixed.pressure.t[0] == pytest.approx(0.0)


def test_clean_streams_pass_silently() -> None:
    t = np.arange(500) * 0.01
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        new_t, repairs = check_clocks([ClockStream("a", "a", t), ClockStream("b", "b", t[::5])])
    assert new_t == {} and repairs == []


def test_backward_reset_is_shifted_not_sorted() -> None:
    t = np.concatenate([np.arange(300) * 0.01, 0.5 + np.arange(300) * 0.01])
    with pytest.warns(RepairWarning, match="clock jumps backward by 2.490 s"):
        fixed = repair_backward_jumps(t, where="imu.csv")
    np.testing.assert_allclose(fixed, np.arange(600) * 0.01, atol=1e-9)


def test_params_are_checked() -> None:
    with pytest.raises(InputError, match="jump_min_s"):
        ClockParams(jump_min_s=0.0)
    assert ClockJump(3, -1.0, 0.1, 2.0).forward is False


def test_rows_out_of_order_are_left_to_sorting() -> None:
    t = np.arange(600) * 0.01
    t = np.concatenate([t[:200], t[400:], t[200:400]])  # a block written late fills a hole
    out = repair_backward_jumps(t, where="x")
    np.testing.assert_array_equal(out, t)
