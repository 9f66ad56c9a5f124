"""Waveforms of the simulated waist: phase relations to heel strikes, helpers, real data."""

from __future__ import annotations

import warnings
from dataclasses import replace
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hrtls.errors import InputError
from hrtls.frames import GRAVITY_M_S2, quat_conjugate, quat_from_euler, quat_rotate
from hrtls.sim.gait_model import GaitParams, simulate_gait
from hrtls.sim.gait_waveforms import levelled_gait_signals, stride_waveforms, waveform_harmonics
from hrtls.sim.imu_model import body_kinematics, ideal_imu
from hrtls.sim.motion_truth import Waypoint, simulate_motion

POINTS = 100


def _straight(speed: float, params: GaitParams | None = None, seed: int = 0,
              length_m: float = 60.0) -> tuple:
    motion = simulate_motion([Waypoint(x=0.0, y=0.0),
                              Waypoint(x=length_m, y=0.0, speed_m_s=speed)], rate_hz=100.0)
    gait = simulate_gait(motion, params or GaitParams(), np.random.default_rng(seed))
    imu = ideal_imu(body_kinematics(motion, gait))
    return motion, gait, imu


def _cruise_waves(motion, gait, signals, speed: float) -> np.ndarray:
    ic, left, bout = gait.initial_contacts()
    sw = stride_waveforms(motion.t, signals, ic, left, bout=bout, points=POINTS,
                          min_stride_s=0.5, max_stride_s=2.5)
    v0 = np.interp(sw.start_s, motion.t, motion.speed)
    v1 = np.interp(sw.start_s + sw.duration_s, motion.t, motion.speed)
    ok = (v0 > 0.97 * speed) & (v1 > 0.97 * speed)
    assert ok.sum() >= 10
    return sw.waveforms[ok]


def _step_extremes(wave: np.ndarray) -> tuple[float, float]:
    """Phase (steps, in (-0.5, 0.5]) of the minimum and maximum of the step-folded waveform."""
    half = len(wave) // 2
    step = 0.5 * (wave[:half] + wave[half:2 * half])
    def rel(i: int) -> float:
        p = i / half
        return p - 1.0 if p > 0.5 else p
    return rel(int(np.argmin(step))), rel(int(np.argmax(step)))


# ------------------------------------------------------------------ simulated phase relations
@pytest.fixture(scope="module", params=[0.7, 1.0, 1.4])
def cruise(request) -> tuple:
    speed = request.param
    motion, gait, imu = _straight(speed)
    # true acceleration in the walking-heading frame (forward, left, up): no attitude filter
    c, s = np.cos(motion.heading), np.sin(motion.heading)
    a = imu.accel_n
    heading_frame = np.column_stack([c * a[:, 0] + s * a[:, 1], -s * a[:, 0] + c * a[:, 1],
                                     a[:, 2]])
    waves = _cruise_waves(motion, gait, heading_frame, speed)
    step_s = float(np.median(np.diff(gait.steps.t_start)))
    return speed, waves.mean(axis=0), step_s, motion, gait, imu


def test_ap_minimum_after_heel_strike_and_maximum_before_the_next(cruise):
    _, mean, step_s, *_ = cruise
    p_min, p_max = _step_extremes(mean[:, 0])
    # mobgap lower back: minimum ~0.1-0.15 s after, maximum ~0.1-0.15 s before the heel strike
    assert 0.05 <= p_min * step_s <= 0.22
    assert -0.22 <= p_max * step_s <= -0.05


def test_vertical_peak_just_after_heel_strike(cruise):
    _, mean, step_s, *_ = cruise
    _, p_max = _step_extremes(mean[:, 2])
    assert 0.0 <= p_max * step_s <= 0.1


def test_lateral_at_stride_frequency_towards_stance_foot(cruise):
    _, mean, *_ = cruise
    h = waveform_harmonics(mean)
    ml = np.abs(h[:, 1])
    assert ml[0] > 3 * ml[1]  # stride frequency dominates the step frequency
    assert ml[0] == ml.max()
    # mid left stance (stride phase 0.25): the body decelerates its leftward sway (to the right)
    assert np.real(h[0, 1] * np.exp(1j * np.pi / 2)) < 0
    # vertical and AP: step frequency, no stride-frequency term beyond the small asymmetry
    assert abs(h[1, 2]) > 10 * abs(h[0, 2])
    assert abs(h[1, 0]) > 10 * abs(h[0, 0])


def test_pelvis_rates_and_levelled_signals_agree_with_truth(cruise):
    speed, mean, _, motion, gait, imu = cruise
    sig = levelled_gait_signals(motion.t, imu.specific_force, imu.angular_rate)
    lev = _cruise_waves(motion, gait, sig, speed).mean(axis=0)
    # the tilt filter reproduces the true heading-frame accelerations closely
    for j in range(3):
        assert np.corrcoef(lev[:, j], mean[:, j])[0, 1] > 0.98
    h = waveform_harmonics(lev)
    assert np.argmax(np.abs(h[:, 5])) == 0  # yaw rate at stride frequency
    assert np.argmax(np.abs(h[:, 4])) == 1  # pitch rate at step frequency
    # left hip forward at the left heel strike: pelvis yawed clockwise there
    yaw = np.cumsum(lev[:, 5]) / POINTS
    assert yaw[0] - yaw.mean() < 0


def test_vertical_amplitude_follows_the_fitted_speed_law():
    from hrtls.sim.gait_model import fill_step_extremes

    p = GaitParams()
    for speed in (0.6, 1.2):
        motion, gait, imu = _straight(speed)
        steps = fill_step_extremes(gait.steps, motion.t, imu.accel_n[:, 2])
        v = np.interp(0.5 * (steps.t_start + steps.t_end), motion.t, motion.speed)
        ok = v > speed - 0.01
        pp = np.median(steps.acc_max[ok] - steps.acc_min[ok])
        assert pp == pytest.approx(p.vertical_pp_1ms_m_s2 * speed ** p.vertical_pp_exponent,
                                   rel=0.1)


def test_amplitude_parameters_scale_their_channel():
    speed = 1.2
    base = GaitParams(amplitude_cv=0.0, step_cv=0.0)
    m0, g0, i0 = _straight(speed, base, length_m=30.0)
    m1, g1, i1 = _straight(speed, replace(base, pelvis_yaw_rad=2 * base.pelvis_yaw_rad,
                                          forward_ratio=0.5 * base.forward_ratio),
                           length_m=30.0)
    s0 = levelled_gait_signals(m0.t, i0.specific_force, i0.angular_rate)
    s1 = levelled_gait_signals(m1.t, i1.specific_force, i1.angular_rate)
    h0 = waveform_harmonics(_cruise_waves(m0, g0, s0, speed).mean(axis=0))
    h1 = waveform_harmonics(_cruise_waves(m1, g1, s1, speed).mean(axis=0))
    assert abs(h1[0, 5]) / abs(h0[0, 5]) == pytest.approx(2.0, rel=0.05)
    assert abs(h1[1, 0]) / abs(h0[1, 0]) == pytest.approx(0.5, rel=0.08)
    assert abs(h1[1, 2]) / abs(h0[1, 2]) == pytest.approx(1.0, rel=0.05)


def _up_and_down(params: GaitParams, speed: float = 0.55) -> tuple:
    """A 16-tread flight up, a stop and turn at the top, the same flight down."""
    run, rise, n = 0.3, 0.17, 16
    wps = [Waypoint(x=0.0, y=0.0),
           Waypoint(x=n * run, y=0.0, z=n * rise, speed_m_s=speed, stop_s=2.0,
                    corner_radius_m=0.0),
           Waypoint(x=0.0, y=0.0, z=0.0, speed_m_s=speed)]
    motion = simulate_motion(wps, rate_hz=100.0)
    gait = simulate_gait(motion, params, np.random.default_rng(3))
    imu = ideal_imu(body_kinematics(motion, gait))
    return motion, gait, imu


def _flight_amplitudes(motion, gait, imu, activity: int, speed: float) -> tuple[float, float]:
    """Median per-step vertical peak-to-peak and per-stride lateral peak-to-peak (m/s^2)."""
    from hrtls.sim.gait_model import fill_step_extremes

    steps = fill_step_extremes(gait.steps, motion.t, imu.accel_n[:, 2])
    mid = 0.5 * (steps.t_start + steps.t_end)
    v = np.interp(mid, motion.t, motion.speed)
    ok = (steps.activity == activity) & (v > 0.97 * speed)
    assert ok.sum() >= 6
    vertical = float(np.median(steps.acc_max[ok] - steps.acc_min[ok]))
    # lateral acceleration of the waist in the heading frame: second difference of its
    # medio-lateral displacement (the nominal path is straight on a flight)
    dt = motion.dt
    lat = np.gradient(np.gradient(gait.offset_body[:, 1], dt), dt)
    idx = np.flatnonzero(ok)
    pp = [np.ptp(lat[(motion.t >= steps.t_start[a]) & (motion.t < steps.t_end[b])])
          for a, b in pairwise(idx) if b == a + 1]
    return vertical, float(np.median(pp))


def test_stairs_down_has_larger_impacts_and_sway_than_up():
    # Inderst Sec. 4.1.1: up / down differ in the medio-lateral amplitude (larger going down)
    p = GaitParams(amplitude_cv=0.0, step_cv=0.0)
    motion, gait, imu = _up_and_down(p)
    v_up, ml_up = _flight_amplitudes(motion, gait, imu, 3, 0.55)
    v_down, ml_down = _flight_amplitudes(motion, gait, imu, 4, 0.55)
    assert v_up == pytest.approx(p.stairs_up_acc_pp_m_s2, rel=0.08)
    assert v_down == pytest.approx(p.stairs_down_acc_pp_m_s2, rel=0.08)
    assert ml_down / ml_up == pytest.approx(p.stairs_down_sway_gain, rel=0.08)
    # symmetric parameters give symmetric flights (the direction is the only difference)
    sym = replace(p, stairs_down_acc_pp_m_s2=p.stairs_up_acc_pp_m_s2, stairs_down_sway_gain=1.0)
    motion, gait, imu = _up_and_down(sym)
    v_up, ml_up = _flight_amplitudes(motion, gait, imu, 3, 0.55)
    v_down, ml_down = _flight_amplitudes(motion, gait, imu, 4, 0.55)
    assert v_down / v_up == pytest.approx(1.0, rel=0.05)
    assert ml_down / ml_up == pytest.approx(1.0, rel=0.05)


def test_descending_fills_slow_stairs_samples_from_the_flight():
    from hrtls.sim.gait_model import _descending

    p = GaitParams()
    motion, _, _ = _up_and_down(p)
    down = _descending(motion)
    stairs = motion.gait == 2
    dz = np.gradient(motion.xyz[:, 2])
    # every stairs sample that moves vertically is classified by its direction, also the
    # slow ones at the ends of a flight whose activity label is standing
    moving_z = stairs & (np.abs(dz) > 1e-9)
    assert np.any(moving_z & (motion.activity == 0))
    np.testing.assert_array_equal(down[moving_z], dz[moving_z] < 0)
    assert not np.any(down[~stairs])


def test_initial_contacts_alternate_and_cover_every_step():
    wps = [Waypoint(x=0.0, y=0.0), Waypoint(x=10.0, y=0.0, stop_s=3.0, corner_radius_m=0.0),
           Waypoint(x=10.0, y=8.0)]
    motion = simulate_motion(wps, rate_hz=100.0)
    gait = simulate_gait(motion, GaitParams(), np.random.default_rng(1))
    t, left, bout = gait.initial_contacts()
    assert len(t) == len(gait.steps) + bout.max() + 1
    assert np.all(np.diff(t) > 0)
    for b in np.unique(bout):
        lb = left[bout == b]
        assert np.all(lb[1:] != lb[:-1])
    even = np.round(np.interp(t, motion.t, gait.phase)).astype(int) % 2 == 0
    np.testing.assert_array_equal(even, left)


# ------------------------------------------------------------------ helpers
def _levelled_slow(t, f, w, tau_s):
    """Pure-Python reference of the levelling kernel."""
    dt = float(np.median(np.diff(t)))
    alpha = min(1.0, dt / tau_s)
    head = f[: max(1, min(len(f), round(1.0 / dt)))]
    u = (head / np.linalg.norm(head, axis=1)[:, None]).mean(axis=0)
    u = u / np.linalg.norm(u)
    out = np.empty((len(t), 6))
    for k in range(len(t)):
        if k > 0:
            rot = Rotation.from_rotvec(-0.5 * (w[k - 1] + w[k]) * dt)
            u = rot.apply(u)
            u = (1 - alpha) * u + alpha * f[k] / np.linalg.norm(f[k])
            u = u / np.linalg.norm(u)
        x = np.array([1.0, 0.0, 0.0]) - u[0] * u
        x = x / np.linalg.norm(x)
        y = np.cross(u, x)
        out[k] = [f[k] @ x, f[k] @ y, f[k] @ u - GRAVITY_M_S2, w[k] @ x, w[k] @ y, w[k] @ u]
    return out


def test_levelling_kernel_matches_python_reference():
    rng = np.random.default_rng(3)
    t = np.arange(300) * 0.01
    w = 0.5 * rng.standard_normal((300, 3))
    f = np.array([0.5, -0.3, GRAVITY_M_S2]) + rng.standard_normal((300, 3))
    np.testing.assert_allclose(levelled_gait_signals(t, f, w, tau_s=0.7),
                               _levelled_slow(t, f, w, 0.7), atol=1e-10)


@settings(max_examples=30, deadline=None)
@given(roll=st.floats(-0.6, 0.6), pitch=st.floats(-0.6, 0.6), yaw=st.floats(-3.0, 3.0),
       rate=st.floats(-1.0, 1.0), freq=st.floats(0.3, 2.0))
def test_unit_at_rest_turning_reads_no_acceleration(roll, pitch, yaw, rate, freq):
    """Any attitude history at rest with a consistent gyroscope: levelled accelerations ~0."""
    from hrtls.sim.imu_model import body_rate

    t = np.arange(400) * 0.01
    ramp = np.clip(t - 1.0, 0.0, 1.0) ** 2 * (3.0 - 2.0 * np.clip(t - 1.0, 0.0, 1.0))
    # still tilt for the first second (the filter's start), then rocking and turning
    q = quat_from_euler(roll + 0.2 * ramp * np.sin(2 * np.pi * freq * t),
                        pitch + 0.2 * ramp * np.cos(2 * np.pi * freq * t),
                        yaw + rate * t)
    f_b = quat_rotate(quat_conjugate(q), np.array([0.0, 0.0, GRAVITY_M_S2]))
    w_b = body_rate(t, q)
    out = levelled_gait_signals(t, f_b, w_b)
    np.testing.assert_allclose(out[:, :3], 0.0, atol=0.03)
    # the yaw-rate channel is the rate about the vertical
    np.testing.assert_allclose(out[:, 5], quat_rotate(q, w_b)[:, 2], atol=0.02)


@settings(max_examples=40, deadline=None)
@given(coef=st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2)), min_size=6, max_size=6),
       mean=st.floats(-5, 5))
def test_waveform_harmonics_recover_coefficients(coef, mean):
    c = np.array([a + 1j * b for a, b in coef])
    ph = np.arange(POINTS) / POINTS
    x = mean + sum(np.real(c[n] * np.exp(2j * np.pi * (n + 1) * ph)) for n in range(6))
    np.testing.assert_allclose(waveform_harmonics(x), c, atol=1e-9)


def test_stride_waveforms_mirror_right_strides_and_skip_bad_ones():
    t = np.arange(0.0, 10.0, 0.01)
    # ML-like channel: +1 in left stance, -1 in right stance; AP-like: same for both
    ic = np.arange(0.5, 9.0, 0.55)
    left = np.arange(len(ic)) % 2 == 0
    stance_left = np.searchsorted(ic, t, side="right") % 2 == 1
    sig = np.column_stack([np.cos(2 * np.pi * t / 0.55), np.where(stance_left, 1.0, -1.0)])
    sw = stride_waveforms(t, sig, ic, left, points=20, mirror_columns=(1,))
    assert len(sw.start_s) == len(ic) - 2
    assert np.all(sw.started_left[::2]) and not np.any(sw.started_left[1::2])
    np.testing.assert_allclose(sw.waveforms[:, 2:9, 1], 1.0)
    np.testing.assert_allclose(sw.waveforms[:, 12:19, 1], -1.0)
    np.testing.assert_allclose(sw.waveforms[0, :, 0], sw.waveforms[1, :, 0], atol=1e-2)
    ic2 = ic.copy()
    ic2[3] = np.nan
    assert len(stride_waveforms(t, sig, ic2, left, points=20).start_s) == len(ic) - 5
    bout = (ic > 5.0).astype(int)
    assert len(stride_waveforms(t, sig, ic, left, bout=bout, points=20).start_s) == len(ic) - 4
    with pytest.raises(InputError):
        stride_waveforms(t, sig[:-1], ic, left)
    with pytest.raises(InputError):
        stride_waveforms(t, sig, ic, left[:-1])
    with pytest.raises(InputError):
        sw_empty = stride_waveforms(t, sig, ic[:2], left[:2])
        sw_empty.mean()


def test_levelled_signals_reject_bad_input():
    t = np.arange(10) * 0.01
    with pytest.raises(InputError):
        levelled_gait_signals(t, np.zeros((9, 3)), np.zeros((10, 3)))
    with pytest.raises(InputError):
        levelled_gait_signals(t[::-1], np.ones((10, 3)), np.zeros((10, 3)))
    bad = np.ones((10, 3))
    bad[3, 1] = np.nan
    with pytest.raises(InputError):
        levelled_gait_signals(t, bad, np.zeros((10, 3)))
    with pytest.raises(InputError):
        levelled_gait_signals(t, np.ones((10, 3)), np.zeros((10, 3)), tau_s=0.0)


# ------------------------------------------------------------------ Fourier heading on sim
def test_fourier_heading_on_simulated_basso_walk():
    """Basso's tip-to-tail heading needs the real AP timing; ~90 deg off on the old model."""
    from hrtls.frames import wrap_angle
    from hrtls.gait.session_analysis import analyze_session
    from hrtls.sim.scenarios import run_scenario

    res = run_scenario("basso_test1", 0)
    steps = analyze_session(res.session, heading="fourier").steps
    truth = res.session.truth
    tm = 0.5 * (steps.t_start + steps.t_end)
    true_h = np.interp(tm, truth.t, np.unwrap(truth.heading_rad))
    ok = np.isfinite(steps.heading_rad)
    assert ok.sum() > 0.8 * len(res.true_steps)
    err = np.degrees(np.abs(wrap_angle(steps.heading_rad[ok] - true_h[ok])))
    assert np.median(err) < 6.0


# ------------------------------------------------------------------ real lower-back data
@pytest.mark.realdata
def test_waveforms_correlate_with_mobgap_lower_back(shared_data: Path):
    from hrtls.datasets.mobgap import list_trials, load_trial

    root = shared_data / "mobgap_lab"
    if not root.is_dir():
        pytest.skip("mobgap_lab recordings absent")
    waves, durations, speeds = [], [], []
    for tid in list_trials(root):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            trial = load_trial(root, tid.participant, tid.test, tid.trial)
        ref = trial.reference.indip
        if ref is None or ref.is_empty:
            ref = trial.reference.stereophoto
        if ref is None or ref.is_empty:
            continue
        t, acc, gyr, _ = trial.session.imu.aligned()
        q_bd = np.asarray(trial.session.meta.mounting_q_bd)
        sig = levelled_gait_signals(t, quat_rotate(q_bd, acc), quat_rotate(q_bd, gyr))
        sw = stride_waveforms(t, sig, ref.initial_contacts_s, ref.initial_contact_left,
                              bout=ref.initial_contact_bout, points=POINTS)
        idx = np.searchsorted(ref.initial_contacts_s, sw.start_s)
        waves.append(sw.waveforms)
        durations.append(sw.duration_s)
        speeds.append(ref.bout_walking_speed_m_s[ref.initial_contact_bout[idx]])
    w, d, v = np.concatenate(waves), np.concatenate(durations), np.concatenate(speeds)
    assert len(w) > 100
    for sel in (v < 0.75, v >= 0.75):
        real = w[sel].mean(axis=0)
        speed, stride = float(v[sel].mean()), float(d[sel].mean())
        base = GaitParams()
        # same cadence; the vertical peak-to-peak of the mean real stride
        step_m = speed * stride / 2
        params = replace(base, step_a_m=step_m - base.step_b_s * speed,
                         vertical_pp_1ms_m_s2=np.ptp(real[:, 2])
                         / speed ** base.vertical_pp_exponent)
        motion, gait, imu = _straight(speed, params)
        sim_sig = levelled_gait_signals(motion.t, imu.specific_force, imu.angular_rate)
        sim = _cruise_waves(motion, gait, sim_sig, speed).mean(axis=0)
        corr = [np.corrcoef(real[:, j], sim[:, j])[0, 1] for j in range(6)]
        # AP, ML, vertical acceleration; roll, pitch, yaw rate. Measured: slow group 0.98,
        # 0.98, 0.99, 0.99, 0.93, 0.99; fast group 0.99, 0.93, 0.99, 0.97, 0.91, 0.97
        assert min(corr[0], corr[2], corr[5]) > 0.95, corr
        assert min(corr[1], corr[3]) > 0.9, corr
        assert corr[4] > 0.85, corr
        # AP extremes on the real data are where the model puts them (measurement sanity)
        step_s = stride / 2
        p_min, p_max = _step_extremes(real[:, 0])
        assert 0.05 <= p_min * step_s <= 0.22 and -0.22 <= p_max * step_s <= -0.05
