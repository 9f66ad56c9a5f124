"""A lower-back sensor in any orientation, mounting unknown: heading changes as with it known.

Real mobgap Test5 walks (sensor strapped with x up; the reader knows that mounting). The same
recording rotated into random device frames, with the mounting left unknown, must give the
same heading change over each walk. Before, the yaw of device x was used: with x up it was
noise (errors of 30-124 deg on these straight walks).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrtls.data import Session
from hrtls.evaluate.metrics import heading_change_rad
from hrtls.pipeline import Tracker, preset

pytestmark = pytest.mark.realdata


def _turn_deg(session: Session) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = Tracker(preset("default")).run(session)
    return float(np.degrees(heading_change_rad(res.steps)))


@pytest.mark.parametrize("participant", ["HA/001", "MS/001"])
def test_heading_change_does_not_depend_on_the_mounting(shared_data: Path,
                                                        participant: str) -> None:
    from hrtls.datasets.mobgap import load_trial

    root = shared_data / "mobgap_lab"
    if not root.is_dir():
        pytest.skip("mobgap_lab not present")
    s = load_trial(root, participant, "Test5", "Trial2").session
    assert s.meta.mounting_q_bd is not None
    reference = _turn_deg(s)
    rotations = [np.eye(3)] + [Rotation.random(random_state=seed).as_matrix()
                               for seed in (1, 2, 3)]
    unknown = s.meta.model_copy(update={"mounting_q_bd": None})
    assert s.imu is not None
    for r in rotations:                       # as recorded (x up) and three random frames
        rotated = s.with_parts(meta=unknown, imu=s.imu.in_device_frame(r))
        assert abs(_turn_deg(rotated) - reference) < 3.0
