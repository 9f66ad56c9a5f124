"""The per-sample helpers of the attitude kernels add no reference counting to the sample loop.

numba reference-counts an array each time an inlined helper binds it; the counts that its
pruning pass cannot remove (an array used inside a branch of the helper) are atomic operations
on every sample. Each helper is compiled here inside a loop, with run-time flags, and the loop
must hold no ``NRT_incref`` / ``NRT_decref`` call.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from hrtls.attitude import _inertial_lowpass_kernel as ILK
from hrtls.attitude import _kernels as K
from hrtls.attitude._jit import FASTMATH

OPTS = {"fastmath": FASTMATH, "error_model": "numpy"}  # as the kernels, without the cache


@numba.njit(**OPTS)
def _read_and_gyro(t, acc, gyr, mag, prm, aux, x, P):
    flags = 0
    on = t[0] > -1.0  # run-time flags, as in the kernels
    for i in range(t.shape[0]):
        s = K.read_sample(t, acc, gyr, mag, i, on, on, prm, aux)
        flags += K.gyro_step(aux, prm, s, on)
        flags += K.count_used(aux, flags, s.acc_fin, s.mag_fin, on)
    return flags


@numba.njit(**OPTS)
def _field(t, acc, gyr, mag, prm, aux, x, P):
    n = 0
    for i in range(t.shape[0]):
        if K.first_field(aux, prm, acc[i, 0], acc[i, 1]):
            n += 1
        ILK._mag_disturbance(x, aux, prm, acc[i, 0], acc[i, 1], gyr[i, 0], 0.01, 5.0, 0.1)
    return n


@numba.njit(**OPTS)
def _bias(t, acc, gyr, mag, prm, aux, x, P):
    for i in range(t.shape[0]):
        if gyr[i, 0] > 0.0:
            ILK._bias_update(P, aux, ILK.EYE3, acc[i, 0], acc[i, 1], acc[i, 2], 1.0, 1.0, 1.0,
                             0.1)
    return 0


@pytest.mark.parametrize("kernel", [_read_and_gyro, _field, _bias])
def test_sample_loop_has_no_reference_counting(kernel):
    n = 20
    rng = np.random.default_rng(0)
    t = np.arange(n) / 100.0
    acc, gyr, mag = (rng.normal(size=(n, 3)) for _ in range(3))
    prm = np.ones(ILK.WALK + 1)
    kernel(t, acc, gyr, mag, prm, np.zeros(K.AUX_SIZE), np.zeros(ILK.NX), np.eye(3))
    llvm = kernel.inspect_llvm(kernel.signatures[0])
    body = llvm.split("define ")[1]  # the compiled function itself (wrappers follow)
    assert "@NRT_incref" not in body and "@NRT_decref" not in body
