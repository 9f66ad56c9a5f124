"""Synthetic waist-IMU gait signals for tests, benchmarks and the default activity model.

Not an estimator and never used by the pipeline: a small generator of the acceleration of the
lower back of a simulated person (one harmonic model per activity), turned into the specific
force of a device mounted in any orientation. The full scenario simulator lives in ``hrtls.sim``.

Model (body/user frame: AP forward, ML left, V up; step phase ``phi`` is 0 at each step event,
the vertical-acceleration peak just after heel strike, as measured on lower-back recordings):

* vertical ``A_v (cos phi + h2 cos(2 phi + p2) + h3 cos(3 phi + p3))``;
* antero-posterior ``A_ap cos(phi - 1.4 pi)`` (deceleration early in the step, forward
  acceleration before the next heel strike);
* medio-lateral ``A_ml sin(phi / 2 + p_ml)`` (stride frequency, alternating sides);
* standing: sway and sensor noise only.

Step length and the vertical peak-to-peak are those of the scenario simulator's person model
(:class:`hrtls.sim.gait_model.GaitParams`, one model for both generators): ``l = a + b v`` with
``v = l f`` at the drawn step frequency ``f``, so ``l = a / (1 - b f)``; peak-to-peak
``A_1 (v / 1 m/s)^alpha`` (walking, running at 3 m/s) or the fixed stairs values. No estimator's
law (Weinberg, Kim, frequency-linear) is built in.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hrtls.data import Activity
from hrtls.frames import GRAVITY_M_S2, quat_from_euler, quat_multiply, quat_rotate
from hrtls.gait._state import FloatArray
from hrtls.sim.gait_model import GaitParams
from hrtls.sim.motion_truth import GAIT_RUN, GAIT_WALK
from hrtls.sim.stop_model import (
    CLOSING_AMPLITUDE_RANGE,
    CLOSING_DELAY_STEPS_RANGE,
    LAST_STEP_AMPLITUDE_RANGE,
)


@dataclass(frozen=True, kw_only=True, slots=True)
class SimPerson:
    """Gait characteristics of one simulated person (``gait``: step length and amplitude laws)."""

    gait: GaitParams = field(default_factory=GaitParams)
    walk_hz: float = 1.85
    run_hz: float = 2.8
    up_hz: float = 1.5
    down_hz: float = 1.8
    ap_ratio: float = 0.7
    ml_walk_m_s2: float = 1.0
    ml_up_ratio: float = 1.3
    ml_down_ratio: float = 1.8
    h2: float = 0.3
    h3: float = 0.1
    p2: float = 0.5
    p3: float = 1.0
    noise_m_s2: float = 0.08
    step_jitter: float = 0.04

    @classmethod
    def random(cls, rng: np.random.Generator) -> SimPerson:
        """A person with randomly drawn characteristics."""
        return cls(gait=GaitParams().drawn(rng), walk_hz=rng.uniform(1.6, 2.1),
                   run_hz=rng.uniform(2.6, 3.2), up_hz=rng.uniform(1.3, 1.7),
                   down_hz=rng.uniform(1.6, 2.0), ap_ratio=rng.uniform(0.5, 0.9),
                   ml_walk_m_s2=rng.uniform(0.8, 1.1), ml_up_ratio=rng.uniform(1.2, 1.5),
                   ml_down_ratio=rng.uniform(1.6, 2.2), h2=rng.uniform(0.1, 0.4),
                   h3=rng.uniform(0.0, 0.2), p2=rng.uniform(0, 2 * np.pi),
                   p3=rng.uniform(0, 2 * np.pi), noise_m_s2=rng.uniform(0.03, 0.12),
                   step_jitter=rng.uniform(0.02, 0.06))

    def step_length(self, activity: int, f_hz: float) -> float:
        """True step length (m) of one step at step frequency ``f_hz``."""
        if activity in (Activity.UPSTAIRS, Activity.DOWNSTAIRS):
            return 0.30
        g = self.gait
        a, b = (g.run_a_m, g.run_b_s) if activity == Activity.RUNNING else (g.step_a_m, g.step_b_s)
        return a / max(1.0 - b * f_hz, 0.2)

    def vertical_pp(self, activity: int, speed_m_s: float) -> float:
        """True vertical acceleration peak-to-peak (m/s^2) of one step."""
        if activity == Activity.UPSTAIRS:
            return self.gait.stairs_up_acc_pp_m_s2
        if activity == Activity.DOWNSTAIRS:
            return self.gait.stairs_down_acc_pp_m_s2
        gait = GAIT_RUN if activity == Activity.RUNNING else GAIT_WALK
        return float(self.gait.vertical_pp(np.array([speed_m_s]), np.array([gait]))[0])


def _waveform_pp(h2: float, h3: float, p2: float, p3: float) -> float:
    """Peak-to-peak of ``cos phi + h2 cos(2 phi + p2) + h3 cos(3 phi + p3)``."""
    phi = np.linspace(0.0, 2.0 * np.pi, 256, endpoint=False)
    w = np.cos(phi) + h2 * np.cos(2 * phi + p2) + h3 * np.cos(3 * phi + p3)
    return float(w.max() - w.min())


@dataclass(frozen=True, slots=True, eq=False)
class SimWalk:
    """A simulated recording.

    Attributes
    ----------
    t: times, s. acc_d: device specific force, m/s^2 (N, 3). q_nd: device -> ENU attitude.
    q_bd: device -> body mounting. activity: per-sample Activity codes.
    step_t: step event times, s. step_length_m: true step lengths. step_heading_rad: true
    walking direction of each step. step_activity: activity of each step.
    """

    t: FloatArray
    acc_d: FloatArray
    q_nd: FloatArray
    q_bd: FloatArray
    activity: np.ndarray
    step_t: FloatArray
    step_length_m: FloatArray
    step_heading_rad: FloatArray
    step_activity: np.ndarray
    speed_m_s: FloatArray
    person: SimPerson = field(default_factory=SimPerson)


def random_mounting(rng: np.random.Generator) -> FloatArray:
    """A uniformly random device -> body rotation [w, x, y, z]."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return q * (1.0 if q[0] >= 0 else -1.0)


def simulate(segments: list[tuple[int, float]], *, person: SimPerson | None = None,
             rate_hz: float = 100.0, q_bd: FloatArray | None = None,
             turn_rate_rad_s: float = 0.0, heading0_rad: float = 0.0,
             ramp_s: float = 1.0, seed: int = 0, stop_amplitude: float | None = None,
             turns: tuple[tuple[float, float, float], ...] = (),
             turn_amplitude: float = 0.5, end_amplitude: float | None = None,
             closing: tuple[float, float] | None = None) -> SimWalk:
    """Simulate a sequence of ``(activity, duration_s)`` segments.

    Parameters
    ----------
    segments: activities and their durations, s.
    person: gait characteristics (default :class:`SimPerson`).
    rate_hz: sampling rate, Hz.
    q_bd: device -> body mounting (identity if None).
    turn_rate_rad_s: constant turn rate of the walking direction while moving, rad/s.
    heading0_rad: initial walking direction (ENU), rad.
    ramp_s: duration of the speed ramps at the start and end of each bout, s.
    seed: random seed of noise and jitter.
    stop_amplitude: None: the step amplitude ignores the ramps; else the vertical and AP
        amplitude of the steps of a ramp scale from this fraction (bout start and end) to 1
        (smaller steps while starting and stopping).
    end_amplitude: the fraction at the end of a bout (None: ``stop_amplitude``).
    closing: ``(amplitude, delay_steps)``: after the last step of a bout followed by standing,
        a closing movement (the trailing foot set beside the other, no step event and no
        forward speed): one vertical cycle of ``amplitude`` times the bout's walking
        amplitude, peaking ``delay_steps`` step periods after the last step event.
    turns: turns on the spot ``(t_start_s, duration_s, angle_rad)``: the walking direction
        turns by the angle at a constant rate, the step amplitude and speed scale by
        ``turn_amplitude`` (short, flat turning steps).
    """
    rng = np.random.default_rng(seed)
    p = person or SimPerson()
    mount = np.array([1.0, 0.0, 0.0, 0.0]) if q_bd is None else np.asarray(q_bd, float)
    total = sum(d for _, d in segments)
    n = round(total * rate_hz)
    t = np.arange(n) / rate_hz
    g = _GaitProfile.zeros(n)
    i0 = 0
    cyc = 0.0
    for a, dur in segments:
        i1 = min(n, i0 + round(dur * rate_hz))
        g.act[i0:i1] = a
        if a == Activity.STANDING:
            g.phase[i0:i1] = cyc
        else:
            cyc = _bout_steps(g, a, i0, i1, cyc=cyc, person=p, rate_hz=rate_hz, rng=rng)
            # speed ramps up over the first and down over the last second of a bout
            ramp = np.clip(np.minimum(t[i0:i1] - t[i0], t[i1 - 1] - t[i0:i1]) / ramp_s, 0, 1)
            g.speed[i0:i1] *= ramp
            g.ramp[i0:i1] = ramp
            g.late[(i0 + i1) // 2:i1] = True
        i0 = i1
    turn_rate = np.where(g.act != Activity.STANDING, turn_rate_rad_s, 0.0)
    if stop_amplitude is not None:
        lo = np.full(n, stop_amplitude)
        if end_amplitude is not None:   # the second half of each bout ramps to its end value
            lo = np.where(g.late, end_amplitude, lo)
        g.amp_v *= lo + (1.0 - lo) * g.ramp
    for t_turn, d_turn, angle in turns:
        inside = (t >= t_turn) & (t < t_turn + d_turn)
        turn_rate = np.where(inside, turn_rate + angle / d_turn, turn_rate)
        g.amp_v[inside] *= turn_amplitude
        g.speed[inside] *= turn_amplitude
    # forward acceleration of the mean speed (smoothed over 0.5 s)
    kern = np.ones(max(1, round(0.5 * rate_hz)))
    speed = np.convolve(g.speed, kern / kern.size, mode="same")
    psi = heading0_rad + np.cumsum(turn_rate) * (1.0 / rate_hz)
    # step events: integer crossings of the phase while moving
    moving = g.act != Activity.STANDING
    cross = np.flatnonzero((np.floor(g.phase[1:]) > np.floor(g.phase[:-1])) & moving[1:]) + 1
    step_t = t[cross]
    extra_v = None if closing is None else _closing_pulses(g, t, step_t, p, *closing)
    acc_d, q_nd = _device_signals(g, t, speed, psi, person=p, mount=mount, rate_hz=rate_hz,
                                  rng=rng, extra_v=extra_v)
    # length and heading of the step that *ends* at each event
    return SimWalk(t, acc_d, q_nd, mount, g.act, step_t, g.len_s[cross - 1], psi[cross],
                   g.act[cross - 1], speed, p)


@dataclass
class _GaitProfile:
    """Per-sample gait of a simulated walk, before it becomes device signals."""

    act: np.ndarray      # activity code
    phase: FloatArray    # step phase, cycles
    amp_v: FloatArray    # vertical amplitude
    amp_ml: FloatArray   # mediolateral amplitude
    shape: FloatArray    # h2, h3 scale and a stairs/run shape flag (n, 3)
    len_s: FloatArray    # true length of the step each sample belongs to
    ap_s: FloatArray     # antero-posterior amplitude relative to walking
    speed: FloatArray    # forward speed, m/s
    ramp: FloatArray     # speed ramp of the bout (1 outside the ramps)
    late: np.ndarray     # in the second half of a bout (its end ramp)

    @classmethod
    def zeros(cls, n: int) -> _GaitProfile:
        """A profile of ``n`` samples (activity unset, ramp 1)."""
        return cls(np.empty(n, dtype=np.int64), np.zeros(n), np.zeros(n), np.zeros(n),
                   np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n), np.ones(n),
                   np.zeros(n, dtype=bool))


def _closing_pulses(g: _GaitProfile, t: FloatArray, step_t: FloatArray, person: SimPerson,
                    amplitude: float, delay_steps: float) -> FloatArray:
    """Vertical acceleration of the closing movement after each bout that ends standing.

    One cycle ``a cos(2 pi (t - t_c) / T)`` under a Hann window of half-width ``T`` (the
    walking step period); ``a`` is the amplitude times the bout's median vertical peak over
    1-3.5 s before its last step (before the end ramp's last second).
    """
    out = np.zeros_like(t)
    period = 1.0 / person.walk_hz
    phi = np.linspace(0.0, 2.0 * np.pi, 256, endpoint=False)
    crest = float(np.max(np.cos(phi) + person.h2 * np.cos(2 * phi + person.p2)
                         + person.h3 * np.cos(3 * phi + person.p3)))
    moving = g.act != Activity.STANDING
    ends = np.flatnonzero(moving[:-1] & ~moving[1:])
    for i_end in ends:
        last = step_t[step_t <= t[i_end]]
        if last.size == 0:
            continue
        t_c = last[-1] + delay_steps * period
        i0, i1 = np.searchsorted(t, [last[-1] - 3.5, last[-1] - 1.0])
        amp = amplitude * crest * float(np.median(g.amp_v[i0:i1 + 1]))
        u = (t - t_c) / period
        win = np.where(np.abs(u) < 1.0, 0.5 * (1.0 + np.cos(np.pi * u)), 0.0)
        out += amp * win * np.cos(2.0 * np.pi * u)
    return out


def _bout_steps(g: _GaitProfile, a: int, i0: int, i1: int, *, cyc: float, person: SimPerson,
                rate_hz: float, rng: np.random.Generator) -> float:
    """Fill samples ``i0:i1`` of ``g`` with steps of activity ``a``; the phase at the end.

    Piecewise-constant frequency with jitter per step; the phase starts at ``cyc`` and ends
    rounded up to a whole cycle.
    """
    p = person
    f0 = {Activity.WALKING: p.walk_hz, Activity.RUNNING: p.run_hz,
          Activity.UPSTAIRS: p.up_hz, Activity.DOWNSTAIRS: p.down_hz}[Activity(a)]
    k = i0
    while k < i1:
        f = f0 * (1.0 + p.step_jitter * rng.normal())
        m = max(1, round(rate_hz / f))
        kk = min(i1, k + m)
        g.phase[k:kk] = cyc + np.arange(kk - k) / m
        length = p.step_length(a, f)
        g.len_s[k:kk] = length
        g.speed[k:kk] = length * f
        h2 = p.h2 * (1.8 if a == Activity.UPSTAIRS else 1.0)
        h3 = p.h3 * (3.0 if a == Activity.DOWNSTAIRS else 1.0) + (
            0.15 if a == Activity.DOWNSTAIRS else 0.0)
        amp = p.vertical_pp(a, length * f) / _waveform_pp(h2, h3, p.p2, p.p3)
        g.amp_v[k:kk] = amp * (1.0 + 0.05 * rng.normal())
        g.amp_ml[k:kk] = p.ml_walk_m_s2 * {
            Activity.WALKING: 1.0, Activity.RUNNING: 1.5, Activity.UPSTAIRS: p.ml_up_ratio,
            Activity.DOWNSTAIRS: p.ml_down_ratio}[Activity(a)]
        g.ap_s[k:kk] = {Activity.WALKING: 1.0, Activity.RUNNING: 1.0,
                        Activity.UPSTAIRS: 0.5, Activity.DOWNSTAIRS: 0.6}[Activity(a)]
        g.shape[k:kk, 0] = h2
        g.shape[k:kk, 1] = h3
        cyc += (kk - k) / m
        k = kk
    return float(np.ceil(cyc - 1e-9))


def _device_signals(g: _GaitProfile, t: FloatArray, speed: FloatArray, psi: FloatArray, *,
                    person: SimPerson, mount: FloatArray, rate_hz: float,
                    rng: np.random.Generator, extra_v: FloatArray | None = None
                    ) -> tuple[FloatArray, FloatArray]:
    """Device-frame specific force (with noise) and attitude ``q_nd`` of the profile.

    ``speed`` is the smoothed forward speed (its derivative is the forward acceleration),
    ``psi`` the walking direction; the trunk adds a yaw oscillation at stride frequency and a
    pitch oscillation at step frequency while moving; ``extra_v`` is added to the vertical.
    """
    p = person
    n = t.shape[0]
    phi = 2.0 * np.pi * g.phase
    moving = g.act != Activity.STANDING
    a_mean = np.gradient(speed, 1.0 / rate_hz)
    a_v = g.amp_v * (np.cos(phi) + g.shape[:, 0] * np.cos(2 * phi + p.p2)
                     + g.shape[:, 1] * np.cos(3 * phi + p.p3))
    a_ap = p.ap_ratio * g.ap_s * g.amp_v * np.cos(phi - 1.4 * np.pi)
    a_ml = g.amp_ml * np.sin(0.5 * phi + 0.3)
    sway = 0.05 * np.sin(2 * np.pi * 0.3 * t + rng.uniform(0, 6))
    a_v = np.where(moving, a_v, sway) + (0.0 if extra_v is None else extra_v)
    a_ap = np.where(moving, a_ap, 0.5 * sway) + a_mean
    a_ml = np.where(moving, a_ml, 0.5 * sway)
    trunk = np.where(moving, np.deg2rad(3.0) * np.sin(0.5 * phi), 0.0)
    lin_n = np.column_stack([np.cos(psi) * a_ap - np.sin(psi) * a_ml,
                             np.sin(psi) * a_ap + np.cos(psi) * a_ml, a_v])
    f_n = lin_n + np.array([0.0, 0.0, GRAVITY_M_S2])
    pitch = np.where(moving, np.deg2rad(2.0) * np.sin(phi), 0.0)
    q_nb = quat_from_euler(np.zeros(n), pitch, psi + trunk)
    q_nd = quat_multiply(q_nb, mount[None, :])  # v_n = q_nb q_bd v_d
    q_dn = q_nd * np.array([1.0, -1.0, -1.0, -1.0])
    acc_d = quat_rotate(q_dn, f_n) + p.noise_m_s2 * rng.normal(size=(n, 3))
    return acc_d, q_nd


def short_walk_u_turn(seed: int, *, rate_hz: float = 100.0) -> SimWalk:
    """Stand, walk about 10 m, turn on the spot (U-turn), walk back, stop and stand.

    A random person and mounting; 2-4 s standing at each end, 5.5-8 s each way, a 1.5-2.5 s
    turn of +-180 deg. The steps of the start ramp shrink to 10-40 % of the walking amplitude,
    the turning steps to 25-50 %. The stop follows the real evidence of
    :mod:`hrtls.sim.stop_model` (shared with the scenario simulator): the end ramp ends at
    60-100 % of the walking amplitude, then a closing movement (vertical only, no step event)
    of 0.28-0.49 times the level, 0.9-1.3 step periods after the last step.
    """
    rng = np.random.default_rng(seed)
    person = SimPerson.random(rng)
    st0, w1, turn, w2, st1 = (rng.uniform(2, 4), rng.uniform(5.5, 8), rng.uniform(1.5, 2.5),
                              rng.uniform(5.5, 8), rng.uniform(2, 4))
    segs = [(int(Activity.STANDING), st0), (int(Activity.WALKING), w1 + turn + w2),
            (int(Activity.STANDING), st1)]
    return simulate(segs, person=person, rate_hz=rate_hz, q_bd=random_mounting(rng),
                    seed=seed, stop_amplitude=rng.uniform(0.1, 0.4),
                    turns=((st0 + w1, turn, np.pi * rng.choice([-1.0, 1.0])),),
                    turn_amplitude=rng.uniform(0.25, 0.5),
                    end_amplitude=rng.uniform(*LAST_STEP_AMPLITUDE_RANGE),
                    closing=(rng.uniform(*CLOSING_AMPLITUDE_RANGE),
                             rng.uniform(*CLOSING_DELAY_STEPS_RANGE)))
