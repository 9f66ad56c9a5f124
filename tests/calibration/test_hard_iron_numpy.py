"""The hard-iron fit (numpy offline, a lean compiled refit and numpy blocks in the running fit)
equals the compiled kernels it replaced, to the last bit (random and real data)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.calibration import _compiled_hard_iron as ref
from tests.calibration.test_hard_iron import walking_field

from hrtls.calibration._running_fit_kernel import running_fit_kernel
from hrtls.calibration.hard_iron import FIT_FAILED, FIT_OK, checked_fit, plane_basis
from hrtls.calibration.hard_iron_running import (
    RunningHardIron,
    RunningHardIronParams,
    block_means,
)

LOG = "ipin2023/IPIN2023_T3_TrainingTrial04_repetition01.txt"


def _field(seed: int, n: int, turn_deg: float, outliers: float) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """Raw field of a device turning ``turn_deg`` with noise and disturbed samples; its up."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-8.0, 8.0, 3)
    yaw = np.sort(rng.uniform(0.0, turn_deg, n))
    mag, acc = walking_field(c, yaw, tilt_deg=float(rng.uniform(0.0, 20.0)), seed=seed)
    bad = rng.random(n) < outliers
    mag[bad] += rng.normal(0.0, 15.0, (int(bad.sum()), 3))
    return mag, acc.mean(axis=0)


def _same_fit(new: tuple, old: tuple) -> None:
    code, c, r, resid, arc, extent, n_used = new
    assert code == old[0] and n_used == old[6]
    np.testing.assert_array_equal(c, old[1])
    assert (r, extent) == (old[2], old[5])
    assert resid == old[3] or (math.isnan(resid) and math.isnan(old[3]))
    # arctan2 and degrees of numpy and of numba's libm calls may differ in the last bit
    assert arc == pytest.approx(old[4], rel=1e-12, abs=1e-9, nan_ok=True)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(20, 400), turn=st.floats(30.0, 720.0),
       outliers=st.sampled_from([0.0, 0.05, 0.3]), gate=st.sampled_from([0.05, 0.15, 0.5]))
def test_plane_fit_equals_the_compiled_fit(seed: int, n: int, turn: float, outliers: float,
                                           gate: float) -> None:
    mag, up = _field(seed, n, turn, outliers)
    basis = plane_basis(up)
    np.testing.assert_array_equal(basis, ref.plane_basis_kernel(up))
    old = ref.checked_fit_kernel(mag, basis, gate, 20, 5.0, 180.0)
    _same_fit(checked_fit(mag, basis, gate, 20, 5.0, 180.0), old)
    out = np.full(6, np.nan)
    code, n_used = running_fit_kernel(mag, up, gate, 20, 5.0, 180.0, out)
    assert code == old[0]
    if code == FIT_FAILED:
        return
    assert n_used == old[6]
    np.testing.assert_array_equal(out[:3], old[1])
    assert tuple(out[3:]) == (old[2], old[3], old[4])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(20, 300))
def test_sphere_fit_equals_the_compiled_fit(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    mag = 30.0 * d / np.linalg.norm(d, axis=1)[:, None] + rng.uniform(-5, 5, 3)
    mag += rng.normal(0.0, 0.5, mag.shape)
    ok, cp, r, resid, kept = ref._fit_kernel(mag, np.eye(3), 0.15, 20, 3)
    new = checked_fit(mag, np.eye(3), 0.15, 20, 5.0, 180.0)
    assert ok and new[0] == FIT_OK
    np.testing.assert_array_equal(new[1], cp)
    assert (new[2], new[3], new[6]) == (r, resid, len(kept))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(1, 30), bs=st.integers(1, 150))
def test_block_means_add_the_rows_in_order(seed: int, k: int, bs: int) -> None:
    rng = np.random.default_rng(seed)
    mag = rng.normal(0.0, 30.0, (k * bs + 3, 3)) * 10.0 ** rng.integers(-3, 4, (k * bs + 3, 1))
    acc = rng.normal(0.0, 9.8, mag.shape)
    acc[rng.integers(0, len(acc))] = np.nan
    m_mean, a_mean, good = block_means(mag, acc, bs)
    for b in range(k):
        rows = slice(b * bs, (b + 1) * bs)
        assert good[b] == bool(np.isfinite(acc[rows]).all())
        if not good[b]:
            continue
        for a in range(3):
            total = 0.0
            for v in mag[rows, a]:
                total += float(v)
            assert m_mean[b, a] == total / bs
        np.testing.assert_array_equal(a_mean[b], ref_block_mean(acc[rows]))


def ref_block_mean(rows: np.ndarray) -> np.ndarray:
    """Mean of the rows added one after the other (as the compiled kernel did)."""
    m, a, good = (np.empty((1, 3)), np.empty((1, 3)), np.empty(1, dtype=np.bool_))
    ref.block_means_kernel(rows, rows, len(rows), m, a, good)
    return m[0]


def _chunks(n: int, cuts: list[int]) -> list[tuple[int, int]]:
    edges = np.unique(np.clip(np.cumsum(cuts), 0, n))
    return [(a, b) for a, b in zip(np.r_[0, edges], np.r_[edges, n], strict=True) if b > a]


def _both(params: RunningHardIronParams, t: np.ndarray, mag: np.ndarray, acc: np.ndarray,
          chunks: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray, RunningHardIron,
                                                  RunningHardIron]:
    new, old = RunningHardIron(params), ref.CompiledRunningHardIron(params)
    a = np.concatenate([new.update(t[i:j], mag[i:j], acc[i:j]) for i, j in chunks])
    b = np.concatenate([old.update(t[i:j], mag[i:j], acc[i:j]) for i, j in chunks])
    return a, b, new, old


def _same_state(new: RunningHardIron, old: RunningHardIron) -> None:
    s, o = new.state, old.state
    for name in s.__slots__:
        np.testing.assert_array_equal(getattr(s, name), getattr(o, name), err_msg=name)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 1000), cuts=st.lists(st.integers(1, 900), min_size=1, max_size=8),
       max_blocks=st.sampled_from([1024, 40, 21]), refit=st.integers(1, 12),
       block=st.integers(1, 12))
def test_running_fit_equals_the_compiled_one(seed: int, cuts: list[int], max_blocks: int,
                                             refit: int, block: int) -> None:
    n = 2400
    mag, acc = walking_field(np.array([3.0, -5.0, 1.0]), np.linspace(0.0, 900.0, n), seed=seed)
    mag[n // 4:n // 4 + 15] = np.nan   # gaps drop their blocks
    acc[n // 2:n // 2 + 3] = np.nan
    t = np.arange(n) * 0.01
    params = RunningHardIronParams(block_samples=block, refit_blocks=refit,
                                   max_blocks=max_blocks, min_samples=20)
    a, b, new, old = _both(params, t, mag, acc, _chunks(n, cuts))
    np.testing.assert_array_equal(a, b)
    _same_state(new, old)
    assert new.state.n_fits > 0


def test_running_fit_on_a_real_walk_equals_the_compiled_one(shared_data: Path) -> None:
    from hrtls.recordings import read_any

    path = shared_data / LOG
    if not path.exists():
        pytest.skip("ipin2023 recordings not available")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        imu = read_any(path).imu
    assert imu is not None and imu.mag is not None
    t, acc = imu.accel.t, imu.accel.values
    mag = np.stack([np.interp(t, imu.mag.t, imu.mag.values[:, a]) for a in range(3)], axis=1)
    params = RunningHardIronParams(block_samples=max(1, round(imu.accel.rate_hz)))
    step = max(1, round(imu.accel.rate_hz / 2))    # half-second chunks, as streamed live
    a, b, new, old = _both(params, t, mag, acc, [(i, min(i + step, len(t)))
                                                 for i in range(0, len(t), step)])
    np.testing.assert_array_equal(a, b)
    _same_state(new, old)
    assert new.state.n_fits > 0
