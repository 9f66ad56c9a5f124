"""Compiled linear interpolation of several columns at once (imported on first use).

:meth:`hrtls.data.series.SensorSeries.interpolate` puts a magnetometer or gyroscope on the
accelerometer's clock; ``np.interp`` would search every query once per column. The kernel
walks the (usually increasing) queries once for all columns, with ``np.interp``'s arithmetic:
ends held, a query equal to a sample takes the sample, else ``slope (x - x_j) + y_j``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.kernels import njit

FloatArray = NDArray[np.float64]


@njit(cache=True)
def interp_columns_kernel(tq: FloatArray, t: FloatArray, values: FloatArray,
                          out: FloatArray) -> None:  # pragma: no cover - compiled
    """``out[:, c] = np.interp(tq, t, values[:, c])`` for every column (``t`` increasing).

    Rows are copied element by element: a row assignment from an array would make numba
    compile its formatted shape-mismatch error, seconds of a first run.
    """
    n = t.shape[0]
    j = 0
    for i in range(tq.shape[0]):
        x = tq[i]
        if math.isnan(x):
            out[i] = x
            continue
        if x < t[0]:
            _copy_row(values, 0, out, i)
            continue
        if x >= t[n - 1]:
            _copy_row(values, n - 1, out, i)
            continue
        if x < t[j]:   # queries went back: search again
            j = np.searchsorted(t, x, side="right") - 1
        while t[j + 1] <= x:   # t[j] <= x < t[j + 1]
            j += 1
        if t[j] == x:
            _copy_row(values, j, out, i)
            continue
        for c in range(values.shape[1]):
            slope = (values[j + 1, c] - values[j, c]) / (t[j + 1] - t[j])
            y = slope * (x - t[j]) + values[j, c]
            if math.isnan(y):   # as np.interp: try from the other end
                y = slope * (x - t[j + 1]) + values[j + 1, c]
                if math.isnan(y) and values[j, c] == values[j + 1, c]:
                    y = values[j, c]
            out[i, c] = y


@njit(cache=True, inline="always")
def _copy_row(src: FloatArray, k: int, dst: FloatArray, i: int) -> None:
    """``dst[i] = src[k]``."""  # pragma: no cover - compiled
    for c in range(src.shape[1]):
        dst[i, c] = src[k, c]
