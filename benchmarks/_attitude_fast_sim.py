"""Hand-held IMU in fast motion, BROAD-like (benchmark and test data, truth known).

Three kinds of unit, after the fast trials of BROAD (Laidig, Caruso, Cereatti & Seel 2021,
Data 6(7) 72) that are not in ``../shared/data/broad``: ``translation`` (quick linear
accelerations of several m/s^2 at 0.5-3 Hz, the orientation only wobbling by a few degrees),
``rotation`` (large, fast rotations about all axes, the position nearly still) and ``combined``
(both). A unit rests for ``rest_s``, then moves; the motion fades in and out smoothly over
``ramp_s`` around each of ``n_breaks`` pauses of ``break_s``. Seeds: 1-3 are for development,
101-110 are held out (``DEV_SEEDS``, ``HELD_OUT_SEEDS``); nothing is tuned on the held-out
seeds.

Physics (conventions of ``docs/conventions.md``: ENU, ``q_nb`` maps body vectors to ENU,
``g_n = [0, 0, -9.80665]``):

* position ``p_n(t) = e(t) s(t)``, ``s`` a sum of sines with analytic derivatives and ``e`` the
  motion envelope (quintic ramps), so ``a_n = e'' s + 2 e' s' + e s''`` exactly;
* orientation from roll, pitch, yaw (``R_nb = Rz(yaw) Ry(pitch) Rx(roll)``), each a constant
  plus ``e(t)`` times a sum of sines, the yaw with an extra slow turn;
* gyroscope: the mean body rate between samples, ``omega = rotvec(R_{k-1}^T R_k) / dt`` (as
  the walk simulator of ``_attitude_sim.py``), seen through ``(I + S) omega`` with small
  per-axis scale errors on the diagonal of ``S`` and axis misalignments off it, plus a
  constant bias and white noise;
* accelerometer: the specific force ``f_b = R_nb^T (a_n - g_n)`` plus a constant bias and white
  noise;
* magnetometer: ``R_nb^T m_n`` (an undisturbed field, Berlin-like norm and dip) plus noise.

The error defaults are of a calibrated MEMS unit at 286 Hz (white noise per sample: gyro
0.2 deg/s, accelerometer 0.03 m/s^2; drawn per seed: gyro bias 0.5 deg/s, accelerometer bias
0.02 m/s^2, gyro scale errors 0.3 % and misalignments 0.2 deg, standard deviations per axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.frames import GRAVITY_M_S2, quat_from_euler, quat_from_rotation, quat_to_rotation

KINDS = ("translation", "rotation", "combined")
DEV_SEEDS = (1, 2, 3)
HELD_OUT_SEEDS = tuple(range(101, 111))
BROAD_RATE_HZ = 2000.0 / 7.0  # 285.7 Hz, the sampling rate of the BROAD files


@dataclass(frozen=True)
class FastMotion:
    """One simulated unit: sensor arrays, true ``q_nb`` and the samples to score."""

    kind: str
    seed: int
    rate_hz: float
    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray
    q_true: np.ndarray
    pos: np.ndarray
    movement: np.ndarray
    gyro_bias_rad_s: np.ndarray


def _envelope(t: np.ndarray, on: list[tuple[float, float]], ramp_s: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e, e', e''`` of a motion envelope: 1 inside each ``(t0, t1)``, smooth ramps.

    The ramps are the quintic ``h(u) = 10 u^3 - 15 u^4 + 6 u^5`` (``h' = 30 u^2 (1 - u)^2``,
    ``h'' = 60 u (1 - u) (1 - 2 u)``, ``u`` the ramp time over ``ramp_s``), whose first and
    second derivatives vanish at both ends: the body's acceleration has no jumps.
    """
    e = np.zeros_like(t)
    de = np.zeros_like(t)
    dde = np.zeros_like(t)
    for t0, t1 in on:
        for start, sign in ((t0, 1.0), (t1 - ramp_s, -1.0)):
            sel = (t >= start) & (t < start + ramp_s)
            u = (t[sel] - start) / ramp_s
            h = u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)
            e[sel] = h if sign > 0 else 1.0 - h
            de[sel] = sign * 30.0 * u * u * (1.0 - u) ** 2 / ramp_s
            dde[sel] = sign * 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / ramp_s ** 2
        e[(t >= t0 + ramp_s) & (t < t1 - ramp_s)] = 1.0
    return e, de, dde


def _sines(rng: np.random.Generator, t: np.ndarray, *, n: int, f_lo_hz: float, f_hi_hz: float,
           rms: float, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A sum of ``n`` sines and its first two derivatives.

    Frequencies are log-uniform in ``[f_lo_hz, f_hi_hz]``; the amplitudes are set so that the
    ``order``-th derivative (0: the signal, 2: for a position, its acceleration) has the RMS
    ``rms``, each sine carrying an equal share.
    """
    f = np.exp(rng.uniform(np.log(f_lo_hz), np.log(f_hi_hz), n))
    om = 2.0 * np.pi * f
    phase = rng.uniform(0.0, 2.0 * np.pi, n)
    amp = rms * np.sqrt(2.0 / n) / om ** order
    arg = np.outer(t, om) + phase
    s = np.sin(arg) @ amp
    ds = np.cos(arg) @ (amp * om)
    dds = -(np.sin(arg) @ (amp * om * om))
    return s, ds, dds


def simulate_fast_motion(kind: str, *, seed: int, duration_s: float = 60.0,
                         rate_hz: float = BROAD_RATE_HZ, rest_s: float = 5.0,
                         n_breaks: int = 2, break_s: float = 5.0, ramp_s: float = 1.0,
                         acc_rms_m_s2: float | None = None,
                         rot_rms_rad: float | None = None,
                         gyro_noise_rad_s: float = float(np.deg2rad(0.2)),
                         gyro_bias_rad_s: float = float(np.deg2rad(0.5)),
                         gyro_scale: float = 0.003,
                         gyro_misalignment_rad: float = float(np.deg2rad(0.2)),
                         acc_noise_m_s2: float = 0.03, acc_bias_m_s2: float = 0.02,
                         mag_noise_uT: float = 0.5, field_uT: float = 49.8,
                         dip_deg: float = 67.0) -> FastMotion:
    """One unit of ``kind`` (``translation``, ``rotation``, ``combined``); see the module text.

    ``acc_rms_m_s2`` is the RMS of each horizontal component of the body's acceleration in the
    moving phase (default 5 for ``translation`` and ``combined``, 0.3 for ``rotation``; the
    vertical one is 0.7 times that) and ``rot_rms_rad`` the RMS of the roll and pitch
    oscillations (default 0.5 rad for ``rotation`` and ``combined``, 0.03 rad for
    ``translation``; the yaw oscillation is twice that).
    """
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r} is not one of {KINDS}")
    fast_acc = kind in ("translation", "combined")
    fast_rot = kind in ("rotation", "combined")
    if acc_rms_m_s2 is None:
        acc_rms_m_s2 = 5.0 if fast_acc else 0.3
    if rot_rms_rad is None:
        rot_rms_rad = 0.5 if fast_rot else 0.03
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    n = round(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    # moving phases: rest, then n_breaks + 1 phases separated by breaks
    moving = duration_s - rest_s - n_breaks * break_s
    phase_s = moving / (n_breaks + 1)
    on = []
    t0 = rest_s
    for _ in range(n_breaks + 1):
        on.append((t0, t0 + phase_s))
        t0 += phase_s + break_s
    e, de, dde = _envelope(t, on, ramp_s)
    # translation: p = e s, a = e'' s + 2 e' s' + e s''
    pos = np.zeros((n, 3))
    acc_n = np.zeros((n, 3))
    for c in range(3):
        rms = acc_rms_m_s2 * (0.7 if c == 2 else 1.0)
        s, ds, dds = _sines(rng, t, n=4, f_lo_hz=0.5, f_hi_hz=3.0, rms=rms, order=2)
        pos[:, c] = e * s
        acc_n[:, c] = dde * s + 2.0 * de * ds + e * dds
    # rotation: constant + e * sines (roll, pitch), yaw with a slow turn as well
    base = rng.uniform(-0.3, 0.3, 2)
    f_hi = 2.0
    ang = []
    for c in range(3):
        s, _, _ = _sines(rng, t, n=4, f_lo_hz=0.2, f_hi_hz=f_hi,
                         rms=rot_rms_rad * (2.0 if c == 2 else 1.0), order=0)
        ang.append(e * s)
    roll = base[0] + ang[0]
    pitch = base[1] + ang[1]
    turn = rng.choice([-1.0, 1.0]) * (np.pi / 4 if fast_rot else 0.05) * np.cumsum(e) / rate_hz
    yaw = rng.uniform(-np.pi, np.pi) + ang[2] + turn
    q = quat_from_euler(roll, pitch, yaw)
    rot = quat_to_rotation(q)
    rel = (rot[:-1].inv() * rot[1:]).as_rotvec() * rate_hz
    gyr = np.vstack([rel[:1], rel])
    f_n = acc_n + np.array([0.0, 0.0, GRAVITY_M_S2])  # a_n - g_n
    acc = rot.inv().apply(f_n)
    dip = np.deg2rad(dip_deg)
    m_n = field_uT * np.array([0.0, np.cos(dip), -np.sin(dip)])
    mag = rot.inv().apply(np.tile(m_n, (n, 1)))
    b_g = rng.normal(size=3) * gyro_bias_rad_s
    b_a = rng.normal(size=3) * acc_bias_m_s2
    sens = (np.eye(3) + np.diag(rng.normal(size=3) * gyro_scale)
            + (1.0 - np.eye(3)) * rng.normal(size=(3, 3)) * gyro_misalignment_rad)
    gyr = gyr @ sens.T + b_g + rng.normal(size=(n, 3)) * gyro_noise_rad_s
    acc = acc + b_a + rng.normal(size=(n, 3)) * acc_noise_m_s2
    mag = mag + rng.normal(size=(n, 3)) * mag_noise_uT
    return FastMotion(kind, seed, rate_hz, t, acc, gyr, mag, quat_from_rotation(rot), pos,
                      t >= rest_s, b_g)
