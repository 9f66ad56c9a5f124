from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from hrtls.datasets.broad import list_trials, load_trial
from hrtls.errors import FormatError
from hrtls.frames import quat_conjugate, quat_multiply, quat_rotate


def _write_trial(path: Path, n: int = 100, *, drop: str | None = None,
                 partial_nan: bool = False) -> Path:
    rng = np.random.default_rng(0)
    arrays = {
        "imu_acc": np.tile([0.0, 0.0, 9.81], (n, 1)) + 0.01 * rng.standard_normal((n, 3)),
        "imu_gyr": 0.01 * rng.standard_normal((n, 3)),
        "imu_mag": np.tile([0.0, 20.0, -40.0], (n, 1)),
        "opt_quat": np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        "opt_pos": np.zeros((n, 3)),
        "movement": np.arange(n) > 10,
    }
    arrays["opt_quat"][5] = np.nan
    if partial_nan:
        arrays["opt_quat"][6, 0] = np.nan
    with h5py.File(path, "w") as f:
        for key, value in arrays.items():
            if key != drop:
                f.create_dataset(key, data=value, compression="gzip")
        f.attrs["sampling_rate"] = 200.0
        f.attrs["info"] = "synthetic"
    return path


def test_synthetic_trial(tmp_path: Path) -> None:
    (tmp_path / "trials.json").write_text(json.dumps(
        {"groups": [], "trials": {"99_test": {"description": "d", "groups": ["all_trials"]}}}))
    trial = load_trial(_write_trial(tmp_path / "99_test.hdf5"))
    assert trial.name == "99_test" and trial.rate_hz == 200.0
    assert trial.description == "d" and trial.groups == ("all_trials",)
    assert trial.info == "synthetic"
    np.testing.assert_allclose(trial.session.imu.accel.t[:2], [0.0, 0.005])
    assert trial.session.imu.mag is not None
    assert not trial.reference_valid[5] and trial.reference_valid[4]
    assert trial.movement.dtype == bool and trial.movement.sum() == 89
    assert list_trials(tmp_path) == [tmp_path / "99_test.hdf5"]


def test_synthetic_defects(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="imu_mag"):
        load_trial(_write_trial(tmp_path / "a.hdf5", drop="imu_mag"))
    with pytest.raises(FormatError, match="row 6"):
        load_trial(_write_trial(tmp_path / "b.hdf5", partial_nan=True))
    (tmp_path / "c.hdf5").write_text("not hdf5")
    with pytest.raises(FormatError, match="HDF5"):
        load_trial(tmp_path / "c.hdf5")


@pytest.mark.realdata
def test_real_quaternion_convention(shared_data: Path) -> None:
    paths = list_trials(shared_data)
    assert len(paths) == 5
    for path in paths:
        trial = load_trial(path)
        _, acc, gyr, mag = trial.session.imu.aligned()
        assert trial.rate_hz == pytest.approx(285.714, abs=1e-3)
        lost = 1.0 - trial.reference_valid.mean()
        assert 0.02 < lost < 0.10
        assert trial.groups and "all_trials" in trial.groups
        if "undisturbed" not in trial.groups:
            continue
        # at rest the reference rotates the accelerometer onto +z of ENU: [0, 0, 9.82]
        rest = (np.linalg.norm(gyr, axis=1) < 0.01) & trial.reference_valid
        assert rest.sum() > 1000
        acc_n = quat_rotate(trial.reference_q[rest], acc[rest]).mean(axis=0)
        np.testing.assert_allclose(acc_n, [0.0, 0.0, 9.82], atol=0.06)
        mag_n = quat_rotate(trial.reference_q[rest], mag[rest]).mean(axis=0)
        assert abs(mag_n[0]) < 2.0 and mag_n[1] > 10.0 and mag_n[2] < -30.0


@pytest.mark.realdata
def test_real_gyro_is_body_rate_of_reference(shared_data: Path) -> None:
    trial = load_trial(shared_data / "broad" / "02_undisturbed_slow_rotation_B.hdf5")
    q = trial.reference_q
    gyr = trial.session.imu.gyro.values  # type: ignore[union-attr]
    ok = trial.reference_valid[:-1] & trial.reference_valid[1:] & trial.movement[:-1]
    # q_{k+1} = q_k * exp(w dt / 2): body-frame rate from successive quaternions
    dq = quat_multiply(quat_conjugate(q[:-1][ok]), q[1:][ok])
    dq *= np.sign(dq[:, :1])
    rate = 2.0 * dq[:, 1:] * trial.rate_hz
    mid = 0.5 * (gyr[:-1][ok] + gyr[1:][ok])
    fast = np.linalg.norm(mid, axis=1) > 0.5
    err = np.linalg.norm(rate[fast] - mid[fast], axis=1) / np.linalg.norm(mid[fast], axis=1)
    assert np.median(err) < 0.12  # 0.07 measured; nav-frame rate would give 0.36
