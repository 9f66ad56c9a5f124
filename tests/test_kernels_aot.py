"""Kernels compiled ahead of time (``hrtls.jobs.aot``) equal their JIT builds; the checks of
their argument types; the JIT serves whatever has no build, and a failed build says so."""

from __future__ import annotations

import os
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hrtls.kernels as K
from hrtls.data._interp_kernel import interp_columns_kernel
from hrtls.fusion.gating import joseph_kernel
from hrtls.gait.butterworth import sos_kernel
from hrtls.gait.motion_detector import running_std_kernel

HAS_CC = shutil.which(os.environ.get("CC", "cc")) is not None or shutil.which("gcc") is not None


def _sos_args(rng: np.random.Generator, n: int) -> tuple[object, ...]:
    sos = rng.normal(size=(2, 6))
    sos[:, 3] = 1.0
    sos[:, 4:] *= 0.2
    return sos, rng.normal(size=(n, 3)), rng.normal(size=(2, 2, 3)), np.empty((n, 3))


def _interp_args(rng: np.random.Generator, n: int) -> tuple[object, ...]:
    t = np.cumsum(rng.uniform(0.01, 0.1, size=n))
    tq = np.sort(rng.uniform(t[0] - 0.2, t[-1] + 0.2, size=n + 3))
    return tq, t, rng.normal(size=(n, 2)), np.empty((n + 3, 2))


def _std_args(rng: np.random.Generator, n: int) -> tuple[object, ...]:
    return (np.cumsum(rng.uniform(0.005, 0.02, size=n)), rng.normal(size=n), 0.25,
            np.zeros(16), np.zeros(16), np.zeros(2, dtype=np.int64), np.zeros(3), np.zeros(n),
            np.zeros(n))


def _joseph_args(rng: np.random.Generator, n: int) -> tuple[object, ...]:
    k = 1 + n % 4
    a = rng.normal(size=(k, k))
    p = a @ a.T + np.eye(k)
    return (rng.normal(size=k), p, rng.normal(size=(2, k)), np.eye(2) * rng.uniform(0.1, 2.0),
            rng.normal(size=2), 9.21, -1, np.zeros(k), np.zeros((k, k)), np.zeros((2, 2)))


CASES = ((sos_kernel, _sos_args), (interp_columns_kernel, _interp_args),
         (running_std_kernel, _std_args), (joseph_kernel, _joseph_args))


@pytest.fixture(scope="module")
def builds(tmp_path_factory: pytest.TempPathFactory) -> K.Table:
    """The kernels of :data:`CASES` built ahead of time from their JIT builds."""
    if not HAS_CC:
        pytest.skip("no C compiler: the ahead-of-time build is not possible here")
    from hrtls.jobs.aot import build

    rng = np.random.default_rng(0)
    for kernel, make in CASES:
        kernel.dispatcher(*make(rng, 20))
    where = tmp_path_factory.mktemp("aot")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # one build per signature the JIT made (other tests may have added some)
        n_sigs = sum(len(k.dispatcher.signatures) for k, _ in CASES)
        assert build([k for k, _ in CASES], where=where) == n_sigs >= 4
    table, needs = K.load_builds(where)
    assert set(table) == {k.key for k, _ in CASES}
    # the Joseph update multiplies with BLAS (numba calls scipy's cython_blas); the others not
    assert needs == {k.key: ["scipy.linalg.cython_blas"] if k is joseph_kernel else []
                     for k, _ in CASES}
    return table


def _aot_call(table: K.Table, kernel: K.Kernel, args: tuple[object, ...]) -> object:
    # the first build that fits, as Kernel.__call__ picks it
    fitting = [fn for fn, fits in table[kernel.key] if fits(args)]
    assert fitting
    return fitting[0](*args)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 300))
def test_builds_equal_the_jit_bit_for_bit(builds: K.Table, seed: int, n: int) -> None:
    for kernel, make in CASES:
        jit_args = make(np.random.default_rng(seed), n)
        aot_args = make(np.random.default_rng(seed), n)
        np.testing.assert_equal(_aot_call(builds, kernel, aot_args),
                                kernel.dispatcher(*jit_args))
        for a, b in zip(aot_args, jit_args, strict=True):
            if isinstance(a, np.ndarray):  # outputs written in place: the same bits
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_builds_are_not_loaded_once_a_source_changes(builds: K.Table, tmp_path: Path) -> None:
    import pickle

    manifest = {"file": "missing.so", "exports": {}, "sources": [(__file__, 0, 0)]}
    with open(tmp_path / K.MANIFEST, "wb") as fh:
        pickle.dump(manifest, fh)
    assert K.load_builds(tmp_path) == ({}, {})
    assert K.load_builds(tmp_path / "nothing here") == ({}, {})


def test_argument_checks_follow_numba_types() -> None:
    f8 = np.dtype(np.float64)
    fits = K.guard([("a", f8, 2, "C", True), ("s", (float, np.float64)),
                    ("s", (int, np.int64)), ("s", (bool, np.bool_))])
    a = np.zeros((3, 2))
    assert fits((a, 1.0, 2, True)) and fits((a, np.float64(1.0), np.int64(2), np.bool_(False)))
    assert not fits((a, 1, 2, True))  # an int where numba types a float64
    assert not fits((a, 1.0, 2.0, True)) and not fits((a, 1.0, True, True))
    assert not fits((a, 1.0, 2))  # too few
    assert not fits((a[:, :1], 1.0, 2, True))  # strided: layout "A"
    assert not fits((np.asfortranarray(np.zeros((3, 2))), 1.0, 2, True))
    assert not fits((a.astype(np.float32), 1.0, 2, True)) and not fits((a[0], 1.0, 2, True))
    ro = a.copy()
    ro.flags.writeable = False
    assert not fits((ro, 1.0, 2, True))
    assert K.array_layout(a[:, :1]) == "A" and K.array_layout(a.T) == "F"


def test_a_kernel_without_builds_calls_the_jit() -> None:
    seen: list[str] = []

    def double(x: np.ndarray) -> None:  # pragma: no cover - compiled
        for i in range(x.size):
            x[i] *= 2.0

    kernel = K.njit(cache=False)(double)
    kernel._aot = ((lambda x: seen.append("aot"), K.guard([("a", np.dtype(np.int64), 1, "C",
                                                             True)])),)
    x = np.arange(3.0)
    kernel(x)  # float64: not the build's type
    assert seen == [] and x.tolist() == [0.0, 2.0, 4.0]
    kernel(np.arange(3))
    assert seen == ["aot"]
    assert kernel.py_func is double and "numba" in sys.modules


def test_a_failed_build_says_so_in_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    import hrtls.jobs.aot as aot
    from hrtls.jobs.warmup import build_ahead

    def no_compiler(*args: object, **kwargs: object) -> int:
        raise FileNotFoundError("cc: not found. If using conda try:\nmore")

    monkeypatch.setattr(aot, "build", no_compiler)
    message = build_ahead()
    assert message == ("kernels not compiled ahead of time (cc: not found); the JIT kernels "
                       "are used")


def test_cython_blas_loads_without_scipy_linalg() -> None:
    import subprocess

    code = ("import sys, hrtls.kernels as K; K.preload_cython('scipy.linalg.cython_blas'); "
            "m = sys.modules['scipy.linalg.cython_blas']; "
            "print('scipy.linalg' in sys.modules, 'dgemm' in m.__pyx_capi__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120).stdout.split()
    assert out == ["False", "True"]


def test_kernels_pickle_as_references() -> None:
    import pickle

    assert pickle.loads(pickle.dumps(sos_kernel)) is sos_kernel
    assert K.declared("hrtls.gait.butterworth:sos_kernel") is sos_kernel
