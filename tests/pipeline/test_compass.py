"""Compass correction of a wandering device yaw: recovery, chunk invariance, disturbance gate."""

from __future__ import annotations

import numpy as np

from hrtls.frames import heading_from_quat, quat_conjugate, quat_from_euler, quat_rotate, wrap_angle
from hrtls.pipeline.compass import CompassParams, CompassYaw

FIELD_N = np.array([0.0, 20.0, -35.0])     # uT, north = +y, dip ~60 deg
HARD_IRON = np.array([5.0, -8.0, 12.0])


def _recording(seed: int = 0, duration_s: float = 300.0, rate_hz: float = 50.0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    yaw = 2.0 * np.pi * t / 60.0 + 0.8 * np.sin(t / 7.0)
    roll = np.radians(8.0) * np.sin(2.0 * np.pi * 1.8 * t)
    pitch = np.radians(6.0) * np.sin(2.0 * np.pi * 0.9 * t + 0.3)
    q_true = quat_from_euler(roll, pitch, yaw)
    mag = quat_rotate(quat_conjugate(q_true), FIELD_N) + HARD_IRON
    mag += rng.normal(0.0, 0.3, mag.shape)
    drift = np.radians(5.0) * np.sin(2.0 * np.pi * t / 200.0)
    q_ahrs = quat_from_euler(roll, pitch, yaw + drift)
    return t, yaw, drift, q_ahrs, mag


def test_wander_removed() -> None:
    t, yaw, drift, q, mag = _recording()
    comp = CompassYaw(0.0)
    qc = comp.correct(t, q, mag)
    err = np.asarray(wrap_angle(heading_from_quat(qc) - yaw))
    const = float(np.mean(drift[t < comp.params.reference_s]))
    late = t > 120.0
    assert np.max(np.abs(err[late] - const)) < np.radians(1.5)
    np.testing.assert_allclose(comp.c[:2], HARD_IRON[:2], atol=0.5)
    # without the correction the wander is up to 5 deg
    raw = np.asarray(wrap_angle(heading_from_quat(q) - yaw))
    assert np.max(np.abs(raw[late] - const)) > np.radians(4.0)
    # before the warm-up nothing is changed
    early = t < comp.params.warmup_s
    np.testing.assert_allclose(qc[early], q[early], atol=1e-12)


def test_corrected_field_starts_without_warm_up() -> None:
    # the hard iron already removed (mag_hard_iron = "fit"): corrections start after the
    # reference window instead of after the 60 s warm-up, and are right from there on
    t, yaw, drift, q, mag = _recording(3)
    comp = CompassYaw(0.0, CompassParams(field_corrected=True))
    qc = comp.correct(t, q, mag - HARD_IRON)
    err = np.asarray(wrap_angle(heading_from_quat(qc) - yaw))
    const = float(np.mean(drift[t < comp.params.reference_s]))
    settled = (t > comp.params.reference_s + 5.0 * comp.params.tau_s) & (t < 60.0)
    assert np.max(np.abs(err[settled] - const)) < np.radians(1.5)
    raw = np.asarray(wrap_angle(heading_from_quat(q) - yaw))
    assert np.max(np.abs(raw[settled] - const)) > np.radians(2.0)  # there was wander to remove
    late = t > 120.0
    assert np.max(np.abs(err[late] - const)) < np.radians(1.5)


def test_chunk_invariant() -> None:
    t, _, _, q, mag = _recording(1, duration_s=150.0)
    whole = CompassYaw(0.0).correct(t, q, mag)
    comp = CompassYaw(0.0)
    parts = [comp.correct(t[i:i + 487], q[i:i + 487], mag[i:i + 487])
             for i in range(0, len(t), 487)]
    np.testing.assert_allclose(np.concatenate(parts), whole, atol=1e-9)
    assert comp.correct(t[:0], q[:0], mag[:0]).shape == (0, 4)


def test_disturbed_field_is_ignored() -> None:
    t, yaw, drift, q, mag = _recording(2)
    bad = (t > 150.0) & (t < 200.0)
    mag[bad] += np.array([25.0, 0.0, 25.0])      # a strong local anomaly
    comp = CompassYaw(0.0)
    qc = comp.correct(t, q, mag)
    err = np.asarray(wrap_angle(heading_from_quat(qc) - yaw))
    const = float(np.mean(drift[t < comp.params.reference_s]))
    # held through the anomaly (the wander meanwhile stays), recovered after it
    held = drift[bad] - drift[np.flatnonzero(bad)[0]]
    assert np.max(np.abs(err[bad] - const - held)) < np.radians(1.5)
    after = t > 245.0
    assert np.max(np.abs(err[after] - const)) < np.radians(1.5)
    np.testing.assert_allclose(comp.c[:2], HARD_IRON[:2], atol=0.5)


def test_tracker_uses_compass_on_device_orientation_only() -> None:
    from hrtls.evaluate.metrics import checkpoint_errors
    from hrtls.pipeline import Tracker, preset
    from hrtls.sim.scenarios import run_scenario

    sim = run_scenario("basso_test1", 0)
    cfg = preset("default")
    assert cfg.attitude.compass_yaw
    causal = Tracker(cfg).run(sim.session)
    assert causal.attitude is not None and "compass" in causal.report
    # with the hard iron of the whole recording (offline two pass), the compass corrects
    # from the end of its reference window on; causally only once the running fit is accepted
    cfg = cfg.model_copy(update={"offline": cfg.offline.model_copy(update={"two_pass": True})})
    res = Tracker(cfg).run(sim.session)
    assert res.attitude is not None and "compass" in res.report
    assert res.report["compass"]["field_ut"] is not None
    off = cfg.model_copy(update={"attitude": cfg.attitude.model_copy(
        update={"compass_yaw": False})})
    ref = Tracker(off).run(sim.session)
    cps = sim.session.checkpoints
    assert cps is not None
    e_on = float(np.mean(checkpoint_errors(res.trajectory, cps)[1]))
    e_off = float(np.mean(checkpoint_errors(ref.trajectory, cps)[1]))
    assert e_on < e_off
    # our own filters fuse the magnetometer themselves: no compass stage
    ekf = cfg.model_copy(update={"attitude": cfg.attitude.model_copy(
        update={"method": "quat-ekf"})})
    s = sim.session.with_parts(orientation=None)
    assert "compass" not in Tracker(ekf).run(s).report
