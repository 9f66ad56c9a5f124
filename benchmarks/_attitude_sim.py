"""Compact simulator: waist IMU of a walking person with magnetic disturbances (benchmark only).

Truth is ``q_nb`` (body = device, ENU). The person stands for ``rest_s``, then walks at
``speed_m_s`` with 90-degree turns every ``leg_s`` seconds and short stops; the pelvis rolls,
pitches and yaws at the stride/step frequency. The gyroscope is the mean rate between samples
(``rotvec(conj(q_{k-1}) q_k) / dt``) plus bias and noise, the accelerometer is
``R^T (a_n - g_n)`` plus noise, the magnetometer is the Earth field plus patches of magnetic
anomaly placed along the path (e.g. steel doors, radiators) plus noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hrtls.frames import GRAVITY_M_S2, quat_from_euler, quat_from_rotation, quat_to_rotation


@dataclass(frozen=True)
class SimWalk:
    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    q_true: np.ndarray
    pos: np.ndarray
    disturbed: np.ndarray  # samples inside a magnetic anomaly
    movement: np.ndarray  # samples to score (all after the initial rest)


def simulate_walk(*, duration_s: float = 300.0, rate_hz: float = 100.0, seed: int = 0,
                  rest_s: float = 5.0, leg_s: float = 12.0, speed_m_s: float = 1.3,
                  n_anomalies: int = 12, anomaly_uT: float = 30.0,
                  gyro_noise: float = 0.005, gyro_bias: float = 0.01, acc_noise: float = 0.05,
                  mag_noise: float = 0.5, field_uT: float = 48.0,
                  dip_deg: float = 62.0) -> SimWalk:
    rng = np.random.default_rng(seed)
    n = int(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    walking = np.zeros(n, dtype=bool)
    heading = np.zeros(n)
    # walking schedule: legs separated by turns; a 3 s stop every third leg
    h = rng.uniform(-np.pi, np.pi)
    tt = rest_s
    events = []  # (t_start, t_end, kind, value)
    leg = 0
    while tt < duration_s:
        events.append((tt, tt + leg_s, "walk", 0.0))
        tt += leg_s
        turn = rng.choice([-1.0, 1.0]) * np.pi / 2 * rng.uniform(0.5, 1.0)
        events.append((tt, tt + 1.5, "turn", turn))
        tt += 1.5
        leg += 1
        if leg % 3 == 0:
            events.append((tt, tt + 3.0, "stop", 0.0))
            tt += 3.0
    for t0, t1, kind, val in events:
        sel = (t >= t0) & (t < t1)
        if kind in ("walk", "turn"):
            walking[sel] = True
        if kind == "turn":
            u = (t[sel] - t0) / (t1 - t0)
            heading[sel] = h + val * (u - np.sin(2 * np.pi * u) / (2 * np.pi))
            h += val
        else:
            heading[sel] = h
    heading[t >= tt] = h
    heading[t < rest_s] = heading[np.searchsorted(t, rest_s)] if rest_s < duration_s else 0.0
    # smooth on/off of the gait oscillations
    env = np.convolve(walking.astype(float), np.ones(int(rate_hz)) / rate_hz, mode="same")
    f_step = 1.8
    ph = 2 * np.pi * f_step * t
    yaw = heading + env * np.deg2rad(4.0) * np.sin(ph / 2)
    roll = env * np.deg2rad(3.0) * np.sin(ph / 2 + 0.3) + np.deg2rad(2.0)
    pitch = env * np.deg2rad(2.0) * np.sin(ph + 0.5) + np.deg2rad(-3.0)
    q = quat_from_euler(roll, pitch, yaw)
    # position: forward speed along heading, vertical bounce, lateral sway
    v = env * speed_m_s
    vx = v * np.cos(heading)
    vy = v * np.sin(heading)
    pos = np.zeros((n, 3))
    pos[:, 0] = np.cumsum(vx) / rate_hz
    pos[:, 1] = np.cumsum(vy) / rate_hz
    sway = env * 0.02 * np.sin(ph / 2)
    pos[:, 0] += -np.sin(heading) * sway
    pos[:, 1] += np.cos(heading) * sway
    pos[:, 2] = env * 0.025 * np.sin(ph)
    acc_n = np.gradient(np.gradient(pos, t, axis=0), t, axis=0)
    rot = quat_to_rotation(q)
    f_n = acc_n + np.array([0.0, 0.0, GRAVITY_M_S2])
    acc = rot.inv().apply(f_n)
    rel = (rot[:-1].inv() * rot[1:]).as_rotvec() * rate_hz
    gyr = np.vstack([rel[:1], rel])
    dip = np.deg2rad(dip_deg)
    m_earth = field_uT * np.array([0.0, np.cos(dip), -np.sin(dip)])
    m_n = np.tile(m_earth, (n, 1))
    disturbed = np.zeros(n, dtype=bool)
    walk_idx = np.flatnonzero(env > 0.5)
    if n_anomalies and len(walk_idx):
        centers = pos[rng.choice(walk_idx, n_anomalies, replace=False), :2]
        for c in centers:
            d = np.linalg.norm(pos[:, :2] - c, axis=1)
            radius = rng.uniform(1.0, 2.5)
            w = np.exp(-0.5 * (d / radius) ** 2)
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            m_n += np.outer(w, direction * anomaly_uT * rng.uniform(0.5, 1.5))
            disturbed |= w > 0.1
    mag = rot.inv().apply(m_n)
    b = rng.normal(size=3) * gyro_bias
    gyr = gyr + b + rng.normal(size=(n, 3)) * gyro_noise
    acc = acc + rng.normal(size=(n, 3)) * acc_noise
    mag = mag + rng.normal(size=(n, 3)) * mag_noise
    movement = t >= rest_s
    return SimWalk(t, acc, gyr, mag, quat_from_rotation(rot), pos, disturbed, movement)


def relative_rotation(q: np.ndarray) -> Rotation:
    return quat_to_rotation(q)
