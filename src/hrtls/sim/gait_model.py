"""Body oscillation of a waist-worn unit during gait, and the true step events.

The gait phase ``phi`` counts steps: it grows at the step frequency ``f = v / l(v)`` and every
integer of ``phi`` is a heel strike (initial contact). Even integers are heel strikes of the
left foot, odd ones of the right foot (``GaitResult.foot`` 0 = left, 1 = right). Step length grows
with speed, ``l = a + b v`` (Tarrio Sec. IV fits ``l = 0.32 + 0.26 v`` for walking); on stairs
one step is one tread. Each stop-free run holds a whole number of steps, so the true step lengths
add up exactly to the distance walked.

Around the nominal path the waist moves (heading frame: x forward, y left, z up). Every channel
is a sum of harmonics of the stride angle ``theta = pi phi`` (0 at a left heel strike, pi at the
next right heel strike):

* vertical, antero-posterior (AP) and medio-lateral (ML) acceleration
  ``a(t) = sum_n Re(c_n exp(i n theta))``; the displacement that is simulated is
  ``-Re(c_n exp(i n theta)) / (n w_s)^2`` with ``w_s`` the stride angular frequency, so the second
  difference of the position gives back ``a`` (the sensor values are derived from the pose);
* pelvis roll, pitch and yaw angles ``sum_n Re(r_n exp(i n theta))`` plus a forward lean.

The complex coefficients ``c_n`` / ``r_n`` are measured on real lower-back recordings (see
"How the waveform constants were measured" below) at two walking speeds and interpolated in
amplitude and phase between them (held constant outside; running uses the fast shape, which was
not measured on runners). What that gives, relative to the heel strikes:

* vertical: peak ~0.05 s after heel strike, low in mid-stance; step frequency with 2nd / 3rd step
  harmonics that are larger at slow speed (double-bump at slow speed);
* AP: minimum (braking) ~0.1-0.15 s after heel strike, maximum (push-off) ~0.1-0.15 s before the
  next heel strike;
* ML: stride frequency, towards the stance foot (acceleration to the right in mid left stance);
* pelvis yaw ~3.5 deg amplitude at stride frequency (left hip forward at left heel strike), pitch
  ~1 deg at step frequency, roll ~0.5-2 deg at stride frequency (with a 3rd harmonic).

The vertical acceleration peak-to-peak of a step is *not* any estimator's law. It is a power law
in walking speed, ``A_pp = A_1 (v / 1 m/s)^alpha``, fitted to the real lower-back recordings
(mobgap lab, INDIP strides, levelled vertical acceleration): the peak-to-peak of the mean stride
waveform of the three speed groups of ``benchmarks/sim_vs_real.py`` is 2.2 / 3.0 / 4.8 m/s^2 at
0.47 / 0.70 / 1.07 m/s, so ``A_1`` = 4.5 m/s^2 and ``alpha`` = 0.95. (The raw per-step
peak-to-peak is 1.4-2.2 times larger: step-to-step variability and heel-strike impacts that
the harmonic model does not carry; per participant its speed exponent is 0.40 / 0.41 / 0.65,
which sets the person-to-person spread of ``alpha``.) Step length is the person's own
``l = a + b v`` (the paper's law of each scenario; 0.50-0.59 s slopes on the real strides), so
Weinberg's ``l = K A_pp^(1/4)`` holds for no constant ``K`` (it predicts ``l ~ v^(alpha/4)``),
and the frequency law ``l = c f + d`` of Basso holds for none either (``l = a / (1 - b f)``).
Each scenario person is drawn around its base parameters (:meth:`GaitParams.drawn`):
``A_1``, ``alpha``, ``a`` and ``b`` vary from person to person.
Running (not in the recordings) uses ``A_pp = A_3 (v / 3 m/s)^alpha`` with our
``run_vertical_pp_3ms_m_s2``. AP amplitude is a ratio of the vertical one; ML sway and pelvis
angles have their own amplitudes. All amplitudes fade in with speed (zero while standing) and
vary from step to step (``amplitude_cv``).

Stairs
------
On stairs one step is one tread and the waveform shape is the walking one at the flight's
speed; only the amplitudes differ between going up and going down:

* vertical peak-to-peak 4.0 m/s^2 up, 6.5 m/s^2 down (``stairs_up_acc_pp_m_s2`` /
  ``stairs_down_acc_pp_m_s2``; before: 5.0 m/s^2 both ways). Descending lands each step on
  the lower tread with the body falling, so the heel-strike impact is larger than when
  climbing, where the body is pushed up with a slower loading. The thesis only uses the
  vertical dynamics to separate stairs from level walking (Inderst Sec. 4.1.1, index i_w of
  eq. 4.3-4.5, threshold d_2); the two values are a modelling choice around the former common
  5.0 m/s^2, not numbers from the papers;
* medio-lateral sway x1.5 going down (``stairs_down_sway_gain``): Inderst Sec. 4.1.1 separates
  up from down by the medio-lateral amplitude (threshold d_3, Fig. 4.3: the shift to the single
  supporting limb is larger going downstairs) and Sec. 4.1.2 keeps the medio-lateral
  peak-to-peak as the LDA feature theta_7 for that purpose. The factor is ours (the thesis
  gives no number).

The direction of a stairs sample comes from the motion's activity label
(:func:`_descending`); the amplitudes pass through the same 1 s moving average as all
waveform coefficients, so they change smoothly at the start and end of a flight.

How the waveform constants were measured
-----------------------------------------
Mobilise-D lab recordings (mobgap example data: HA/001, HA/002, MS/001; Test5 straight walks and
the walking bouts of Test11), lower-back IMU at 100 Hz, reference initial contacts from INDIP
(Stereophoto where INDIP is empty). The accelerometer and gyroscope were rotated into the body
frame with ``meta.mounting_q_bd`` and levelled by
:func:`~hrtls.sim.gait_waveforms.levelled_gait_signals` (gyro-propagated gravity direction blended
with the accelerometer, time constant 2 s; gravity removed; AP = body x projected on the
horizontal). Strides between consecutive same-foot initial contacts of one bout (0.8-1.8 s) were
resampled on a stride phase that is linear between the contacts (left contact 0, right contact
0.5); strides that start on the right foot were mirrored (ML, roll, yaw sign flipped) and the 139
strides were averaged in two speed groups by the reference bout speed
(:func:`~hrtls.sim.gait_waveforms.stride_waveforms`): 86 strides below 0.75 m/s (mean 0.54 m/s,
97.5 steps/min) and 53 strides above (mean 0.98 m/s, 102.8 steps/min). The tables below are the
Fourier coefficients of those mean waveforms
(:func:`~hrtls.sim.gait_waveforms.waveform_harmonics`): accelerations relative to the amplitude of
the vertical step-frequency harmonic (ML in m/s^2), angles from the rate harmonics divided by
``i n w_s``. Odd harmonics of vertical / AP and even ones of ML / roll / yaw are left-right
asymmetries that cancel in the mirrored mean (their residual is < 0.06); the vertical stride
harmonic is put back as ``asymmetry_ratio``. ``python benchmarks/sim_vs_real.py --table`` repeats
the measurement (prints these tables) and compares the model with the real waveforms.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from hrtls.data import Activity, StepEvents
from hrtls.sim.motion_truth import GAIT_RUN, GAIT_STAIRS, MotionTruth
from hrtls.sim.stop_model import stop_pulses

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
Harmonics = tuple[tuple[int, float, float, float, float], ...]
ArrayT = TypeVar("ArrayT", FloatArray, ComplexArray)

WAVEFORM_ANCHOR_SPEEDS_M_S: tuple[float, float] = (0.54, 0.98)
"""Walking speeds (m/s) of the two measured waveform sets (slow, fast); see the module notes."""

# Measured stride harmonics (module notes), one row per harmonic n of the stride angle:
# (n, amplitude at the slow anchor, phase deg, amplitude at the fast anchor, phase deg),
# meaning a(theta) = sum amplitude * cos(n theta + phase), theta = 0 at a left heel strike.
# vertical acceleration, relative to the step-frequency (n = 2) amplitude
_VERTICAL: Harmonics = ((2, 1.0, -41.0, 1.0, -25.0), (4, 0.47, -64.0, 0.22, -52.0),
                        (6, 0.27, -79.0, 0.16, -50.0), (8, 0.15, -116.0, 0.11, -128.0))
_VERTICAL_ASYMMETRY_PHASE_DEG = 140.0  # phase of the n = 1 residual (left-right asymmetry)
# AP acceleration, relative to the vertical n = 2 amplitude
_FORWARD: Harmonics = ((2, 0.81, 87.0, 0.66, 80.0), (4, 0.21, 59.0, 0.17, 58.0),
                       (6, 0.04, 64.0, 0.11, -25.0))
# ML acceleration, m/s^2 (positive to the left)
_LATERAL: Harmonics = ((1, 1.13, 83.0, 0.75, 92.0), (3, 0.29, 76.0, 0.37, 175.0),
                       (5, 0.21, 116.0, 0.24, 89.0))
# pelvis angles, rad (roll about forward, pitch about left (positive = nose down), yaw about up)
_ROLL: Harmonics = ((1, 0.031, 73.0, 0.010, 103.0), (3, 0.007, -165.0, 0.010, -162.0))
_PITCH: Harmonics = ((2, 0.014, 130.0, 0.017, 149.0),)
_YAW: Harmonics = ((1, 0.070, 114.0, 0.061, 121.0), (3, 0.003, 155.0, 0.006, -149.0))
# values of the GaitParams amplitudes that reproduce the tables at the fast anchor
_REF_H2, _REF_H3, _REF_FORWARD = 0.22, 0.16, 0.66
_REF_SWAY_M = 0.026  # ML n = 1 displacement at the fast anchor: 0.75 / (2 pi / 1.167 s)^2
_REF_ROLL_RAD, _REF_PITCH_RAD, _REF_YAW_RAD = 0.010, 0.017, 0.061


@dataclass(frozen=True, slots=True, kw_only=True)
class GaitParams:
    """One person's gait.

    Amplitudes are those of the fast measured waveform set (~1 m/s, see the module notes); the
    measured speed trends of shape and amplitude are applied around them.

    Attributes
    ----------
    step_a_m, step_b_s: walking step length ``l = step_a_m + step_b_s v`` (m, s).
    run_a_m, run_b_s: running step length ``l = run_a_m + run_b_s v``.
    vertical_pp_1ms_m_s2, vertical_pp_exponent: walking vertical acceleration peak-to-peak
        ``A_1 (v / 1 m/s)^alpha``, m/s^2 (module notes: fitted to real recordings).
    run_vertical_pp_3ms_m_s2: running vertical peak-to-peak at 3 m/s, m/s^2 (same exponent).
    stairs_up_acc_pp_m_s2, stairs_down_acc_pp_m_s2: vertical acceleration peak-to-peak
        going up / down stairs, m/s^2 (see "Stairs" in the module notes).
    stairs_down_sway_gain: medio-lateral sway going down stairs relative to level walking and
        going up.
    step_cv: coefficient of variation of step length from step to step.
    amplitude_cv: coefficient of variation of the oscillation amplitudes.
    harmonic2_ratio, harmonic3_ratio: 2nd / 3rd step harmonic of vertical acceleration relative
        to the step-frequency one (measured 0.22 / 0.16 at 0.98 m/s, 0.47 / 0.27 at 0.54 m/s).
    asymmetry_ratio: stride-frequency (left/right) vertical acceleration relative to the
        step-frequency one.
    forward_ratio: AP acceleration relative to the vertical, step-frequency harmonics (measured
        0.66 at 0.98 m/s, 0.81 at 0.54 m/s).
    lateral_sway_m: stride-frequency lateral displacement amplitude at ~1 m/s, m (measured
        0.026 m; 0.043 m at 0.54 m/s).
    pelvis_yaw_rad, pelvis_roll_rad, pelvis_pitch_rad: amplitudes of the pelvis yaw and roll
        (stride frequency) and pitch (step frequency), rad.
    lean_rad: forward lean while walking, rad.
    envelope_speed_m_s: speed at which the oscillation reaches full amplitude, m/s.
    """

    step_a_m: float = 0.32
    step_b_s: float = 0.26
    run_a_m: float = 0.55
    run_b_s: float = 0.20
    vertical_pp_1ms_m_s2: float = 4.5
    vertical_pp_exponent: float = 0.95
    run_vertical_pp_3ms_m_s2: float = 14.0
    stairs_up_acc_pp_m_s2: float = 4.0
    stairs_down_acc_pp_m_s2: float = 6.5
    stairs_down_sway_gain: float = 1.5
    step_cv: float = 0.03
    amplitude_cv: float = 0.15
    harmonic2_ratio: float = _REF_H2
    harmonic3_ratio: float = _REF_H3
    asymmetry_ratio: float = 0.04
    forward_ratio: float = _REF_FORWARD
    lateral_sway_m: float = _REF_SWAY_M
    pelvis_yaw_rad: float = _REF_YAW_RAD
    pelvis_roll_rad: float = _REF_ROLL_RAD
    pelvis_pitch_rad: float = _REF_PITCH_RAD
    lean_rad: float = 0.03
    envelope_speed_m_s: float = 0.5

    def drawn(self, rng: np.random.Generator) -> GaitParams:
        """A person around these parameters: the spread of the three real participants.

        ``A_1`` and the running amplitude x U(0.87, 1.13), ``alpha`` + U(-0.12, 0.12), step
        law ``a`` x U(0.85, 1.15) and ``b`` x U(0.85, 1.15).
        """
        u = rng.uniform(size=5)
        amp = 0.87 + 0.26 * u[0]
        return dataclasses.replace(
            self, vertical_pp_1ms_m_s2=self.vertical_pp_1ms_m_s2 * amp,
            run_vertical_pp_3ms_m_s2=self.run_vertical_pp_3ms_m_s2 * amp,
            vertical_pp_exponent=self.vertical_pp_exponent + 0.24 * (u[1] - 0.5),
            step_a_m=self.step_a_m * (0.85 + 0.3 * u[2]),
            step_b_s=self.step_b_s * (0.85 + 0.3 * u[3]))

    def vertical_pp(self, speed_m_s: FloatArray, gait: NDArray[np.int64]) -> FloatArray:
        """Vertical acceleration peak-to-peak (m/s^2) of walking or running steps."""
        v = np.maximum(np.asarray(speed_m_s, dtype=np.float64), 1e-3)
        walk = self.vertical_pp_1ms_m_s2 * v ** self.vertical_pp_exponent
        run = self.run_vertical_pp_3ms_m_s2 * (v / 3.0) ** self.vertical_pp_exponent
        return np.asarray(np.where(gait == GAIT_RUN, run, walk), dtype=np.float64)

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
    phase: gait phase (steps counted from the start; heel strikes at integers, left foot at
        even integers).
    offset_body: waist displacement from the nominal path, m, (N, 3) in the heading frame
        (forward, left, up).
    euler_osc: pelvis (roll, pitch, yaw) added to the nominal attitude, rad, (N, 3).
    steps: true step events (heel strike to heel strike).
    foot: foot of each step's starting heel strike (0 left, 1 right; alternating).
    """

    phase: FloatArray
    offset_body: FloatArray
    euler_osc: FloatArray
    steps: StepEvents
    foot: NDArray[np.int64]

    def initial_contacts(self) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.int64]]:
        """True heel strikes: times (s), True for the left foot, and the stop-free run of each.

        A step ends where the next one starts within a run; the last heel strike of a run is
        the end of its last step.
        """
        st = self.steps
        n = len(st)
        if n == 0:
            return np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0, dtype=np.int64)
        new_run = np.concatenate([[True], np.abs(st.t_start[1:] - st.t_end[:-1]) > 1e-9])
        run = np.cumsum(new_run) - 1
        last = np.concatenate([new_run[1:], [True]])  # last step of each run
        t = np.concatenate([st.t_start, st.t_end[last]])
        left = np.concatenate([self.foot == 0, self.foot[last] == 1])
        bout = np.concatenate([run, run[last]])
        order = np.argsort(t, kind="stable")
        return (np.asarray(t[order], dtype=np.float64), np.asarray(left[order], dtype=bool),
                np.asarray(bout[order], dtype=np.int64))


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


def _moving_average(x: ArrayT, n: int) -> ArrayT:
    """Centred moving average over ``n`` samples along axis 0 (ends held)."""
    if n <= 1 or len(x) == 0:
        return x
    pad = np.concatenate([np.repeat(x[:1], n // 2, axis=0), x,
                          np.repeat(x[-1:], n - n // 2 - 1, axis=0)])
    c = np.cumsum(np.concatenate([np.zeros_like(x[:1]), pad]), axis=0)
    out: ArrayT = np.asarray((c[n:] - c[:-n]) / n, dtype=x.dtype)
    return out


def _coefficients(table: Harmonics, weight: FloatArray, scale: tuple[float, ...]
                  ) -> tuple[NDArray[np.int64], ComplexArray]:
    """Harmonic numbers and complex coefficients (N, H) interpolated between the anchors.

    Amplitude and phase are interpolated separately (the phase along the shorter arc), so a
    harmonic whose phase moves with speed does not shrink in between.
    """
    ns = np.array([row[0] for row in table], dtype=np.int64)
    a0 = np.array([row[1] for row in table])
    p0 = np.deg2rad([row[2] for row in table])
    a1 = np.array([row[3] for row in table])
    dp = np.angle(np.exp(1j * (np.deg2rad([row[4] for row in table]) - p0)))
    # the weight takes few distinct values (mostly 0 or 1): evaluate each once
    levels, inverse = np.unique(weight, return_inverse=True)
    w = levels[:, None]
    amp = ((1.0 - w) * a0 + w * a1) * np.asarray(scale)
    coef = amp * np.exp(1j * (p0 + w * dp))
    return ns, np.asarray(coef[inverse.ravel()], dtype=np.complex128)


def _synthesize(ns: NDArray[np.int64], coef: ComplexArray, z: ComplexArray) -> FloatArray:
    """``sum_n Re(coef_n z^n)`` per sample, ``z = exp(i theta)``."""
    out = np.zeros(len(z))
    zn = np.ones_like(z)
    power = 0
    for j, n in enumerate(ns):  # harmonics in increasing order
        while power < n:
            zn = zn * z
            power += 1
        out += np.real(coef[:, j] * zn)
    return out


def _vertical_table(p: GaitParams) -> tuple[Harmonics, tuple[float, ...]]:
    """Vertical harmonics including the asymmetry term, and the per-harmonic scales."""
    asym = (1, p.asymmetry_ratio, _VERTICAL_ASYMMETRY_PHASE_DEG, p.asymmetry_ratio,
            _VERTICAL_ASYMMETRY_PHASE_DEG)
    return (asym, *_VERTICAL), (1.0, 1.0, p.harmonic2_ratio / _REF_H2,
                                p.harmonic3_ratio / _REF_H3, 1.0)


def _vertical_pp(p: GaitParams, weight: FloatArray) -> FloatArray:
    """Peak-to-peak of the vertical waveform (unit step-frequency amplitude) at ``weight``."""
    grid = np.linspace(0.0, 1.0, 21)
    table, scale = _vertical_table(p)
    ns, coef = _coefficients(table, grid, scale)
    th = np.linspace(0.0, 2.0 * np.pi, 1441)
    wave = np.real(coef[:, None, :] * np.exp(1j * ns[None, None, :] * th[None, :, None]))
    wave = wave.sum(axis=2)
    pp = wave.max(axis=1) - wave.min(axis=1)
    return np.asarray(np.interp(weight, grid, pp), dtype=np.float64)


def _descending(motion: MotionTruth) -> NDArray[np.bool_]:
    """True on stairs samples that go down.

    The direction is the sample's activity label; stairs samples labelled standing (speed
    below 0.05 m/s at the ends of a flight) take the label of the nearest labelled stairs
    sample, so a flight keeps one direction up to its ends.
    """
    stairs = motion.gait == GAIT_STAIRS
    act = motion.activity
    known = np.flatnonzero(stairs & ((act == int(Activity.UPSTAIRS))
                                     | (act == int(Activity.DOWNSTAIRS))))
    down = np.zeros(len(act), dtype=bool)
    if len(known) == 0:
        return down
    idx = np.flatnonzero(stairs)
    j = np.clip(np.searchsorted(known, idx), 1, max(len(known) - 1, 1))
    before = known[j - 1]
    after = known[np.minimum(j, len(known) - 1)]
    nearest = np.where(np.abs(idx - before) <= np.abs(after - idx), before, after)
    down[idx] = act[nearest] == int(Activity.DOWNSTAIRS)
    return down


def simulate_gait(motion: MotionTruth, params: GaitParams, rng: np.random.Generator
                  ) -> GaitResult:
    """Gait phase, body oscillation and true steps for ``motion``."""
    phase, steps = _phase_and_steps(motion, params, rng)
    offset_body, euler_osc = _oscillation(motion, params, rng, phase)
    if len(motion.t) > 2 and motion.dt > 0:
        # the stops' own draws come from a child generator: the gait stream is unchanged
        up = offset_body[:, 2]
        acc_up = np.gradient(np.gradient(up, motion.dt), motion.dt)
        offset_body[:, 2] = up + stop_pulses(motion.t, acc_up, steps, motion.moving,
                                             rng.spawn(1)[0])
    # feet alternate (the stride-frequency terms flip sign every step); even steps: left foot
    foot = np.mod(np.arange(len(steps)), 2).astype(np.int64)
    return GaitResult(phase=phase, offset_body=offset_body, euler_osc=euler_osc, steps=steps,
                      foot=foot)


def _phase_and_steps(motion: MotionTruth, p: GaitParams, rng: np.random.Generator
                     ) -> tuple[FloatArray, StepEvents]:
    """Gait phase (a whole number of steps per stop-free run) and the true step events."""
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
    return phase, steps


def _oscillation(motion: MotionTruth, p: GaitParams, rng: np.random.Generator,
                 phase: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Waist displacement (forward, left, up), m, and pelvis (roll, pitch, yaw), rad, (N, 3)."""
    v, dt, gait = motion.speed, motion.dt, motion.gait
    n = len(motion.t)
    # amplitudes, from the speed-dependent step length at a floored speed
    v_env = p.envelope_speed_m_s
    v_eff = np.maximum(v, v_env)
    l_eff = np.where(np.isfinite(motion.step_length_override), motion.step_length_override,
                     p.step_length(v_eff, gait))
    down = _descending(motion)
    acc_pp = np.where(gait == GAIT_STAIRS,
                      np.where(down, p.stairs_down_acc_pp_m_s2, p.stairs_up_acc_pp_m_s2),
                      p.vertical_pp(v_eff, gait))
    sway_gain = np.where(down, p.stairs_down_sway_gain, 1.0)
    w_stride = np.pi * v_eff / l_eff  # stride angular frequency, rad/s
    # where between the slow and the fast measured waveforms (running: the fast one)
    v_slow, v_fast = WAVEFORM_ANCHOR_SPEEDS_M_S
    weight = np.where(gait == GAIT_RUN, 1.0, np.clip((v_eff - v_slow) / (v_fast - v_slow),
                                                     0.0, 1.0))
    # vertical step-frequency acceleration amplitude such that the whole waveform's
    # peak-to-peak acceleration is acc_pp
    a_step = acc_pp / _vertical_pp(p, weight)
    win = max(1, round(1.0 / dt)) if dt > 0 else 1
    x = np.clip(v / v_env, 0.0, 1.0)
    envelope = x * x * x * (x * (6.0 * x - 15.0) + 10.0)
    envelope = envelope * (1.0 + p.amplitude_cv * _smooth_noise(rng, n, dt, 1.0))
    # stride angle theta = pi phase: 0 at left heel strikes, pi at right ones
    z = np.exp(1j * np.pi * phase)

    def displacement(table: Harmonics, scale: tuple[float, ...], gain: FloatArray
                     ) -> FloatArray:
        # acceleration harmonics -> displacement harmonics: divide by -(n w_s)^2
        ns, c = _coefficients(table, weight, scale)
        c = c * (gain[:, None] / -((ns[None, :] * w_stride[:, None]) ** 2))
        return envelope * _synthesize(ns, _moving_average(c, win), z)

    def angle(table: Harmonics, scale: float) -> FloatArray:
        ns, c = _coefficients(table, weight, (scale,) * len(table))
        return envelope * _synthesize(ns, _moving_average(c, win), z)

    v_table, v_scale = _vertical_table(p)
    up = displacement(v_table, v_scale, a_step)
    fwd = displacement(_FORWARD, (p.forward_ratio / _REF_FORWARD,) * len(_FORWARD), a_step)
    side = displacement(_LATERAL, (p.lateral_sway_m / _REF_SWAY_M,) * len(_LATERAL),
                        sway_gain)
    roll = angle(_ROLL, p.pelvis_roll_rad / _REF_ROLL_RAD)
    pitch = angle(_PITCH, p.pelvis_pitch_rad / _REF_PITCH_RAD) + envelope * p.lean_rad
    yaw = angle(_YAW, p.pelvis_yaw_rad / _REF_YAW_RAD)
    return np.column_stack([fwd, side, up]), np.column_stack([roll, pitch, yaw])


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
