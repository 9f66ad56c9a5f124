import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import (
    Activity,
    ImuStream,
    Landmark,
    PositionFixes,
    RangeMeasurements,
    RssReadings,
    SensorSeries,
    Session,
    StepEvents,
    Trajectory,
    activity_codes,
)
from hrtls.errors import InputError, RepairWarning, UnitError
from hrtls.units import DEG, G_TO_M_S2, guess_time_scale

T = np.arange(200) * 0.01
REST = np.tile([0.0, 0.0, 9.81], (200, 1))


def test_series_names_stream_and_index_for_backward_time():
    t = T.copy()
    t[57] = t[55]
    with pytest.raises(InputError, match=r"gyro.*index 57.*strictly increasing"):
        SensorSeries(t, REST, "gyro")


def test_series_duplicate_time_is_named():
    t = T.copy()
    t[10] = t[9]
    with pytest.raises(InputError, match="duplicated at index 10"):
        SensorSeries(t, REST, "acc")


def test_series_nan_is_error_and_repair_drops_with_warning():
    v = REST.copy()
    v[3, 1] = np.nan
    with pytest.raises(InputError, match=r"non-finite.*index 3"):
        SensorSeries(T, v, "acc")
    with pytest.warns(RepairWarning, match="dropped 1 row"):
        s = SensorSeries.from_raw(T, v, name="acc", repair=True)
    assert len(s) == 199


def test_repair_sorts_and_merges_duplicates_by_averaging():
    t = np.array([0.0, 0.02, 0.01, 0.02, 0.03])
    v = np.array([[0.0], [2.0], [1.0], [4.0], [3.0]])
    with pytest.warns(RepairWarning) as record:
        s = SensorSeries.from_raw(t, v, name="x", repair=True)
    message = str(record[0].message)
    assert "sorted" in message and "merged 1" in message
    assert np.array_equal(s.t, [0.0, 0.01, 0.02, 0.03])
    assert np.array_equal(s.values[:, 0], [0.0, 1.0, 3.0, 3.0])


@settings(max_examples=100)
@given(st.lists(st.floats(0, 100, allow_nan=False), min_size=2, max_size=60))
def test_repair_always_yields_strictly_increasing(times):
    t = np.array(times)
    v = np.arange(len(t), dtype=float)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RepairWarning)
        s = SensorSeries.from_raw(t, v, name="x", repair=True)
    assert np.all(np.diff(s.t) > 0)
    assert len(s) == len(np.unique(t))
    assert np.isclose(s.values.sum() * 0 + v.sum(), v.sum())  # values finite and kept


def test_unit_checks_catch_g_and_deg_s_with_fix():
    with pytest.raises(UnitError, match=r"g, not m/s\^2; multiply by 9\.80665"):
        ImuStream(SensorSeries(T, REST / G_TO_M_S2, "acc"))
    spin = np.column_stack([np.zeros(200), np.zeros(200), np.full(200, 90.0)])
    with pytest.raises(UnitError, match="deg/s"):
        ImuStream(SensorSeries(T, REST, "acc"), SensorSeries(T, spin, "gyro"))
    ImuStream(SensorSeries(T, REST, "acc"), SensorSeries(T, spin * DEG, "gyro"))
    gauss = np.tile([0.2, 0.0, -0.4], (200, 1))
    with pytest.raises(UnitError, match="gauss"):
        ImuStream(SensorSeries(T, REST, "acc"), mag=SensorSeries(T, gauss, "mag"))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=25, unique=True),
       st.lists(st.floats(-2.0, 22.0), min_size=1, max_size=40), st.booleans(),
       st.integers(0, 2**32 - 1))
def test_series_interpolate_is_np_interp_per_column(grid, queries, ordered, seed):
    """The compiled kernel gives np.interp's values bit for bit (ends, exact hits, any order)."""
    t = np.sort(np.asarray(grid, dtype=float)) * 0.5
    v = np.random.default_rng(seed).normal(size=(len(t), 3))
    v[::3, 1] = 7.0   # flat stretches
    q = np.asarray([*queries, float(t[0]), float(t[-1])])
    q = np.sort(q) if ordered else q
    got = SensorSeries(t, v, "magnetometer").interpolate(q)
    want = np.column_stack([np.interp(q, t, c) for c in v.T])
    np.testing.assert_array_equal(got, want)


def test_imu_aligned_interpolates_other_rates():
    tg = np.arange(400) * 0.005
    gyro = SensorSeries(tg, np.column_stack([tg, tg, tg]), "gyro")
    imu = ImuStream(SensorSeries(T, REST, "acc"), gyro)
    _, _, gyr, mag = imu.aligned()
    assert mag is None and np.allclose(gyr[:, 0], T)


def test_observations_allow_equal_times_but_not_backwards():
    RssReadings([0.0, 0.0, 1.0], ["a", "b", "a"], [-60, -70, -65])
    with pytest.raises(InputError, match="backwards"):
        RssReadings([0.0, 1.0, 0.5], ["a", "b", "a"], [-60, -70, -65])
    with pytest.raises(InputError, match="dBm"):
        RssReadings([0.0], ["a"], [60.0])
    with pytest.raises(InputError, match="empty identifier"):
        RssReadings([0.0], [""], [-60.0])
    with pytest.raises(InputError, match="positive"):
        PositionFixes([0.0], [[0, 0, 0]], [0.0])
    r = RangeMeasurements([0.0], ["n"], [3.0], [np.nan])
    assert np.isnan(r.sigma_m[0])


def test_landmark_needs_location_and_wraps_bearings():
    with pytest.raises(ValueError, match="position"):
        Landmark(id="t1")
    lm = Landmark(id="t1", kind="rfid", position=(1, 2, 0), bearings_rad=(4.0,))
    assert -np.pi < lm.bearings_rad[0] <= np.pi


def test_session_needs_a_source_of_motion():
    with pytest.raises(InputError, match="no source of motion"):
        Session()


def test_trajectory_and_steps_validate():
    tr = Trajectory.build(t=[0, 1], xyz=[[0, 0, 0], [1, 0, 0]])
    assert tr.path_length_m == 1.0
    bad = np.array([[[1.0, 0.5], [0.0, 1.0]]] * 2)
    with pytest.raises(InputError, match="symmetric"):
        Trajectory.build(t=[0, 1], xyz=[[0, 0, 0], [1, 0, 0]], cov_xy=bad)
    with pytest.raises(InputError, match="ends before"):
        StepEvents.build(t_start=[1.0], t_end=[0.5], length_m=[0.7])
    s = StepEvents.build(t_start=[0, 0.5], t_end=[0.5, 1.0], length_m=[0.7, 0.7],
                         activity=["walking", "upstairs"])
    assert s.distance_m == pytest.approx(1.4)
    assert list(s.activity) == [Activity.WALKING, Activity.UPSTAIRS]


def test_steps_select_and_concatenate_keep_every_column():
    a = StepEvents.build(t_start=[0.0, 0.5, 1.0], t_end=[0.5, 1.0, 1.5],
                         length_m=[0.6, 0.7, 0.8], heading_rad=[0.1, 0.2, 0.3],
                         dz_m=[0.0, 0.17, 0.0], activity=["walking", "upstairs", "standing"],
                         frequency_hz=[2.0, 2.0, 1.9], acc_max=[3.0, 4.0, 5.0],
                         acc_min=[-3.0, -4.0, -5.0])
    kept = a.select(np.array([True, False, True]))
    assert kept.t_start.tolist() == [0.0, 1.0]
    assert kept.dz_m.tolist() == [0.0, 0.0]
    assert kept.acc_min.tolist() == [-3.0, -5.0]
    b = StepEvents.build(t_start=[2.0], t_end=[2.6], length_m=[0.5])
    both = StepEvents.concatenate([kept, b])
    assert len(both) == 3
    assert both.length_m.tolist() == [0.6, 0.8, 0.5]
    assert list(both.activity) == [Activity.WALKING, Activity.STANDING, Activity.WALKING]
    assert np.isnan(both.heading_rad[2]) and both.heading_rad[:2].tolist() == [0.1, 0.3]
    with pytest.raises(InputError):  # the parts must stay in time order
        StepEvents.concatenate([b, kept])


def test_activity_parse_errors_name_index():
    with pytest.raises(InputError, match="index 1"):
        activity_codes(["walking", "flying"])


def test_guess_time_scale():
    assert guess_time_scale(np.arange(10) * 10.0) == 1e-3  # ms at 100 Hz
    assert guess_time_scale(np.arange(10) * 1e7) == 1e-9  # ns at 100 Hz
    assert guess_time_scale(np.arange(10) * 0.01) == 1.0


def test_imu_in_another_device_frame_and_heading_change() -> None:
    """Hand-made: a 90 deg turn about z of the device frame maps x onto y; refusals named."""
    import math

    from hrtls.data import ImuStream, SensorSeries, StepEvents
    from hrtls.errors import InputError
    from hrtls.evaluate.metrics import heading_change_rad

    t = np.arange(3) * 0.01
    acc = SensorSeries(t, np.tile([1.0, 0.0, 9.81], (3, 1)), "accel")
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    out = ImuStream(acc).in_device_frame(rz)
    np.testing.assert_allclose(out.accel.values, np.tile([0.0, 1.0, 9.81], (3, 1)))
    assert out.gyro is None and out.mag is None
    with pytest.raises(InputError, match="r_new_old"):
        ImuStream(acc).in_device_frame(2.0 * np.eye(3))
    n = 10
    heading = np.r_[np.zeros(5), np.full(5, 3.0)]          # a 3 rad turn half-way
    heading[7] = np.nan
    steps = StepEvents.build(t_start=np.arange(n) * 0.5, t_end=np.arange(n) * 0.5 + 0.5,
                             length_m=np.full(n, 0.7), heading_rad=heading)
    assert heading_change_rad(steps) == pytest.approx(3.0)
    with pytest.raises(InputError, match="heading_change_rad"):
        heading_change_rad(steps, end_fraction=0.9)
    assert math.isfinite(heading_change_rad(steps, end_fraction=0.5))
