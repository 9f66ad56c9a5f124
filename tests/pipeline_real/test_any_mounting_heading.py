"""A lower-back sensor in any orientation, mounting unknown: heading changes as with it known.

Real mobgap Test5 walks (sensor strapped with x up; the reader knows that mounting). The same
recording rotated into random device frames, with the mounting left unknown, must give the
same heading change over each walk (over the steps both runs give a heading for: with the
mounting unknown the first steps have none). Before, the yaw of device x was used: with x up
it was noise (errors of 30-124 deg on these straight walks).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrtls.data import Session, StepEvents
from hrtls.evaluate.metrics import heading_change_rad
from hrtls.pipeline import Tracker, preset

pytestmark = pytest.mark.realdata


def _steps(session: Session) -> StepEvents:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Tracker(preset("default")).run(session).steps


def _turn_deg(steps: StepEvents, t_end: np.ndarray) -> float:
    """Heading change over the steps ending at ``t_end``."""
    return float(np.degrees(heading_change_rad(steps.select(np.isin(steps.t_end, t_end)))))


@pytest.mark.parametrize("participant", ["HA/001", "MS/001"])
def test_heading_change_does_not_depend_on_the_mounting(shared_data: Path,
                                                        participant: str) -> None:
    from hrtls.datasets.mobgap import load_trial

    root = shared_data / "mobgap_lab"
    if not root.is_dir():
        pytest.skip("mobgap_lab not present")
    s = load_trial(root, participant, "Test5", "Trial2").session
    assert s.meta.mounting_q_bd is not None
    known = _steps(s)
    rotations = [np.eye(3)] + [Rotation.random(random_state=seed).as_matrix()
                               for seed in (1, 2, 3)]
    unknown = s.meta.model_copy(update={"mounting_q_bd": None})
    assert s.imu is not None
    for r in rotations:                       # as recorded (x up) and three random frames
        steps = _steps(s.with_parts(meta=unknown, imu=s.imu.in_device_frame(r)))
        np.testing.assert_array_equal(steps.t_end, known.t_end)
        both = steps.t_end[np.isfinite(steps.heading_rad)]
        assert len(both) >= 5
        assert abs(_turn_deg(steps, both) - _turn_deg(known, both)) < 3.0
