"""Hard-iron offset from a walking recording (hrtls.calibration.hard_iron)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hrtls.calibration.hard_iron import fit_hard_iron
from hrtls.errors import InputError

EARTH_ENU = np.array([0.0, 24.0, -41.6])  # uT: 48 uT, 60 deg inclination, north = +y


def walking_field(c: np.ndarray, yaw_deg: np.ndarray, *, tilt_deg: float = 3.0,
                  noise_ut: float = 0.1, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Raw field and specific force of a device upright at the waist turning by ``yaw_deg``."""
    rng = np.random.default_rng(seed)
    n = len(yaw_deg)
    tilt = rng.normal(0.0, tilt_deg, (n, 2))
    r_nd = Rotation.from_euler("zyx", np.column_stack([yaw_deg, tilt]), degrees=True)
    mag = r_nd.inv().apply(EARTH_ENU) + c + rng.normal(0.0, noise_ut, (n, 3))
    acc = r_nd.inv().apply([0.0, 0.0, 9.81])
    return mag, acc


def test_recovers_the_horizontal_offset_of_a_device_turning_at_the_waist() -> None:
    c = np.array([4.6, 2.9, 0.8])
    yaw = np.linspace(0.0, 720.0, 4000)
    mag, acc = walking_field(c, yaw)
    fit = fit_hard_iron(mag, up_d=acc.mean(axis=0))
    assert fit.hard_iron_ut[:2] == pytest.approx(c[:2], abs=0.1)
    assert abs(fit.hard_iron_ut[2]) < 0.1  # the part along up is not observed: left at zero
    assert fit.field_ut == pytest.approx(24.0, abs=0.5)  # the horizontal field (+ tilt)
    assert fit.arc_deg > 350.0
    assert fit.residual_ut < 2.5  # the 3 deg tilt mixes in the vertical field


def test_figure_of_eight_recovers_all_three_components_without_up() -> None:
    rng = np.random.default_rng(3)
    c = np.array([-7.0, 12.0, 5.0])
    r_nd = Rotation.random(3000, random_state=rng)
    mag = r_nd.inv().apply(EARTH_ENU) + c + rng.normal(0.0, 0.1, (3000, 3))
    fit = fit_hard_iron(mag)
    assert fit.hard_iron_ut == pytest.approx(c, abs=0.05)
    assert fit.field_ut == pytest.approx(np.linalg.norm(EARTH_ENU), abs=0.1)


def test_disturbed_samples_are_dropped() -> None:
    c = np.array([-2.0, 3.5, 0.0])
    mag, acc = walking_field(c, np.linspace(0.0, 360.0, 3000), seed=1)
    mag[1000:1300] += np.array([15.0, -10.0, 5.0])  # passing a magnet: a tenth of the walk
    fit = fit_hard_iron(mag, up_d=acc.mean(axis=0))
    assert fit.hard_iron_ut[:2] == pytest.approx(c[:2], abs=0.25)  # 0.6 deg of heading
    assert fit.n_used <= 2750


def test_too_little_turning_is_refused_with_the_angle() -> None:
    mag, acc = walking_field(np.array([3.0, 0.0, 0.0]), np.linspace(0.0, 120.0, 4000))
    with pytest.raises(InputError, match=r"turned through 1[12]\d deg.*at least 180 deg"):
        fit_hard_iron(mag, up_d=acc.mean(axis=0), block_samples=40)


def test_block_means_keep_a_half_turn_accurate() -> None:
    # single samples: the 3 deg sway biases a circle fit to a short arc; block means do not
    c = np.array([4.0, -3.0, 1.0])
    mag, acc = walking_field(c, np.linspace(0.0, 200.0, 8000), seed=5)
    fit = fit_hard_iron(mag, up_d=acc.mean(axis=0), block_samples=50)
    assert fit.hard_iron_ut[:2] == pytest.approx(c[:2], abs=0.15)
    assert fit.arc_deg == pytest.approx(200.0, abs=5.0)
    with pytest.raises(InputError, match="block_samples"):
        fit_hard_iron(mag, block_samples=0)


@pytest.mark.parametrize("bad", [np.zeros((10, 3)), np.zeros((100, 2)), np.full((100, 3), np.nan)])
def test_bad_input_is_named(bad: np.ndarray) -> None:
    with pytest.raises(InputError, match="hard-iron fit"):
        fit_hard_iron(bad, up_d=[0.0, 0.0, 1.0])


def test_a_device_that_never_turns_is_refused() -> None:
    # straight walking: the samples scatter around one point and fit a tiny circle
    mag, acc = walking_field(np.array([3.0, 1.0, 0.0]), np.full(1500, 30.0), tilt_deg=1.0)
    with pytest.raises(InputError, match="span"):
        fit_hard_iron(mag, up_d=acc.mean(axis=0))


def test_zero_up_direction_is_refused() -> None:
    mag, _ = walking_field(np.zeros(3), np.linspace(0.0, 360.0, 500))
    with pytest.raises(InputError, match="up_d"):
        fit_hard_iron(mag, up_d=[0.0, 0.0, 0.0])


@settings(max_examples=40, deadline=None)
@given(cx=st.floats(-8.0, 8.0), cy=st.floats(-8.0, 8.0), start=st.floats(0.0, 360.0),
       mount_deg=st.floats(-180.0, 180.0))
def test_offset_recovered_for_any_offset_and_mounting_yaw(cx: float, cy: float, start: float,
                                                          mount_deg: float) -> None:
    # the device is turned about its vertical on the belt: same fit in its own frame
    c = np.array([cx, cy, 0.0])
    yaw = start + np.linspace(0.0, 300.0, 1500)
    mag, acc = walking_field(c, yaw + mount_deg, noise_ut=0.05, seed=2)
    fit = fit_hard_iron(mag, up_d=acc.mean(axis=0))
    assert np.hypot(*(fit.hard_iron_ut[:2] - c[:2])) < 0.15
    assert math.isfinite(fit.residual_ut)


def test_long_recordings_are_thinned_without_changing_the_offset() -> None:
    c = np.array([2.5, -4.0, 0.0])
    mag, acc = walking_field(c, np.linspace(0.0, 1440.0, 60_000), seed=4)
    thinned = fit_hard_iron(mag, up_d=acc.mean(axis=0), max_samples=5_000)
    assert thinned.n_used <= 5_000
    assert thinned.hard_iron_ut[:2] == pytest.approx(c[:2], abs=0.1)


def _covered_deg_sorted(d: np.ndarray) -> float:
    """Slow readable reference: 360 deg less the widest gap of the sorted directions."""
    ang = np.sort(np.arctan2(d[:, 1], d[:, 0]))
    gap = ang[0] + 2.0 * np.pi - ang[-1]
    if len(ang) > 1:
        gap = max(gap, float(np.max(np.diff(ang))))
    return 360.0 - float(np.degrees(gap))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=1, max_size=80),
       st.floats(0.1, 50.0))
def test_covered_angle_equals_the_sorted_reference(angles: list[float], radius: float) -> None:
    from hrtls.calibration.hard_iron import _spread

    a = np.asarray(angles)
    d = radius * np.column_stack([np.cos(a), np.sin(a)])
    arc, extent = _spread(d)
    assert arc == pytest.approx(_covered_deg_sorted(d), abs=1e-9)
    assert extent == pytest.approx(max(np.ptp(d[:, 0]), np.ptp(d[:, 1])))


def test_covered_angle_hand_computed() -> None:
    from hrtls.calibration.hard_iron import _spread

    # directions 0, 90 and 180 deg: the widest gap is the 180 deg from 180 back to 0
    d = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    assert _spread(d)[0] == pytest.approx(180.0)
    # a single direction covers nothing
    assert _spread(np.array([[0.0, 2.0]]))[0] == pytest.approx(0.0)
