"""Small seeded motions for the attitude tests."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrtls.frames import GRAVITY_M_S2, quat_from_rotation, quat_to_rotation

FIELD_N = 48.0 * np.array([0.0, np.cos(np.deg2rad(60)), -np.sin(np.deg2rad(60))])


@dataclass
class Motion:
    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    q: np.ndarray  # truth q_nd


def make_motion(n: int = 600, rate_hz: float = 100.0, seed: int = 0, *, rest_s: float = 1.0,
                amp_rad: float = 0.6, noise: bool = True, bias: float = 0.0,
                accel_amp: float = 1.0) -> Motion:
    """Rest, then smooth rotations about all axes with some linear acceleration."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    on = np.clip((t - rest_s) / 0.5, 0.0, 1.0)
    freqs = rng.uniform(0.2, 0.8, size=3)
    phases = rng.uniform(0, 2 * np.pi, size=3)
    roll = on * 0.5 * amp_rad * np.sin(2 * np.pi * freqs[0] * t + phases[0])
    pitch = on * 0.5 * amp_rad * np.sin(2 * np.pi * freqs[1] * t + phases[1])
    yaw = rng.uniform(-np.pi, np.pi) + on * amp_rad * np.sin(2 * np.pi * freqs[2] * t + phases[2])
    rot = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll]))
    q = quat_from_rotation(rot)
    rel = (rot[:-1].inv() * rot[1:]).as_rotvec() * rate_hz
    gyr = np.vstack([rel[:1] * 0, rel])
    lin = on[:, None] * accel_amp * np.column_stack(
        [np.sin(2 * np.pi * 1.7 * t), np.cos(2 * np.pi * 1.1 * t), np.sin(2 * np.pi * 1.9 * t)])
    acc = rot.inv().apply(lin + np.array([0.0, 0.0, GRAVITY_M_S2]))
    mag = rot.inv().apply(np.tile(FIELD_N, (n, 1)))
    if noise:
        gyr = gyr + rng.normal(size=gyr.shape) * 0.003
        acc = acc + rng.normal(size=acc.shape) * 0.03
        mag = mag + rng.normal(size=mag.shape) * 0.3
    gyr = gyr + bias
    return Motion(t, acc, gyr, mag, quat_from_rotation(quat_to_rotation(q)))


@pytest.fixture(scope="session")
def motion() -> Motion:
    return make_motion(800, seed=3)
