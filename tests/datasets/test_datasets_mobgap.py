from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import scipy.io

from hrtls.datasets.mobgap import MOBGAP_Q_BD, MobgapTrialId, list_trials, load_trial
from hrtls.errors import FormatError, InputError
from hrtls.frames import GRAVITY_M_S2, quat_rotate, quat_to_matrix

# ------------------------------------------------------------------------------------------
# synthetic files (no real data needed)
# ------------------------------------------------------------------------------------------
_BOUT_FIELDS = ["Start", "End", "Cadence", "WalkingSpeed", "Length", "NumberStrides",
                "InitialContact_Event", "InitialContact_LeftRight", "Stride_InitialContacts",
                "Stride_Length", "Stride_Speed", "Step_Length", "Turn_Start", "Turn_End",
                "Turn_Angle"]


def _bouts(rows: list[dict[str, Any]]) -> np.ndarray:
    arr = np.zeros((len(rows),), dtype=[(f, "O") for f in _BOUT_FIELDS])
    for i, row in enumerate(rows):
        arr[i] = tuple(row[f] for f in _BOUT_FIELDS)
    return arr


def _bout(start: float, ics_s: list[float], *, samples: bool, turn: bool = False
          ) -> dict[str, Any]:
    ic = np.array(ics_s)
    sic = np.column_stack([ic[:-2], ic[2:]])
    if samples:
        sic = np.round(sic * 100).astype(np.uint16)
    return {
        "Start": start, "End": float(ic[-1]), "Cadence": 100.0, "WalkingSpeed": 1.1,
        "Length": 4.0, "NumberStrides": len(sic),
        "InitialContact_Event": ic,
        "InitialContact_LeftRight": np.array(["Left", "Right"] * (len(ic) // 2)
                                             + ["Left"] * (len(ic) % 2), dtype=object),
        "Stride_InitialContacts": sic,
        "Stride_Length": np.full(len(sic), 1.2), "Stride_Speed": np.full(len(sic), 1.0),
        "Step_Length": np.full(len(ic) - 1, 0.6) if not samples else np.zeros(0, np.uint8),
        "Turn_Start": 2.0 if turn else np.zeros(0, np.uint8),
        "Turn_End": 3.0 if turn else np.zeros(0, np.uint8),
        "Turn_Angle": -90.0 if turn else np.zeros(0, np.uint8),
    }


def _write_mobgap(folder: Path, *, n: int = 400, indip_bouts: int = 2) -> Path:
    part = folder / "mobgap_lab" / "HA" / "009"
    part.mkdir(parents=True)
    t = np.arange(n) / 100.0
    acc_g = np.tile([1.0, 0.0, 0.0], (n, 1))  # x up at rest
    gyr = np.zeros((n, 3))
    gyr[:, 0] = 10.0  # deg/s about the vertical axis
    bouts_indip = [_bout(0.5, [0.5, 1.0, 1.5, 2.0, 2.5], samples=True, turn=True),
                   _bout(3.0, [3.0, 3.5, 3.9], samples=True)][:indip_bouts]
    stereo = _bout(0.6, [0.6, 1.1, 1.6, 2.1], samples=False)
    trial = {
        "StartDateTime": "2020-01-01T00:00:00.000Z", "TimeZone": "UTC",
        "SU": {"LowerBack": {"Acc": acc_g, "Gyr": gyr, "Mag": np.ones((n, 3)),
                             "Bar": np.full(n, 1000.0), "Timestamp": 1.6e9 + t,
                             "Fs": {"Acc": 100, "Gyr": 100, "Mag": 100, "Bar": 100}}},
        "Standards": {
            "INDIP": {"MicroWB": _bouts(bouts_indip) if bouts_indip else np.zeros(0, np.uint8),
                      "ContinuousWalkingPeriod": np.zeros(0, np.uint8), "Fs": 100},
            "Stereophoto": {"MicroWB": stereo, "ContinuousWalkingPeriod": stereo, "Fs": 100},
        },
    }
    scipy.io.savemat(part / "data.mat", {"data": {"TimeMeasure1": {"Test5": {"Trial1": trial}}}})
    scipy.io.savemat(part / "infoForAlgo.mat", {"infoForAlgo": {"TimeMeasure1": {
        "Height": 180, "Weight": 70, "SensorHeight": 100.0, "Handedness": "R"}}})
    return folder


def test_mounting_rotation_maps_sensor_axes_to_body_axes() -> None:
    r = quat_to_matrix(np.array(MOBGAP_Q_BD))
    np.testing.assert_allclose(r, [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-12)
    # sensor up (x) -> body up (z); sensor forward (z) -> body forward (x); right -> -left
    np.testing.assert_allclose(quat_rotate(np.array(MOBGAP_Q_BD), [1, 0, 0]), [0, 0, 1],
                               atol=1e-12)
    np.testing.assert_allclose(quat_rotate(np.array(MOBGAP_Q_BD), [0, 0, 1]), [1, 0, 0],
                               atol=1e-12)
    np.testing.assert_allclose(quat_rotate(np.array(MOBGAP_Q_BD), [0, 1, 0]), [0, -1, 0],
                               atol=1e-12)


def test_synthetic_trial_units_time_and_references(tmp_path: Path) -> None:
    root = _write_mobgap(tmp_path)
    assert list_trials(root) == [MobgapTrialId("HA/009", "Test5", "Trial1")]
    trial = load_trial(root, "HA/009", "Test5", "Trial1")
    s = trial.session
    np.testing.assert_allclose(s.imu.accel.values[0], [GRAVITY_M_S2, 0, 0])
    np.testing.assert_allclose(s.imu.gyro.values[0, 0], math.radians(10.0))
    assert s.imu.mag is None
    np.testing.assert_allclose(s.pressure.values[:, 0], 100000.0)
    np.testing.assert_allclose(s.imu.accel.t[:3], [0.0, 0.01, 0.02])
    assert s.meta.time_origin_unix_s == pytest.approx(1.6e9)
    assert s.meta.user.height_m == pytest.approx(1.80)
    assert s.meta.placement == "lower back"
    assert any("Mag" in note for note in s.meta.notes)
    indip = trial.reference.indip
    assert indip is not None and indip.n_bouts == 2
    # INDIP stride contacts were written in samples and come back in seconds
    np.testing.assert_allclose(indip.stride_start_s, [0.5, 1.0, 1.5, 3.0])
    np.testing.assert_allclose(indip.stride_end_s, [1.5, 2.0, 2.5, 3.9])
    np.testing.assert_array_equal(indip.stride_bout, [0, 0, 0, 1])
    np.testing.assert_array_equal(indip.initial_contact_left[:2], [True, False])
    assert indip.step_length_m.size == 0
    np.testing.assert_allclose(indip.turn_angle_deg, [-90.0])
    np.testing.assert_allclose(indip.bouts_s, [[0.5, 2.5], [3.0, 3.9]])
    assert indip.strides.shape == (4, 4) and indip.turns.shape == (1, 3)
    np.testing.assert_allclose(indip.strides[0], [0.5, 1.5, 1.2, 1.0])
    stereo = trial.reference.stereophoto
    assert stereo is not None and stereo.n_bouts == 1  # a single struct, not an array
    np.testing.assert_allclose(stereo.stride_start_s, [0.6, 1.1])
    assert len(stereo.step_length_m) == 3
    cwp = load_trial(root, "HA/009", "Test5", "Trial1", level="ContinuousWalkingPeriod")
    assert cwp.reference.indip is not None and cwp.reference.indip.is_empty


def test_synthetic_session_survives_the_session_format(tmp_path: Path) -> None:
    from hrtls.io.session import read_session, write_session

    session = load_trial(_write_mobgap(tmp_path), "HA/009", "Test5", "Trial1").session
    back = read_session(write_session(session, tmp_path / "session"))
    assert back.meta.mounting_q_bd == pytest.approx(MOBGAP_Q_BD)
    assert back.meta.user.height_m == pytest.approx(1.80)
    np.testing.assert_allclose(back.imu.accel.values, session.imu.accel.values)  # type: ignore[union-attr]
    np.testing.assert_allclose(back.pressure.values, session.pressure.values)  # type: ignore[union-attr]


def test_synthetic_single_bout_and_empty(tmp_path: Path) -> None:
    root = _write_mobgap(tmp_path, indip_bouts=0)
    trial = load_trial(root, "HA/009", "Test5", "Trial1")
    assert trial.reference.indip is not None and trial.reference.indip.is_empty
    assert trial.reference.get("indip") is trial.reference.indip
    with pytest.raises(InputError, match="reference system"):
        trial.reference.get("vicon")


def test_unknown_names_raise_with_choices(tmp_path: Path) -> None:
    root = _write_mobgap(tmp_path)
    with pytest.raises(InputError, match="HA/009"):
        load_trial(root, "HA/001", "Test5", "Trial1")
    with pytest.raises(InputError, match="Test5"):
        load_trial(root, "HA/009", "Test11", "Trial1")
    with pytest.raises(InputError, match="Trial1"):
        load_trial(root, "HA/009", "Test5", "Trial7")


def test_not_a_mobgap_file_is_a_format_error(tmp_path: Path) -> None:
    part = tmp_path / "X" / "001"
    part.mkdir(parents=True)
    scipy.io.savemat(part / "data.mat", {"other": np.ones(3)})
    with pytest.raises(FormatError, match="mobgap"):
        load_trial(tmp_path, "X/001", "Test5", "Trial1")


# ------------------------------------------------------------------------------------------
# real recordings
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def mobgap_root(shared_data: Path) -> Path:
    return shared_data / "mobgap_lab"


@pytest.mark.realdata
def test_real_listing(mobgap_root: Path) -> None:
    ids = list_trials(mobgap_root)
    assert len(ids) == 9
    assert MobgapTrialId("HA/001", "Test5", "Trial1") in ids
    assert {i.participant for i in ids} == {"HA/001", "HA/002", "MS/001"}


@pytest.mark.realdata
def test_real_units_axes_and_meta(mobgap_root: Path) -> None:
    trial = load_trial(mobgap_root, "HA/001", "Test5", "Trial1")
    s = trial.session
    t, acc, gyr, mag = s.imu.aligned()
    assert mag is None and trial.mag_unknown_unit.shape == acc.shape
    # |a| at rest is 0.98 g (data README) -> about 9.6 m/s^2 after conversion
    rest = acc[:50]
    assert np.linalg.norm(rest.mean(axis=0)) == pytest.approx(9.81, abs=0.3)
    # in the body frame gravity is on +z
    body = quat_rotate(np.array(s.meta.mounting_q_bd), rest.mean(axis=0))
    assert body[2] > 9.0
    assert np.percentile(np.linalg.norm(gyr, axis=1), 99) < 10.0  # rad/s, not deg/s
    assert 9.0e4 < np.median(s.pressure.values) < 1.1e5  # Pa
    assert np.median(np.diff(t)) == pytest.approx(0.01)
    assert s.meta.time_origin_unix_s == pytest.approx(1607605064.733, abs=1e-3)
    assert s.meta.user.height_m == pytest.approx(1.59)
    assert trial.sampling_rate_hz == 100.0


@pytest.mark.realdata
def test_real_reference_units(mobgap_root: Path) -> None:
    trial = load_trial(mobgap_root, "HA/001", "Test5", "Trial1")
    for ref in (trial.reference.indip, trial.reference.stereophoto):
        assert ref is not None and ref.n_bouts == 1
        # strides begin and end at initial contacts (INDIP samples converted to s)
        for edge in (ref.stride_start_s, ref.stride_end_s):
            gap = np.min(np.abs(edge[:, None] - ref.initial_contacts_s[None, :]), axis=1)
            assert np.all(gap < 0.011)
        assert np.all((ref.stride_start_s >= ref.bout_start_s[0] - 1e-9)
                      & (ref.stride_end_s <= ref.bout_end_s[0] + 1e-9))
        assert 0.8 < np.nanmedian(ref.stride_length_m) < 1.6
        assert 80 < ref.bout_cadence_spm[0] < 130
    assert trial.reference.indip is not None
    assert trial.reference.indip.stride_start_s[0] == pytest.approx(5.05)
    assert len(trial.reference.stereophoto.step_length_m) == 9  # type: ignore[union-attr]


@pytest.mark.realdata
def test_real_empty_references(mobgap_root: Path) -> None:
    trial = load_trial(mobgap_root, "HA/002", "Test5", "Trial1")
    assert trial.reference.indip is not None and trial.reference.indip.is_empty
    assert trial.reference.stereophoto is not None and trial.reference.stereophoto.is_empty
    other = load_trial(mobgap_root, "HA/002", "Test5", "Trial2")
    assert other.reference.indip is not None and other.reference.indip.is_empty
    assert other.reference.stereophoto is not None and other.reference.stereophoto.n_bouts == 1


@pytest.mark.realdata
def test_real_all_trials_load_and_turns_match_gyro(mobgap_root: Path) -> None:
    for tid in list_trials(mobgap_root):
        trial = load_trial(mobgap_root, tid.participant, tid.test, tid.trial)
        for ref in (trial.reference.indip, trial.reference.stereophoto):
            if ref is None:
                continue
            assert len(ref.initial_contacts_s) == len(ref.initial_contact_left)
            assert len(ref.stride_start_s) == len(ref.stride_length_m)
            assert len(ref.turn_start_s) == len(ref.turn_angle_deg)
            assert np.all(ref.turn_end_s >= ref.turn_start_s)
    # Stereophoto turn angles agree in size with the integrated vertical (sensor x) gyro
    trial = load_trial(mobgap_root, "MS/001", "Test11", "Trial1")
    t, _, gyr, _ = trial.session.imu.aligned()
    ref = trial.reference.stereophoto
    assert ref is not None and len(ref.turn_angle_deg) > 5
    integrated = np.array([np.degrees(np.sum(gyr[(t >= s) & (t < e), 0]) * 0.01)
                           for s, e in zip(ref.turn_start_s, ref.turn_end_s, strict=True)])
    assert np.median(np.abs(np.abs(integrated) - np.abs(ref.turn_angle_deg))) < 20.0
