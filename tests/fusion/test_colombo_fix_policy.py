"""Fix handling for Colombo's targets: drift-aware gate, step in progress, stretch variance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.fusion.fixes import (
    DRIFT_MIN_PATH_M,
    FixCorrector,
    FixParams,
    FixSchedule,
    partial_step,
    step_in_progress,
)
from hrtls.fusion.state import FilterState
from hrtls.fusion.yaw_stretch import YawStretchParams, stretch_yaw


def test_step_in_progress_hand_cases() -> None:
    t0 = np.array([0.0, 0.5, 1.0, 3.0])
    t1 = np.array([0.5, 1.0, 1.5, 3.5])
    assert step_in_progress(0.2, t0, t1) == 0
    assert step_in_progress(0.5, t0, t1) == 1          # a boundary belongs to the next step
    assert step_in_progress(1.49, t0, t1) == 2
    assert step_in_progress(2.0, t0, t1) == -1          # a pause between steps
    assert step_in_progress(-1.0, t0, t1) == -1
    assert step_in_progress(3.5, t0, t1) == -1          # after the last end
    assert step_in_progress(1.0, np.zeros(0), np.zeros(0)) == -1


def test_partial_step_hand_computed() -> None:
    d = partial_step(1.25, t_start=1.0, t_end=1.5, length_m=0.8, heading_rad=math.pi / 2)
    np.testing.assert_allclose(d, [0.0, 0.4], atol=1e-12)
    np.testing.assert_allclose(partial_step(2.0, t_start=1.0, t_end=1.5, length_m=0.8,
                                            heading_rad=0.0), [0.0, 0.0])
    np.testing.assert_allclose(partial_step(1.0, t_start=1.0, t_end=1.0, length_m=0.8,
                                            heading_rad=0.0), [0.0, 0.0])


@settings(max_examples=100, deadline=None)
@given(a=st.floats(0.0, 1.0), length=st.floats(0.0, 2.0), h=st.floats(-math.pi, math.pi))
def test_partial_step_is_a_fraction_of_the_step(a: float, length: float, h: float) -> None:
    d = partial_step(10.0 + 0.6 * a, t_start=10.0, t_end=10.6, length_m=length, heading_rad=h)
    assert np.hypot(*d) == pytest.approx(a * length, abs=1e-9)
    if a * length > 1e-6:
        assert math.cos(math.atan2(d[1], d[0]) - h) == pytest.approx(1.0, abs=1e-9)


def _state(sigma: float) -> FilterState:
    return FilterState.initial(sigma_xy_m=sigma).evolve(t=10.0)


def test_drift_variance_lets_a_good_fix_through_the_gate() -> None:
    corr = FixCorrector(FixParams(period_s=None, require_motion=False, gate_probability=0.997,
                                  max_consecutive_rejections=5))
    s = _state(0.1)
    kw = {"t": 10.0, "xyz": [0.9, 0.0, 0.0], "sigma_m": 0.03}
    assert not corr.update(s, FixSchedule(), **kw).diagnostics.accepted
    upd = corr.update(s, FixSchedule(), drift_var_m2=1.0, **kw)
    assert upd.diagnostics.accepted
    # hand-computed gain with P = 0.01 + 1.0 and R = 0.0009
    k = 1.01 / (1.01 + 0.0009)
    assert upd.state.x[0] == pytest.approx(0.9 * k)
    assert upd.state.P[0, 0] == pytest.approx((1 - k) * 1.01)
    with pytest.raises(InputError):
        corr.update(s, FixSchedule(), drift_var_m2=-1.0, **kw)


@settings(max_examples=50, deadline=None)
@given(dx=st.floats(-0.2, 0.2), dy=st.floats(-0.2, 0.2))
def test_zero_drift_is_the_plain_update(dx: float, dy: float) -> None:
    corr = FixCorrector(FixParams(period_s=None, require_motion=False))
    s = _state(0.3)
    a = corr.update(s, FixSchedule(), t=10.0, xyz=[dx, dy, 0.0], sigma_m=0.05)
    b = corr.update(s, FixSchedule(), t=10.0, xyz=[dx, dy, 0.0], sigma_m=0.05, drift_var_m2=0.0)
    np.testing.assert_array_equal(a.state.x, b.state.x)
    np.testing.assert_array_equal(a.state.P, b.state.P)


def test_drift_min_path_is_positive() -> None:
    assert DRIFT_MIN_PATH_M > 0.0


def test_stretch_variance_grows_with_the_walked_path() -> None:
    """``(sa^2 + sb^2 + (f L)^2) / chord^2 + floor^2`` (rotation method), hand-computed."""
    kw = {"t_start": 0.0, "t": np.array([2.0]), "speed_m_s": np.array([1.0]),
          "yaw_rad": np.array([0.0]), "start_xy": np.zeros(2), "offset_start": np.zeros(2),
          "offset_end": np.array([0.0, 0.1]), "sigma_start_m": 0.03, "sigma_end_m": 0.04}
    plain = stretch_yaw(**kw)
    drift = stretch_yaw(**kw, path_m=12.0, params=YawStretchParams(drift_fraction=0.1))
    chord2 = 2.0**2 + 0.1**2
    assert plain.var_yaw_rad2 == pytest.approx((0.03**2 + 0.04**2) / chord2 + 0.02**2)
    assert drift.var_yaw_rad2 == pytest.approx((0.03**2 + 0.04**2 + 1.2**2) / chord2
                                               + 0.02**2)
    assert drift.correction_rad == pytest.approx(plain.correction_rad)
    # without path_m the path of the samples (2 m) is used
    own = stretch_yaw(**kw, params=YawStretchParams(drift_fraction=0.1))
    assert own.var_yaw_rad2 == pytest.approx((0.03**2 + 0.04**2 + 0.2**2) / chord2 + 0.02**2)
    with pytest.raises(InputError):
        YawStretchParams(drift_fraction=-0.1)
