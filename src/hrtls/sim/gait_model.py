"""Body oscillation of a waist-worn unit during gait, and the true step events.

The gait phase ``phi`` counts steps: it grows at the step frequency ``f = v / l(v)`` and every
integer of ``phi`` is a heel strike. Step length grows with speed,
``l = a + b v`` (Tarrio Sec. IV fits ``l = 0.32 + 0.26 v`` for walking); on stairs one step is one
tread. Each stop-free run holds a whole number of steps, so the true step lengths add up exactly
to the distance walked.

Around the nominal path the waist moves (body frame: x forward, y left, z up):

* vertical bounce at the step frequency with 2nd/3rd harmonics and a left/right asymmetry at the
  stride frequency; its acceleration peak-to-peak follows Weinberg's relation
  ``l = K (A_max - A_min)^(1/4)`` (Tarrio eq. 3, Inderst eq. 4.24) for the person's ``K``, so a
  Weinberg estimator with the right ``K`` is unbiased on this model;
* forward surge at the step frequency (braking at heel strike);
* lateral sway at the stride frequency;
* pelvis yaw, roll (stride frequency) and pitch (step frequency) oscillation plus a forward lean.

All amplitudes fade in with speed (zero while standing) and vary from step to step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from hrtls.data import StepEvents
from hrtls.sim.motion import GAIT_RUN, GAIT_STAIRS, MotionTruth

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True, kw_only=True)
class GaitParams:
    """One person's gait.

    Attributes
    ----------
    step_a_m, step_b_s: walking step length ``l = step_a_m + step_b_s v`` (m, s).
    run_a_m, run_b_s: running step length ``l = run_a_m + run_b_s v``.
    weinberg_k_walk, weinberg_k_run: Weinberg constant ``K`` (m / (m/s^2)^(1/4)) that sets the
        vertical acceleration peak-to-peak ``(l / K)^4`` while walking / running.
    stairs_acc_pp_m_s2: vertical acceleration peak-to-peak on stairs, m/s^2.
    step_cv: coefficient of variation of step length from step to step.
    amplitude_cv: coefficient of variation of the oscillation amplitudes.
    harmonic2_ratio, harmonic3_ratio: 2nd / 3rd harmonic of vertical acceleration relative to
        the fundamental.
    asymmetry_ratio: stride-frequency (left/right) vertical acceleration relative to the
        fundamental.
    forward_ratio: forward surge acceleration relative to the vertical fundamental.
    lateral_sway_m: lateral sway amplitude, m.
    pelvis_yaw_rad, pelvis_roll_rad, pelvis_pitch_rad: pelvis rotation amplitudes, rad.
    lean_rad: forward lean while walking, rad.
    envelope_speed_m_s: speed at which the oscillation reaches full amplitude, m/s.
    """

    step_a_m: float = 0.32
    step_b_s: float = 0.26
    run_a_m: float = 0.55
    run_b_s: float = 0.20
    weinberg_k_walk: float = 0.42
    weinberg_k_run: float = 0.50
    stairs_acc_pp_m_s2: float = 5.0
    step_cv: float = 0.03
    amplitude_cv: float = 0.08
    harmonic2_ratio: float = 0.30
    harmonic3_ratio: float = 0.12
    asymmetry_ratio: float = 0.05
    forward_ratio: float = 0.5
    lateral_sway_m: float = 0.02
    pelvis_yaw_rad: float = 0.07
    pelvis_roll_rad: float = 0.05
    pelvis_pitch_rad: float = 0.025
    lean_rad: float = 0.03
    envelope_speed_m_s: float = 0.5

    def step_length(self, speed_m_s: FloatArray, gait: NDArray[np.int64]) -> FloatArray:
        """Step length (m) at horizontal speed ``speed_m_s`` for walking or running samples."""
        v = np.asarray(speed_m_s, dtype=np.float64)
        walk = self.step_a_m + self.step_b_s * v
        run = self.run_a_m + self.run_b_s * v
        return np.asarray(np.where(gait == GAIT_RUN, run, walk), dtype=np.float64)


@dataclass(frozen=True, slots=True)
class GaitResult:
    """Oscillation around the nominal motion and the true steps.

    Attributes
    ----------
    phase: gait phase (steps counted from the start; heel strikes at integers).
    offset_body: waist displacement from the nominal path, m, (N, 3) in the heading frame
        (forward, left, up).
    euler_osc: pelvis (roll, pitch, yaw) added to the nominal attitude, rad, (N, 3).
    steps: true step events (heel strike to heel strike).
    foot: alternating foot label of each step (0 for even, 1 for odd step numbers).
    """

    phase: FloatArray
    offset_body: FloatArray
    euler_osc: FloatArray
    steps: StepEvents
    foot: NDArray[np.int64]


def _smooth_noise(rng: np.random.Generator, n: int, dt: float, tau_s: float) -> FloatArray:
    """Smooth (infinitely differentiable) unit-variance noise with correlation time ``tau_s``.

    White noise convolved with a Gaussian kernel of standard deviation ``tau_s``; a first-order
    Gauss-Markov process would not do, its kinks put white noise into the accelerations.
    """
    if n == 0:
        return np.zeros(0)
    sigma = max(tau_s / dt, 1.0)
    x = gaussian_filter1d(rng.standard_normal(n), sigma, mode="reflect")
    return np.asarray(x * np.sqrt(2.0 * np.sqrt(np.pi) * sigma), dtype=np.float64)


def _waveform_pp(p: GaitParams) -> float:
    """Peak-to-peak of the unit-fundamental vertical acceleration waveform over a stride."""
    th = np.linspace(0.0, 4.0 * np.pi, 4001)
    a = (np.cos(th) + p.harmonic2_ratio * np.cos(2 * th + 0.6)
         + p.harmonic3_ratio * np.cos(3 * th + 1.2) + p.asymmetry_ratio * np.cos(0.5 * th))
    return float(a.max() - a.min())


def _moving_average(x: FloatArray, n: int) -> FloatArray:
    if n <= 1 or len(x) == 0:
        return x
    pad = np.concatenate([np.full(n // 2, x[0]), x, np.full(n - n // 2 - 1, x[-1])])
    c = np.cumsum(np.concatenate([[0.0], pad]))
    return np.asarray((c[n:] - c[:-n]) / n, dtype=np.float64)


def simulate_gait(motion: MotionTruth, params: GaitParams, rng: np.random.Generator
                  ) -> GaitResult:
    """Gait phase, body oscillation and true steps for ``motion``."""
    p = params
    t, v, dt = motion.t, motion.speed, motion.dt
    n = len(t)
    gait = motion.gait
    l_model = p.step_length(v, gait)
    l_now = np.where(np.isfinite(motion.step_length_override), motion.step_length_override,
                     l_model)
    variation = 1.0 + p.step_cv * _smooth_noise(rng, n, dt, 0.8)
    rate = np.where(motion.moving, v / l_now * variation, 0.0)
    if dt > 0:  # smooth jumps of the step length (walk/run, stairs) so the phase has no kinks
        rate = gaussian_filter1d(rate, 0.15 / dt, mode="nearest")
    phase = np.zeros(n)
    t_start: list[FloatArray] = []
    t_end: list[FloatArray] = []
    offset = 0.0
    n_runs = int(motion.run_id.max()) + 1 if n else 0
    for r in range(n_runs):
        idx = np.flatnonzero(motion.run_id == r)
        if len(idx) < 2:
            continue
        local = np.concatenate([[0.0], np.cumsum(0.5 * (rate[idx[1:]] + rate[idx[:-1]]) * dt)])
        total = local[-1]
        n_steps = max(1, round(total))
        local *= n_steps / total if total > 0 else 0.0
        phase[idx] = offset + local
        # phase stays constant while standing after this run
        after = idx[-1] + 1
        phase[after:] = offset + n_steps
        ks = np.arange(n_steps + 1, dtype=np.float64)
        tk = np.interp(ks, local, t[idx])  # heel strikes: where the phase crosses integers
        t_start.append(tk[:-1])
        t_end.append(tk[1:])
        offset += n_steps
    ts = np.concatenate(t_start) if t_start else np.zeros(0)
    te = np.concatenate(t_end) if t_end else np.zeros(0)
    s_a = np.interp(ts, t, motion.s)
    s_b = np.interp(te, t, motion.s)
    pa = np.column_stack([np.interp(ts, t, c) for c in motion.xyz.T]) if len(ts) else \
        np.zeros((0, 3))
    pb = np.column_stack([np.interp(te, t, c) for c in motion.xyz.T]) if len(te) else \
        np.zeros((0, 3))
    mid = np.clip(np.searchsorted(t, 0.5 * (ts + te)), 0, max(n - 1, 0))
    steps = StepEvents.build(
        t_start=ts, t_end=te, length_m=np.maximum(s_b - s_a, 0.0),
        heading_rad=np.arctan2(pb[:, 1] - pa[:, 1], pb[:, 0] - pa[:, 0]),
        dz_m=pb[:, 2] - pa[:, 2], activity=motion.activity[mid] if n else np.zeros(0, int),
        frequency_hz=1.0 / np.maximum(te - ts, 1e-9),
    )

    # amplitudes, from the speed-dependent step length at a floored speed
    v_env = p.envelope_speed_m_s
    v_eff = np.maximum(v, v_env)
    l_eff = np.where(np.isfinite(motion.step_length_override), motion.step_length_override,
                     p.step_length(v_eff, gait))
    k = np.where(gait == GAIT_RUN, p.weinberg_k_run, p.weinberg_k_walk)
    acc_pp = np.where(gait == GAIT_STAIRS, p.stairs_acc_pp_m_s2, (l_eff / k) ** 4)
    omega = 2.0 * np.pi * v_eff / l_eff
    win = max(1, round(1.0 / dt)) if dt > 0 else 1
    # fundamental's displacement amplitude, m, such that the whole waveform's peak-to-peak
    # acceleration is acc_pp
    disp = _moving_average(acc_pp / (_waveform_pp(p) * omega**2), win)
    x = np.clip(v / v_env, 0.0, 1.0)
    envelope = x * x * x * (x * (6.0 * x - 15.0) + 10.0)
    envelope = envelope * (1.0 + p.amplitude_cv * _smooth_noise(rng, n, dt, 1.0))
    a_z = envelope * disp
    th = 2.0 * np.pi * phase
    up = -a_z * (np.cos(th) + p.harmonic2_ratio / 4.0 * np.cos(2 * th + 0.6)
                 + p.harmonic3_ratio / 9.0 * np.cos(3 * th + 1.2)
                 + p.asymmetry_ratio * 4.0 * np.cos(0.5 * th))
    fwd = a_z * p.forward_ratio * np.cos(th + 0.3)
    side = envelope * p.lateral_sway_m * np.sin(0.5 * th)
    roll = envelope * p.pelvis_roll_rad * np.sin(0.5 * th + 0.4)
    pitch = envelope * (p.pelvis_pitch_rad * np.cos(th) + p.lean_rad)
    yaw = envelope * p.pelvis_yaw_rad * np.sin(0.5 * th - 0.5)
    # feet alternate (the stride-frequency terms flip sign every step); even steps are labelled 0
    foot = np.mod(np.arange(len(ts)), 2).astype(np.int64)
    return GaitResult(phase=phase, offset_body=np.column_stack([fwd, side, up]),
                      euler_osc=np.column_stack([roll, pitch, yaw]), steps=steps, foot=foot)


def fill_step_extremes(steps: StepEvents, t: FloatArray, acc_up: FloatArray) -> StepEvents:
    """Steps with ``acc_max`` / ``acc_min`` set to the extremes of ``acc_up`` within each step."""
    if len(steps) == 0:
        return steps
    n = len(t)
    i0 = np.minimum(np.searchsorted(t, steps.t_start), n - 1)
    i1 = np.clip(np.searchsorted(t, steps.t_end, side="right"), i0 + 1, n)
    ext = np.append(acc_up, 0.0)
    pairs = np.column_stack([i0, i1]).ravel()
    hi = np.maximum.reduceat(ext, pairs)[::2]
    lo = np.minimum.reduceat(ext, pairs)[::2]
    return StepEvents.build(t_start=steps.t_start, t_end=steps.t_end, length_m=steps.length_m,
                            heading_rad=steps.heading_rad, dz_m=steps.dz_m,
                            activity=steps.activity, frequency_hz=steps.frequency_hz,
                            acc_max=hi, acc_min=lo)
