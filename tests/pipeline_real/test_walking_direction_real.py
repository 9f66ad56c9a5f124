"""The walking direction found from the motion on real recordings turned into random frames.

Gait stage on the same attitude (``inertial-lp`` on the turned IMU) with the known mounting
(turned with the frame) and with the mounting unknown: the step headings must agree. mobgap
HA/001 (lower back; the data the estimator's parameters were chosen on) and the held-out IPIN
T23r03 (phone held in front; known mounting: the top edge made horizontal).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrtls.attitude.registry import make_filter
from hrtls.data import ImuStream
from hrtls.frames import quat_conjugate, quat_from_rotation, quat_multiply, wrap_angle
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.pipeline.mounting import handheld_mounting_q_bd

pytestmark = pytest.mark.realdata


def direction_errors_deg(imu: ImuStream, q_bd: np.ndarray, r: np.ndarray) -> np.ndarray:
    """|unknown - known| step heading in device frame ``r`` (steps with a heading), deg."""
    turned = imu.in_device_frame(r)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = make_filter("inertial-lp").run(turned)
    acc = np.column_stack([np.interp(res.t, turned.accel.t, turned.accel.values[:, k])
                           for k in range(3)])
    q_bd_r = quat_multiply(q_bd, quat_conjugate(quat_from_rotation(Rotation.from_matrix(r))))
    rate = 1.0 / float(np.median(np.diff(res.t)))
    known = GaitAnalyzer(rate_hz=rate, heading="yaw", mounting_q_bd=q_bd_r).process(
        res.t, acc, res.q)
    unknown = GaitAnalyzer(rate_hz=rate, heading="yaw").process(res.t, acc, res.q)
    np.testing.assert_array_equal(known.steps.t_end, unknown.steps.t_end)
    d = wrap_angle(unknown.steps.heading_rad - known.steps.heading_rad)
    return np.abs(np.degrees(d[np.isfinite(d)]))


@pytest.mark.parametrize("seed", [11, 12])
def test_lower_back_any_frame(shared_data: Path, seed: int) -> None:
    from hrtls.datasets.mobgap import load_trial

    root = shared_data / "mobgap_lab"
    if not root.is_dir():
        pytest.skip("mobgap_lab not present")
    s = load_trial(root, "HA/001", "Test11", "Trial1").session
    assert s.imu is not None and s.meta.mounting_q_bd is not None
    e = direction_errors_deg(s.imu, np.asarray(s.meta.mounting_q_bd),
                             Rotation.random(random_state=seed).as_matrix())
    assert len(e) > 60
    assert np.median(e) < 10.0


@pytest.mark.parametrize("seed", [11, 12])
def test_hand_held_phone_any_frame(shared_data: Path, seed: int) -> None:
    from hrtls.recordings import read_any

    path = shared_data / "ipin2023" / "IPIN2023_T3_TrainingTrial23_repetition03.txt"
    if not path.is_file():
        pytest.skip("IPIN log not present")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = read_any(path, trim_to_start=True)
    assert s.imu is not None
    e = direction_errors_deg(s.imu, handheld_mounting_q_bd(s.imu.accel.values),
                             Rotation.random(random_state=seed).as_matrix())
    assert len(e) > 60
    assert np.median(e) < 10.0
