from __future__ import annotations

import json

import numpy as np
import pytest

from hrtls.data.session import StartPose
from hrtls.errors import InputError
from hrtls.fusion.state import FilterState, independent_block


def test_roundtrip_json() -> None:
    s = FilterState.initial(t=2.0, xyz=(1.0, 2.0, 3.0), heading_rad=4.0)
    d = json.loads(json.dumps(s.to_dict()))
    s2 = FilterState.from_dict(d)
    np.testing.assert_array_equal(s.x, s2.x)
    np.testing.assert_array_equal(s.P, s2.P)
    assert s2.t == 2.0
    assert -np.pi < s2.heading <= np.pi
    assert s2.heading == pytest.approx(4.0 - 2 * np.pi)


def test_invalid_state_raises() -> None:
    with pytest.raises(InputError):
        FilterState(0.0, np.zeros(3), np.eye(4))
    with pytest.raises(InputError):
        FilterState(0.0, np.array([np.nan, 0, 0, 0]), np.eye(4))
    p = np.eye(4)
    p[0, 0] = -1.0
    with pytest.raises(InputError, match="negative eigenvalue"):
        FilterState(0.0, np.zeros(4), p)
    with pytest.raises(InputError):
        FilterState.from_dict({"x": [0, 0, 0, 0]})


def test_from_start_pose_and_block() -> None:
    s = FilterState.from_start_pose(StartPose(x=1.0, y=2.0, heading=0.5, sigma_xy_m=0.3))
    assert s.cov_xy[0, 0] == pytest.approx(0.09)
    assert s.heading == pytest.approx(0.5)
    unknown = FilterState.from_start_pose(StartPose())
    assert unknown.var_heading == pytest.approx(np.pi**2)
    p = np.full((4, 4), 0.1) + np.eye(4)
    q = independent_block(p, [0, 1], np.eye(2) * 5.0)
    assert q[0, 2] == 0.0 and q[3, 1] == 0.0 and q[0, 0] == 5.0 and q[2, 3] == pytest.approx(0.1)
