"""Causal hard-iron estimate: the circle fit of :mod:`~hrtls.calibration.hard_iron` as data come.

The raw field is averaged over consecutive blocks of ``block_samples`` samples (about one second,
see the fit's module notes), together with the accelerometer (the device's up direction). Every
``refit_blocks`` completed blocks, :func:`~hrtls.calibration.hard_iron.fit_hard_iron` is run on
the block means kept so far, with the mean accelerometer reading of those blocks as up
direction. A successful fit is *accepted* and applied to the samples after the block that
completed it; before the first accepted fit the offset is unknown (NaN, the field is used raw);
a refused refit keeps the last accepted offset.

Blocks are counted in samples from the first one, so the estimate at a sample is the same
however the recording is cut into chunks, and it never depends on later samples. Memory is
bounded: when more than ``max_blocks`` block means are kept, every second one is dropped and
only every second later block is kept (the stride doubles; the fit needs the headings seen,
not every second of them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hrtls.calibration.hard_iron import HardIronFit, fit_hard_iron
from hrtls.errors import InputError
from hrtls.frames import FloatArray

__all__ = ["RunningHardIron", "RunningHardIronParams", "RunningHardIronState"]


@dataclass(frozen=True, kw_only=True, slots=True)
class RunningHardIronParams:
    """Parameters of :class:`RunningHardIron`.

    block_samples: samples averaged into one block mean (the tracker uses one second).
    refit_blocks: completed blocks between two fits.
    max_blocks: block means kept at most (older ones thinned evenly).
    min_arc_deg, gate_fraction, min_field_ut, min_samples: those of
    :func:`~hrtls.calibration.hard_iron.fit_hard_iron` (``min_samples`` counts block means).
    """

    block_samples: int = 1
    refit_blocks: int = 10
    max_blocks: int = 1024
    min_arc_deg: float = 180.0
    gate_fraction: float = 0.15
    min_field_ut: float = 5.0
    min_samples: int = 50

    def __post_init__(self) -> None:
        for name in ("block_samples", "refit_blocks", "max_blocks", "min_samples"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} = {getattr(self, name)}", where="RunningHardIronParams",
                                 expected="at least 1")


@dataclass(slots=True)
class RunningHardIronState:
    """Everything :class:`RunningHardIron` carries between chunks (plain arrays and numbers).

    ``part_*``: sums over the block in progress; ``blocks_mag`` (max_blocks + 1, 3): kept block
    means, the first ``n_kept`` rows valid; ``c_ut``: the accepted offset (NaN before).
    """

    part_mag: FloatArray
    part_acc: FloatArray
    part_n: int
    part_bad: bool
    blocks_mag: FloatArray
    n_kept: int
    acc_sum: FloatArray
    n_good: int
    n_closed: int
    stride: int
    c_ut: FloatArray
    field_ut: float
    residual_ut: float
    arc_deg: float
    n_used: int
    t_accepted: float
    n_fits: int

    @classmethod
    def fresh(cls, max_blocks: int) -> RunningHardIronState:
        """The state before any sample."""
        return cls(np.zeros(3), np.zeros(3), 0, False, np.zeros((max_blocks + 1, 3)), 0,
                   np.zeros(3), 0, 0, 1, np.full(3, np.nan), math.nan, math.nan, math.nan, 0,
                   math.nan, 0)


class RunningHardIron:
    """Hard-iron offset estimated causally from the raw field of an ordinary walk."""

    def __init__(self, params: RunningHardIronParams | None = None) -> None:
        self.params = params or RunningHardIronParams()
        self.state = RunningHardIronState.fresh(self.params.max_blocks)

    @property
    def accepted(self) -> bool:
        """Whether a fit has been accepted."""
        return bool(np.all(np.isfinite(self.state.c_ut)))

    def update(self, t: FloatArray, mag_ut: FloatArray, acc_m_s2: FloatArray) -> FloatArray:
        """Offsets (N, 3) in force at each sample (NaN rows before the first accepted fit).

        ``t`` (N,) s, ``mag_ut`` raw field (N, 3), ``acc_m_s2`` accelerometer (N, 3), aligned.
        """
        st, bs = self.state, self.params.block_samples
        n = len(t)
        out = np.empty((n, 3))
        pos = 0
        if st.part_n:   # finish the block in progress
            pos = min(n, bs - st.part_n)
            self._add_partial(mag_ut[:pos], acc_m_s2[:pos])
            out[:pos] = st.c_ut
            if st.part_n == bs:
                ok = not st.part_bad
                self._close(st.part_mag / bs if ok else None, st.part_acc / bs, float(t[pos - 1]))
                self._clear_partial()
        k = (n - pos) // bs
        if k:
            end = pos + k * bs
            mb = mag_ut[pos:end].reshape(k, bs, 3)
            ab = acc_m_s2[pos:end].reshape(k, bs, 3)
            good = np.all(np.isfinite(mb), axis=(1, 2)) & np.all(np.isfinite(ab), axis=(1, 2))
            m_mean = mb.mean(axis=1)
            a_mean = ab.mean(axis=1)
            t_end = t[pos + bs - 1:end:bs]
            b = 0
            while b < k:   # runs of blocks that end where a refit may be due
                e = min(k, b + self.params.refit_blocks
                        - st.n_closed % self.params.refit_blocks)
                out[pos + b * bs:pos + e * bs] = st.c_ut
                self._close_run(m_mean[b:e], a_mean[b:e], good[b:e], float(t_end[e - 1]))
                b = e
            pos = end
        if pos < n:
            self._add_partial(mag_ut[pos:], acc_m_s2[pos:])
            out[pos:] = st.c_ut
        return out

    def _add_partial(self, m: FloatArray, a: FloatArray) -> None:
        st = self.state
        if np.all(np.isfinite(m)) and np.all(np.isfinite(a)):
            st.part_mag = st.part_mag + m.sum(axis=0)
            st.part_acc = st.part_acc + a.sum(axis=0)
        else:   # a block with a gap is dropped, as in the offline fit
            st.part_bad = True
        st.part_n += len(m)

    def _clear_partial(self) -> None:
        st = self.state
        st.part_mag = np.zeros(3)
        st.part_acc = np.zeros(3)
        st.part_n = 0
        st.part_bad = False

    def _close_run(self, mag_mean: FloatArray, acc_mean: FloatArray, good: np.ndarray,
                   t_end: float) -> None:
        """Completed blocks of which only the last may be due for a refit (``good``: no gap).

        Equal to :meth:`_close` block by block; the kept means are appended at once unless the
        run would thin the kept set.
        """
        st, prm = self.state, self.params
        n_good = int(good.sum())
        slot = (st.n_good + np.arange(n_good)) % st.stride == 0
        n_new = int(slot.sum())
        if st.n_kept + n_new > prm.max_blocks:
            for j in range(len(good)):
                self._close(mag_mean[j] if good[j] else None, acc_mean[j], t_end)
            return
        st.blocks_mag[st.n_kept:st.n_kept + n_new] = mag_mean[good][slot]
        st.n_kept += n_new
        # block by block, as :meth:`_close` adds them (the same rounding)
        st.acc_sum = np.cumsum(np.vstack([st.acc_sum, acc_mean[good]]), axis=0)[-1]
        st.n_good += n_good
        st.n_closed += len(good)
        if st.n_closed % prm.refit_blocks == 0 and st.n_kept >= prm.min_samples:
            self._refit(t_end)

    def _close(self, mag_mean: FloatArray | None, acc_mean: FloatArray, t_end: float) -> None:
        """One completed block (``mag_mean`` None: it had a gap); refit when one is due."""
        st, prm = self.state, self.params
        st.n_closed += 1
        if mag_mean is not None:
            if st.n_good % st.stride == 0:
                st.blocks_mag[st.n_kept] = mag_mean
                st.n_kept += 1
                if st.n_kept > prm.max_blocks:
                    half = st.blocks_mag[:st.n_kept:2].copy()
                    st.blocks_mag[:len(half)] = half
                    st.n_kept = len(half)
                    st.stride *= 2
            st.acc_sum = st.acc_sum + acc_mean
            st.n_good += 1
        if st.n_closed % prm.refit_blocks == 0 and st.n_kept >= prm.min_samples:
            self._refit(t_end)

    def _refit(self, t_end: float) -> None:
        st, prm = self.state, self.params
        try:
            fit: HardIronFit = fit_hard_iron(
                st.blocks_mag[:st.n_kept], up_d=st.acc_sum / max(st.n_good, 1), block_samples=1,
                min_arc_deg=prm.min_arc_deg, gate_fraction=prm.gate_fraction,
                min_field_ut=prm.min_field_ut, min_samples=prm.min_samples)
        except InputError:
            return
        if not self.accepted:
            st.t_accepted = t_end
        st.c_ut = np.asarray(fit.hard_iron_ut, dtype=np.float64)
        st.field_ut, st.residual_ut = fit.field_ut, fit.residual_ut
        st.arc_deg, st.n_used = fit.arc_deg, fit.n_used
        st.n_fits += 1
