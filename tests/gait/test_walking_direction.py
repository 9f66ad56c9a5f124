"""Walking direction relative to the device from the motion (mounting unknown)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.errors import InputError
from hrtls.frames import quat_conjugate, quat_from_rotvec, quat_multiply, wrap_angle
from hrtls.gait.analyzer import GaitAnalyzer
from hrtls.gait.synthetic import SimPerson, random_mounting, simulate
from hrtls.gait.walking_direction import (
    WalkingDirection,
    WalkingDirectionParams,
    in_reference_frame,
)

from ._chunks import run_with_restarts

N_STEP = 48            # samples per step (a multiple of 4: the lag is exactly a quarter step)
RATE_HZ = 96.0


def pendulum_walk(delta_rad: float, n_steps: int, *, sway_m_s2: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Samples and steps of an ideal walk: ``v = cos(w t)``, forward ``-sin(w t)`` along
    ``delta``, lateral sway at half the step rate; steps of ``N_STEP`` samples."""
    i = np.arange(n_steps * N_STEP + N_STEP)
    t = i / RATE_HZ
    ph = 2.0 * np.pi * i / N_STEP
    fwd = np.array([math.cos(delta_rad), math.sin(delta_rad)])
    left = np.array([-fwd[1], fwd[0]])
    h = -np.sin(ph)[:, None] * fwd + sway_m_s2 * np.sin(0.5 * ph)[:, None] * left
    v = np.cos(ph)
    # step k covers samples (k + 1) N_STEP + 1 .. (k + 2) N_STEP (the first step of data
    # before it feeds the lagged terms)
    last = (np.arange(n_steps - 1) + 2) * N_STEP - 1
    return t, h, v, t[last - N_STEP], t[last]


def test_hand_computed_pendulum_walk() -> None:
    """With ``m = N/4``: ``h_{i-m} (v_i - v_{i-2m}) = cos(phi_i) * 2 cos(phi_i) * fwd``, so each
    step adds ``2 * N/2 * fwd = N fwd`` to ``c``."""
    delta = math.radians(130.0)
    lam, c0 = 0.9, 5.0
    t, h, v, starts, ends = pendulum_walk(delta, 7)
    est = WalkingDirection(WalkingDirectionParams(forgetting_per_step=lam, prior_m2_s4=c0,
                                                  settle_steps=3))
    out = est.update(t, h, np.zeros(len(t)), v, starts, ends)
    assert np.all(np.isnan(out[:2]))
    # after 3 steps: c = lam^3 c0 e_x + N (lam^2 + lam + 1) fwd
    s3 = N_STEP * (lam**2 + lam + 1.0)
    c = np.array([lam**3 * c0 + s3 * math.cos(delta), s3 * math.sin(delta)])
    np.testing.assert_allclose(out[2:], math.atan2(c[1], c[0]), atol=1e-9)
    # the running estimate keeps folding steps (6 in all): c = lam^6 c0 e_x + N sum lam^j fwd
    s6 = N_STEP * sum(lam**j for j in range(6))
    np.testing.assert_allclose(est.state.c[:3], [lam**6 * c0 + s6 * math.cos(delta),
                                                 s6 * math.sin(delta), 6.0], atol=1e-9)
    # walking backwards (the forward acceleration against the jerk) turns it by pi
    back = WalkingDirection(WalkingDirectionParams(prior_m2_s4=0.0, settle_steps=1))
    d_back = back.update(t, -h, np.zeros(len(t)), v, starts, ends)
    np.testing.assert_allclose(wrap_angle(d_back - delta - math.pi), 0.0, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(alpha=st.floats(-math.pi, math.pi), delta=st.floats(-math.pi, math.pi),
       seed=st.integers(0, 10_000))
def test_rotating_the_reference_rotates_the_estimate(alpha: float, delta: float,
                                                     seed: int) -> None:
    """Turning the reference direction by alpha (no prior) turns the offset by -alpha."""
    t, h, v, starts, ends = pendulum_walk(delta, 6, sway_m_s2=0.5)
    rng = np.random.default_rng(seed)
    h = h + rng.normal(0.0, 0.3, h.shape)
    v = v + rng.normal(0.0, 0.3, v.shape)
    p = WalkingDirectionParams(prior_m2_s4=0.0, settle_steps=2)
    d0 = WalkingDirection(p).update(t, h, np.zeros(len(t)), v, starts, ends)
    # the reference turned by alpha (a device turned about the vertical): the offset from
    # it is alpha less, the walking direction psi_r + delta stays
    d1 = WalkingDirection(p).update(t, h, np.full(len(t), alpha), v, starts, ends)
    np.testing.assert_allclose(wrap_angle(d1[1:] - d0[1:] + alpha), 0.0, atol=1e-9)
    # the same through the frame change itself: h = R(-psi_r) a_h
    np.testing.assert_allclose(in_reference_frame(h, np.full(len(t), alpha)),
                               h @ np.array([[math.cos(alpha), -math.sin(alpha)],
                                             [math.sin(alpha), math.cos(alpha)]]), atol=1e-12)


@pytest.fixture(scope="module")
def walk():
    rng = np.random.default_rng(5)
    return simulate([(0, 3), (1, 30), (0, 3), (1, 12), (0, 2)], person=SimPerson.random(rng),
                    q_bd=random_mounting(rng), heading0_rad=0.7, turn_rate_rad_s=0.05, seed=5)


def test_device_turned_about_vertical_keeps_step_headings(walk) -> None:
    """Mounting unknown: the device turned about the vertical by any angle gives the same
    step headings (the old device-axis yaw turned with it)."""
    no_prior = WalkingDirectionParams(prior_m2_s4=0.0)
    base = GaitAnalyzer(rate_hz=100.0, heading="yaw", walking_direction=no_prior).process(
        walk.t, walk.acc_d, walk.q_nd)
    ok = np.isfinite(base.steps.heading_rad)
    assert ok.all() and ok.size > 60   # the first steps waited for the offset
    for angle in (0.4, 2.0, -2.9):
        # the new device frame: v_new = R_z(angle) v_old, so q_nd_new = q_nd * conj(q_z)
        q_z = quat_from_rotvec(np.array([0.0, 0.0, angle]))
        q_new = quat_multiply(walk.q_nd, quat_conjugate(q_z))
        acc_new = np.column_stack([
            np.cos(angle) * walk.acc_d[:, 0] - np.sin(angle) * walk.acc_d[:, 1],
            np.sin(angle) * walk.acc_d[:, 0] + np.cos(angle) * walk.acc_d[:, 1],
            walk.acc_d[:, 2]])
        turned = GaitAnalyzer(rate_hz=100.0, heading="yaw",
                              walking_direction=no_prior).process(walk.t, acc_new, q_new)
        np.testing.assert_allclose(turned.steps.t_end, base.steps.t_end, atol=1e-9)
        d = wrap_angle(turned.steps.heading_rad[ok] - base.steps.heading_rad[ok])
        # not exact: the reference axis may be another device axis, whose yaw under the
        # walk's tilt sway differs from the first one's by more than a constant
        np.testing.assert_allclose(d, 0.0, atol=1e-3)


def test_simulated_walk_direction_near_the_known_mounting(walk) -> None:
    """The simulator's walk (its own waveforms) gives the direction of its known mounting."""
    unknown = GaitAnalyzer(rate_hz=100.0, heading="yaw").process(walk.t, walk.acc_d, walk.q_nd)
    known = GaitAnalyzer(rate_hz=100.0, heading="yaw", mounting_q_bd=walk.q_bd).process(
        walk.t, walk.acc_d, walk.q_nd)
    d = np.degrees(wrap_angle(unknown.steps.heading_rad - known.steps.heading_rad))
    assert np.all(np.abs(d) < 10.0)


@pytest.mark.parametrize("bounds", [[0, 350, 777, 2100, 2101, 3500], [0, 150, 151, 4100],
                                    [0, 420, 470, 520]])
def test_chunks_with_restarts_equal_one_call(walk, bounds: list[int]) -> None:
    """Mounting unknown: chunks, each followed by a JSON save/restore, give the same steps
    (also while the first steps wait for the offset)."""
    whole = GaitAnalyzer(rate_hz=100.0, heading="yaw").process(walk.t, walk.acc_d, walk.q_nd)
    assert np.isfinite(whole.steps.heading_rad).all()
    cuts = [*bounds, len(walk.t)]
    parts = run_with_restarts(lambda: GaitAnalyzer(rate_hz=100.0, heading="yaw"), walk.t,
                              walk.acc_d, walk.q_nd, cuts)
    np.testing.assert_array_equal(parts.steps.t_end, whole.steps.t_end)
    np.testing.assert_array_equal(parts.steps.heading_rad, whole.steps.heading_rad)


def test_state_round_trip_is_exact(walk) -> None:
    ga = GaitAnalyzer(rate_hz=100.0, heading="yaw")
    ga.update(walk.t[:2000], walk.acc_d[:2000], walk.q_nd[:2000])
    st = json.loads(json.dumps(ga.state(), allow_nan=False))
    assert st["walking_direction"]["c"][2] > 4
    other = GaitAnalyzer(rate_hz=100.0, heading="yaw")
    other.restore(st)
    np.testing.assert_array_equal(other.direction.state.c, ga.direction.state.c)
    np.testing.assert_array_equal(other.direction.state.h, ga.direction.state.h)
    a = ga.update(walk.t[2000:], walk.acc_d[2000:], walk.q_nd[2000:])
    b = other.update(walk.t[2000:], walk.acc_d[2000:], walk.q_nd[2000:])
    np.testing.assert_array_equal(a.steps.heading_rad, b.steps.heading_rad)


def test_bad_parameters_and_inputs() -> None:
    with pytest.raises(InputError, match="forgetting_per_step"):
        WalkingDirectionParams(forgetting_per_step=0.0)
    with pytest.raises(InputError, match="max_step_s"):
        WalkingDirectionParams(max_step_s=0.0)
    with pytest.raises(InputError, match="settle_steps"):
        WalkingDirectionParams(settle_steps=0)
    est = WalkingDirection()
    with pytest.raises(InputError, match="step ends"):
        est.update(np.arange(3.0), np.zeros((3, 2)), np.zeros(3), np.zeros(3), np.zeros(2),
                   np.zeros(1))
    with pytest.raises(InputError, match="horizontal acceleration"):
        est.update(np.arange(3.0), np.zeros((3, 3)), np.zeros(3), np.zeros(3), np.zeros(0),
                   np.zeros(0))
