"""Waveform measurement of waist-worn gait: levelled signals, stride waveforms, harmonics.

How the harmonic tables of :mod:`hrtls.sim.gait_model` were obtained from real lower-back
recordings (see "How the waveform constants were measured" there); used by
``benchmarks/sim_vs_real.py`` and the tests to compare the simulator with real strides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2
from hrtls.kernels import njit

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

GAIT_SIGNAL_COLUMNS = ("ap_m_s2", "ml_m_s2", "vertical_m_s2", "roll_rate_rad_s",
                       "pitch_rate_rad_s", "yaw_rate_rad_s")
"""Columns of :func:`levelled_gait_signals`."""

_MIRRORED = (1, 3, 5)  # ML acceleration, roll rate and yaw rate change sign left <-> right


@njit(cache=True)
def _levelled_kernel(f: FloatArray, w: FloatArray, dt: float, alpha: float, u0: FloatArray,
                     gravity: float, out: FloatArray) -> None:  # pragma: no cover
    """Gyro-propagated, accelerometer-blended up direction ``u``; signals in (x_h, y_h, u)."""
    ux, uy, uz = u0[0], u0[1], u0[2]
    for k in range(f.shape[0]):
        if k > 0:
            # u is fixed in the navigation frame, so in the body frame it turns by -w dt:
            # exact rotation (Rodrigues) with the mean rate of the interval
            wx = 0.5 * (w[k - 1, 0] + w[k, 0])
            wy = 0.5 * (w[k - 1, 1] + w[k, 1])
            wz = 0.5 * (w[k - 1, 2] + w[k, 2])
            wn = np.sqrt(wx * wx + wy * wy + wz * wz)
            if wn > 0.0:
                kx, ky, kz = -wx / wn, -wy / wn, -wz / wn
                c, s = np.cos(wn * dt), np.sin(wn * dt)
                kd = (kx * ux + ky * uy + kz * uz) * (1.0 - c)
                cx = ky * uz - kz * uy
                cy = kz * ux - kx * uz
                cz = kx * uy - ky * ux
                ux, uy, uz = (ux * c + cx * s + kx * kd, uy * c + cy * s + ky * kd,
                              uz * c + cz * s + kz * kd)
            fn = np.sqrt(f[k, 0] ** 2 + f[k, 1] ** 2 + f[k, 2] ** 2)
            if fn > 0.0:
                ux = (1.0 - alpha) * ux + alpha * f[k, 0] / fn
                uy = (1.0 - alpha) * uy + alpha * f[k, 1] / fn
                uz = (1.0 - alpha) * uz + alpha * f[k, 2] / fn
            un = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux /= un
            uy /= un
            uz /= un
        # forward: body x projected on the horizontal; left: u x forward
        xx, xy, xz = 1.0 - ux * ux, -ux * uy, -ux * uz
        xn = np.sqrt(xx * xx + xy * xy + xz * xz)
        xx /= xn
        xy /= xn
        xz /= xn
        yx = uy * xz - uz * xy
        yy = uz * xx - ux * xz
        yz = ux * xy - uy * xx
        out[k, 0] = f[k, 0] * xx + f[k, 1] * xy + f[k, 2] * xz
        out[k, 1] = f[k, 0] * yx + f[k, 1] * yy + f[k, 2] * yz
        out[k, 2] = f[k, 0] * ux + f[k, 1] * uy + f[k, 2] * uz - gravity
        out[k, 3] = w[k, 0] * xx + w[k, 1] * xy + w[k, 2] * xz
        out[k, 4] = w[k, 0] * yx + w[k, 1] * yy + w[k, 2] * yz
        out[k, 5] = w[k, 0] * ux + w[k, 1] * uy + w[k, 2] * uz


def levelled_gait_signals(t: ArrayLike, specific_force_b: ArrayLike, angular_rate_b: ArrayLike,
                          *, tau_s: float = 2.0, gravity_m_s2: float = GRAVITY_M_S2
                          ) -> FloatArray:
    """AP / ML / vertical acceleration and roll / pitch / yaw rate of a waist unit, (N, 6).

    The up direction in the body frame is propagated with the gyroscope and pulled towards the
    accelerometer with time constant ``tau_s`` (a tilt-only complementary filter); forward is
    the body x axis projected on the horizontal, left completes the right-handed frame.
    Gravity is removed from the vertical acceleration. Columns: :data:`GAIT_SIGNAL_COLUMNS`.

    Parameters
    ----------
    t: uniformly sampled times, s (N,).
    specific_force_b: body-frame specific force (x forward, y left, z up), m/s^2 (N, 3).
    angular_rate_b: body-frame angular rate, rad/s (N, 3).
    tau_s: time constant of the accelerometer correction, s.
    gravity_m_s2: gravity removed from the vertical channel, m/s^2.
    """
    tt = np.asarray(t, dtype=np.float64)
    f = np.ascontiguousarray(specific_force_b, dtype=np.float64)
    w = np.ascontiguousarray(angular_rate_b, dtype=np.float64)
    if tt.ndim != 1 or len(tt) < 2 or not np.all(np.diff(tt) > 0):
        raise InputError("times", where="t", expected="at least 2 strictly increasing times")
    for name, arr in (("specific_force_b", f), ("angular_rate_b", w)):
        if arr.shape != (len(tt), 3) or not np.all(np.isfinite(arr)):
            raise InputError(f"shape {arr.shape}", where=name,
                             expected=f"({len(tt)}, 3) finite values")
    if not tau_s > 0:
        raise InputError(f"tau_s={tau_s}", where="tau_s", expected="> 0 s")
    dt = float(np.median(np.diff(tt)))
    head = f[: max(1, min(len(f), round(1.0 / dt)))]
    u0 = (head / np.maximum(np.linalg.norm(head, axis=1), 1e-12)[:, None]).mean(axis=0)
    if np.linalg.norm(u0) < 1e-6:
        raise InputError("no gravity in the first second", where="specific_force_b",
                         expected="specific force including gravity")
    out = np.empty((len(tt), 6))
    _levelled_kernel(f, w, dt, min(1.0, dt / tau_s), u0 / np.linalg.norm(u0),
                     float(gravity_m_s2), out)
    return out


@dataclass(frozen=True, slots=True)
class StrideWaveforms:
    """Stride-normalized signals.

    Attributes
    ----------
    waveforms: (S, P, C) signals on the stride phase ``k / P`` (0 at the first heel strike of
        the stride, 0.5 at the opposite foot's heel strike, linear in time in between); strides
        that start on the right foot are mirrored (columns of ML acceleration, roll and yaw
        rate negated), so every stride reads as starting on the left foot.
    start_s, duration_s: first heel strike and duration of each stride, s.
    started_left: True where the stride started on the left foot.
    """

    waveforms: FloatArray
    start_s: FloatArray
    duration_s: FloatArray
    started_left: NDArray[np.bool_]

    def mean(self) -> FloatArray:
        """Mean waveform (P, C)."""
        if len(self.start_s) == 0:
            raise InputError("no stride", where="stride waveforms",
                             expected="at least one valid stride")
        return np.asarray(self.waveforms.mean(axis=0), dtype=np.float64)


def stride_waveforms(t: ArrayLike, signals: ArrayLike, contacts_s: ArrayLike,
                     contact_left: ArrayLike, *, bout: ArrayLike | None = None,
                     points: int = 100, min_stride_s: float = 0.8, max_stride_s: float = 1.8,
                     mirror_columns: tuple[int, ...] = _MIRRORED) -> StrideWaveforms:
    """Cut ``signals`` into strides between same-foot heel strikes and resample them.

    A stride is three consecutive contacts ``c0 < c1 < c2`` of one bout with alternating feet,
    a duration within ``[min_stride_s, max_stride_s]`` and the middle contact within 35-65 % of
    it. Contacts may contain NaN (a missed contact); strides touching one are skipped.

    Parameters
    ----------
    t: sample times, s (N,).
    signals: (N, C) signals, e.g. :func:`levelled_gait_signals`.
    contacts_s: heel-strike (initial contact) times, s, sorted.
    contact_left: True for left-foot contacts.
    bout: walking bout of each contact (strides never span two bouts); one bout if None.
    points: samples per stride.
    min_stride_s, max_stride_s: accepted stride durations, s.
    mirror_columns: columns whose sign flips between the left and the right side.
    """
    tt = np.asarray(t, dtype=np.float64)
    x = np.asarray(signals, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    ic = np.asarray(contacts_s, dtype=np.float64)
    left = np.asarray(contact_left, dtype=bool)
    b = np.zeros(len(ic), dtype=np.int64) if bout is None else np.asarray(bout, dtype=np.int64)
    if x.shape[0] != len(tt):
        raise InputError(f"{x.shape[0]} rows for {len(tt)} times", where="signals",
                         expected="one row per time")
    if left.shape != ic.shape or b.shape != ic.shape:
        raise InputError("lengths differ", where="contact_left/bout",
                         expected=f"{len(ic)} values like contacts_s")
    if points < 4:
        raise InputError(f"points={points}", where="points", expected=">= 4")
    ph = np.arange(points) / points
    flip = np.ones(x.shape[1])
    flip[[c for c in mirror_columns if c < x.shape[1]]] = -1.0
    waves: list[FloatArray] = []
    starts: list[float] = []
    durations: list[float] = []
    lefts: list[bool] = []
    for i in range(len(ic) - 2):
        c0, c1, c2 = ic[i], ic[i + 1], ic[i + 2]
        if not (np.isfinite(c0) and np.isfinite(c1) and np.isfinite(c2)):
            continue
        if b[i] != b[i + 2] or left[i] == left[i + 1] or left[i] != left[i + 2]:
            continue
        dur = c2 - c0
        if not (min_stride_s <= dur <= max_stride_s) or not 0.35 < (c1 - c0) / dur < 0.65:
            continue
        if c0 < tt[0] or c2 > tt[-1]:
            continue
        ts = np.where(ph < 0.5, c0 + (c1 - c0) * ph / 0.5, c1 + (c2 - c1) * (ph - 0.5) / 0.5)
        wave = np.column_stack([np.interp(ts, tt, col) for col in x.T])
        waves.append(wave if left[i] else wave * flip)
        starts.append(float(c0))
        durations.append(float(dur))
        lefts.append(bool(left[i]))
    return StrideWaveforms(
        waveforms=np.array(waves).reshape(len(waves), points, x.shape[1]),
        start_s=np.array(starts), duration_s=np.array(durations),
        started_left=np.array(lefts, dtype=bool))


def waveform_harmonics(waveform: ArrayLike, n_max: int = 6) -> ComplexArray:
    """Stride harmonics 1..``n_max`` of a stride-normalized waveform (P,) or (P, C).

    Row ``n - 1`` holds ``c_n`` with ``x(k / P) ~ mean + sum_n Re(c_n exp(2 pi i n k / P))``.
    """
    x = np.asarray(waveform, dtype=np.float64)
    if x.shape[0] < 2 * n_max + 1:
        raise InputError(f"{x.shape[0]} points", where="waveform",
                         expected=f"at least {2 * n_max + 1} points per stride")
    c = np.fft.rfft(x, axis=0) * (2.0 / x.shape[0])
    return np.asarray(c[1: n_max + 1], dtype=np.complex128)
