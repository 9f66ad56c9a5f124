from __future__ import annotations

import numpy as np
import pytest

from hrtls.errors import InputError
from hrtls.fusion.yaw_stretch import YawStretchParams, stretch_yaw


def straight(delta: float, n: int = 200, v: float = 1.2) -> dict[str, object]:
    t = np.arange(1, n + 1) * 0.02
    length = v * t[-1]
    est_end = length * np.array([np.cos(delta), np.sin(delta)])
    return {"t_start": 0.0, "t": t, "speed_m_s": np.full(n, v), "yaw_rad": np.full(n, delta),
                "start_xy": np.zeros(2), "offset_start": np.zeros(2),
                "offset_end": np.array([length, 0.0]) - est_end, "sigma_start_m": 0.05,
                "sigma_end_m": 0.05}


@pytest.mark.parametrize("method", ["paper", "rotation"])
def test_straight_segment_recovers_bias(method: str) -> None:
    res = stretch_yaw(**straight(0.2), params=YawStretchParams(method=method))  # type: ignore[arg-type]
    assert res.valid
    assert res.correction_rad == pytest.approx(-0.2, abs=1e-9)
    assert res.yaw_rad == pytest.approx(0.0, abs=1e-9)
    # eq. 27-28 per sample: every stretched displacement points along x with the same speed
    np.testing.assert_allclose(res.stretched_yaw, 0.0, atol=1e-9)
    np.testing.assert_allclose(res.stretched_speed, 1.2, rtol=1e-9)
    # eq. 24: the stretched track ends on the second fix
    np.testing.assert_allclose(res.stretched_xy[-1], [1.2 * 4.0, 0.0], atol=1e-9)
    assert res.var_yaw_rad2 > 0.02**2


def test_rotation_handles_a_u_turn_where_eq_28_fails() -> None:
    # half circle of radius 2 m walked at 1 m/s with a constant yaw bias of 0.15 rad
    r, v, bias = 2.0, 1.0, 0.15
    t = np.arange(1, 629) * 0.01
    true_yaw = v / r * t
    rot = np.array([[np.cos(bias), -np.sin(bias)], [np.sin(bias), np.cos(bias)]])
    true_end = np.sum(np.column_stack([np.cos(true_yaw), np.sin(true_yaw)]) * 0.01 * v, axis=0)
    est_end = np.sum(np.column_stack([np.cos(true_yaw + bias), np.sin(true_yaw + bias)]) * 0.01 * v,
                     axis=0)
    assert np.hypot(*true_end) > 3.9
    kw = {"t_start": 0.0, "t": t, "speed_m_s": np.full(t.size, v), "yaw_rad": true_yaw + bias,
          "start_xy": np.zeros(2), "offset_start": np.zeros(2),
          "offset_end": true_end - est_end, "sigma_start_m": 0.05, "sigma_end_m": 0.05}
    rotation = stretch_yaw(**kw)  # type: ignore[arg-type]
    assert rotation.valid
    assert rotation.correction_rad == pytest.approx(-bias, abs=1e-9)
    np.testing.assert_allclose(rot @ true_end, est_end, atol=1e-9)
    paper = stretch_yaw(**kw, params=YawStretchParams(method="paper",  # type: ignore[arg-type]
                                                      max_correction_rad=3.0))
    assert abs(paper.correction_rad + bias) > 0.1     # eq. 28 at j = 0 is far off here


def test_invalid_segments() -> None:
    short = straight(0.1, n=10)
    assert not stretch_yaw(**short).valid  # type: ignore[arg-type]
    still = straight(0.1)
    still["speed_m_s"] = np.zeros(200)
    assert not stretch_yaw(**still).valid  # type: ignore[arg-type]
    big = straight(1.0)
    res = stretch_yaw(**big)  # type: ignore[arg-type]
    assert not res.valid and "beyond" in res.reason
    bad = straight(0.1)
    bad["t"] = np.arange(200)[::-1] * 0.02
    with pytest.raises(InputError):
        stretch_yaw(**bad)  # type: ignore[arg-type]
