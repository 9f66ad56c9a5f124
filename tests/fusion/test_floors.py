from __future__ import annotations

import numpy as np
import pytest

from hrtls.data.results import Activity
from hrtls.errors import InputError
from hrtls.fusion.floors import floor_index, floor_level, floor_level_update
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictor


def test_floor_index_and_level() -> None:
    np.testing.assert_array_equal(floor_index([-0.2, 1.4, 1.6, 3.1, -3.2], 3.0), [0, 0, 1, 1, -1])
    assert float(floor_level(2, 3.0, ground_z_m=0.5)) == pytest.approx(6.5)
    with pytest.raises(InputError):
        floor_index(1.0, 0.0)


def test_stairs_then_level_constraint() -> None:
    pred = StepPredictor()
    s = FilterState.initial()
    for i in range(16):                                   # 16 risers of 0.17 m = 2.72 m
        s = pred.predict(s, t=float(i + 1), length_m=0.3, heading_rad=0.0,
                         activity=int(Activity.UPSTAIRS))
    assert int(floor_index(s.x[2], 3.0)) == 1
    s2, diag = floor_level_update(s, 3.0, sigma_m=0.05)
    assert diag.accepted
    assert abs(s2.x[2] - 3.0) < abs(s.x[2] - 3.0)
    assert s2.P[2, 2] < s.P[2, 2]
