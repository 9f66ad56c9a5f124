"""The Butterworth low-pass written in hrtls against scipy.signal, the reference."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfreqz

from hrtls.gait.butterworth import (
    butter_lowpass_sos,
    sos_kernel,
    sos_response,
    sos_steady_state,
)
from hrtls.gait.features import StreamingButterworth

DESIGNS = [(order, fraction * rate, rate)
           for order in range(1, 11)
           for fraction in (0.002, 0.03, 0.06, 0.2, 0.25, 0.3, 0.4, 0.45, 0.498)
           for rate in (50.0, 100.0, 100.31278980158413, 211.7)]


@pytest.mark.parametrize(("order", "cutoff_hz", "rate_hz"), DESIGNS)
def test_design_steady_state_and_response_equal_scipy(order: int, cutoff_hz: float,
                                                      rate_hz: float) -> None:
    ref = butter(order, cutoff_hz, fs=rate_hz, output="sos")
    sos = butter_lowpass_sos(order, cutoff_hz, rate_hz)
    # the same sections in the same order, to the bit: tracks equal those made with scipy
    np.testing.assert_array_equal(sos, ref)
    np.testing.assert_array_equal(sos_steady_state(sos), sosfilt_zi(ref))
    f = np.array([0.3, 1.79, 1.81, 0.4 * rate_hz])
    np.testing.assert_array_equal(sos_response(sos, f, rate_hz),
                                  sosfreqz(ref, worN=f, fs=rate_hz)[1])


@pytest.mark.parametrize(("order", "cutoff_hz"), [(4, 3.0), (5, 6.0), (3, 40.0)])
def test_kernel_equals_sosfilt(order: int, cutoff_hz: float) -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2000, 3)) + 9.0
    sos = butter_lowpass_sos(order, cutoff_hz, 100.0)
    zi = np.multiply.outer(sos_steady_state(sos), np.ones(3)) * x[0]
    ref, zf = sosfilt(sos, x, axis=0, zi=zi)
    y = np.empty_like(x)
    sos_kernel(sos, x, zi, y)
    np.testing.assert_array_equal(y, ref)
    np.testing.assert_array_equal(zi, zf)


def test_streaming_filter_of_one_column_and_of_columns() -> None:
    x = np.random.default_rng(4).normal(size=(300, 2))
    both = StreamingButterworth(order=5, cutoff_hz=6.0, rate_hz=100.0)
    one = StreamingButterworth(order=5, cutoff_hz=6.0, rate_hz=100.0)
    y = both.update(x)
    assert y.shape == x.shape
    np.testing.assert_array_equal(one.update(x[:, 1]), y[:, 1])
    assert both.zi is not None and both.zi.shape == (3, 2, 2)
    assert one.zi is not None and one.zi.shape == (3, 2)
    assert both.update(np.zeros((0, 2))).shape == (0, 2)
