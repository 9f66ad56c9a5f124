"""Causal hard-iron estimate (hrtls.calibration.hard_iron_running)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.calibration.test_hard_iron import walking_field

from hrtls.calibration.hard_iron import fit_hard_iron
from hrtls.calibration.hard_iron_running import RunningHardIron, RunningHardIronParams
from hrtls.errors import InputError

C_UT = np.array([4.0, -3.0, 1.0])


def _walk(n_blocks: int, block: int, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]:
    """Times, raw field and specific force of a device turning slowly, with a gap."""
    n = n_blocks * block
    yaw = np.linspace(0.0, 720.0, n)
    mag, acc = walking_field(C_UT, yaw, seed=seed)
    mag[n // 3:n // 3 + block // 2] = np.nan  # a gap drops its block
    return np.arange(n) * 0.01, mag, acc


class _BlockByBlock:
    """Slow readable reference: every block closed on its own, refits by ``fit_hard_iron``."""

    def __init__(self, params: RunningHardIronParams) -> None:
        self.params = params
        self.kept: list[np.ndarray] = []
        self.stride = 1
        self.acc_sum = np.zeros(3)
        self.n_good = self.n_closed = self.n_fits = 0
        self.c_ut = np.full(3, np.nan)

    def update(self, t: np.ndarray, mag_ut: np.ndarray, acc_m_s2: np.ndarray) -> np.ndarray:
        out = np.empty((len(t), 3))
        prm, bs = self.params, self.params.block_samples
        for i in range(0, len(t) - len(t) % bs, bs):
            sl = slice(i, i + bs)
            out[sl] = self.c_ut
            m, a = mag_ut[sl], acc_m_s2[sl]
            self.n_closed += 1
            if np.all(np.isfinite(m)) and np.all(np.isfinite(a)):
                if self.n_good % self.stride == 0:
                    self.kept.append(m.mean(axis=0))
                    if len(self.kept) > prm.max_blocks:
                        self.kept = self.kept[::2]
                        self.stride *= 2
                self.acc_sum = self.acc_sum + a.mean(axis=0)
                self.n_good += 1
            if self.n_closed % prm.refit_blocks == 0 and len(self.kept) >= prm.min_samples:
                try:
                    fit = fit_hard_iron(np.array(self.kept), up_d=self.acc_sum / self.n_good,
                                        min_arc_deg=prm.min_arc_deg,
                                        gate_fraction=prm.gate_fraction,
                                        min_field_ut=prm.min_field_ut,
                                        min_samples=prm.min_samples)
                except InputError:
                    continue
                self.c_ut = fit.hard_iron_ut
                self.n_fits += 1
        return out


def _params(max_blocks: int) -> RunningHardIronParams:
    return RunningHardIronParams(block_samples=10, refit_blocks=7, max_blocks=max_blocks,
                                 min_samples=20)


def test_runs_of_blocks_equal_the_block_by_block_reference() -> None:
    t, mag, acc = _walk(400, 10)
    for max_blocks in (1024, 48):   # 48: the kept set is thinned several times
        fast = RunningHardIron(_params(max_blocks)).update(t, mag, acc)
        ref_est = _BlockByBlock(_params(max_blocks))
        ref = ref_est.update(t, mag, acc)
        np.testing.assert_array_equal(fast, ref)
        assert ref_est.n_fits > 10
    assert np.allclose(fast[-1, :2], C_UT[:2], atol=0.3)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 700), min_size=1, max_size=8), st.sampled_from([1024, 48]))
def test_any_chunking_gives_the_offsets_of_one_chunk(cuts: list[int], max_blocks: int) -> None:
    t, mag, acc = _walk(200, 10, seed=1)
    whole = RunningHardIron(_params(max_blocks)).update(t, mag, acc)
    est = RunningHardIron(_params(max_blocks))
    edges = np.unique(np.clip(np.cumsum(cuts), 0, len(t)))
    parts = [est.update(t[a:b], mag[a:b], acc[a:b])
             for a, b in zip(np.r_[0, edges], np.r_[edges, len(t)], strict=True) if b > a]
    # a block cut by a chunk is summed in two parts: equal up to rounding
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0.0, atol=1e-9)
