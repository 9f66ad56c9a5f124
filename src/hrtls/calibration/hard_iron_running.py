"""Causal hard-iron estimate: the circle fit of :mod:`~hrtls.calibration.hard_iron` as data come.

The raw field is averaged over consecutive blocks of ``block_samples`` samples (about one second,
see the fit's module notes), together with the accelerometer (the device's up direction). Every
``refit_blocks`` completed blocks, the fit and the acceptance tests of
:func:`~hrtls.calibration.hard_iron.fit_hard_iron` (one compiled pass,
:mod:`hrtls.calibration._running_fit_kernel`) are run on the block means kept so far, with the
mean accelerometer reading of those blocks as up direction; the blocks between two refits are
kept together (numpy). A successful fit is *accepted* and applied to the samples after the
block that completed it; before the first accepted fit the offset is unknown (NaN, the field is
used raw); a refused refit keeps the last accepted offset.

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

from hrtls.calibration._running_fit_kernel import FIT_OK, running_fit_kernel
from hrtls.errors import InputError
from hrtls.frames import FloatArray
from hrtls.kernels import njit

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
                self._close_blocks((st.part_mag / bs)[None], (st.part_acc / bs)[None],
                                   np.array([not st.part_bad]), np.array([float(t[pos - 1])]),
                                   np.empty((0, 3)))
                self._clear_partial()
        k = (n - pos) // bs
        if k:
            end = pos + k * bs
            m_mean, a_mean, good = block_means(mag_ut[pos:end], acc_m_s2[pos:end], bs)
            self._close_blocks(m_mean, a_mean, good,
                               np.ascontiguousarray(t[pos + bs - 1:end:bs]), out[pos:end])
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

    def _close_blocks(self, mag_mean: FloatArray, acc_mean: FloatArray, good: np.ndarray,
                      t_end: FloatArray, out: FloatArray) -> None:
        """Close blocks in order (``good``: no gap), refitting when due.

        ``out``: the rows of their samples (``len(mag_mean) * block_samples``, or none), set to
        the offset in force before each block closed. The blocks between two refits are
        handled together.
        """
        st, prm = self.state, self.params
        k = len(mag_mean)
        bs = out.shape[0] // k
        goods = np.flatnonzero(good)
        means = mag_mean[goods]
        # running sums of the accelerometer means, added in block order
        acc_run = np.cumsum(np.vstack([st.acc_sum[None], acc_mean[goods]]), axis=0)
        n_before = np.r_[0, np.cumsum(good)]     # good blocks before each block
        b = 0
        while b < k:
            e = min(k, b + prm.refit_blocks - st.n_closed % prm.refit_blocks)
            out[b * bs:e * bs] = st.c_ut
            self._keep(means[n_before[b]:n_before[e]])
            st.acc_sum = acc_run[n_before[e]].copy()
            st.n_closed += e - b
            if st.n_closed % prm.refit_blocks == 0 and st.n_kept >= prm.min_samples:
                self._refit(float(t_end[e - 1]))
            b = e

    def _keep(self, means: FloatArray) -> None:
        """Keep every ``stride``-th good block mean (counted over all good blocks).

        More than ``max_blocks`` kept: every second one is dropped and the stride doubles.
        """
        st, cap = self.state, self.params.max_blocks
        if st.stride == 1 and st.n_kept + len(means) <= cap:    # all kept, no thinning
            st.blocks_mag[st.n_kept:st.n_kept + len(means)] = means
            st.n_kept += len(means)
            st.n_good += len(means)
            return
        pos = 0
        while pos < len(means):
            due = pos + np.flatnonzero((st.n_good + np.arange(len(means) - pos)) % st.stride == 0)
            take = due[:cap + 1 - st.n_kept]
            st.blocks_mag[st.n_kept:st.n_kept + len(take)] = means[take]
            st.n_kept += len(take)
            if st.n_kept <= cap:
                st.n_good += len(means) - pos
                return
            st.n_good += int(take[-1]) + 1 - pos
            pos = int(take[-1]) + 1
            half = (st.n_kept + 1) // 2
            st.blocks_mag[:half] = st.blocks_mag[:st.n_kept:2].copy()
            st.n_kept = half
            st.stride *= 2

    def _refit(self, t_end: float) -> None:
        """The fit on the kept block means; accepted, it is the offset from now on."""
        st, prm = self.state, self.params
        up = st.acc_sum / max(st.n_good, 1)
        u0, u1, u2 = up.tolist()
        norm2 = u0 * u0 + u1 * u1 + u2 * u2
        if not (math.isfinite(norm2) and norm2 > 0.0):
            return
        fit = np.empty(6)
        code, n_used = running_fit_kernel(st.blocks_mag[:st.n_kept], up, prm.gate_fraction,
                                          prm.min_samples, prm.min_field_ut, prm.min_arc_deg,
                                          fit)
        if code != FIT_OK:
            return   # a refused refit keeps the last accepted offset
        if not self.accepted:
            st.t_accepted = t_end
        c0, c1, c2, st.field_ut, st.residual_ut, st.arc_deg = fit.tolist()
        st.c_ut = np.array([c0, c1, c2])
        st.n_used = int(n_used)
        st.n_fits += 1


def block_means(mag: FloatArray, acc: FloatArray, bs: int
                ) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """Means of consecutive blocks of ``bs`` rows, and whether each block is all finite.

    :func:`block_means_kernel`; the means of a block that is not all finite are unset.
    """
    k = len(mag) // bs
    m_mean, a_mean = np.empty((k, 3)), np.empty((k, 3))
    good = np.empty(k, dtype=np.bool_)
    block_means_kernel(np.ascontiguousarray(mag[:k * bs], dtype=np.float64),
                       np.ascontiguousarray(acc[:k * bs], dtype=np.float64), bs, m_mean, a_mean,
                       good)
    return m_mean, a_mean, good


@njit(cache=True)
def block_means_kernel(mag: FloatArray, acc: FloatArray, bs: int, mag_mean: FloatArray,
                       acc_mean: FloatArray, good: np.ndarray) -> None:
    # pragma: no cover - compiled
    """Means of consecutive blocks of ``bs`` rows, summed in row order as numpy's ``mean``.

    ``good``: every value of the block is finite (else its means are left unset).
    """
    for b in range(mag_mean.shape[0]):
        i0 = b * bs
        ok = True
        for i in range(i0, i0 + bs):
            for a in range(3):
                ok = ok and math.isfinite(mag[i, a]) and math.isfinite(acc[i, a])
        good[b] = ok
        if not ok:
            continue
        for a in range(3):
            sm = mag[i0, a]
            sa = acc[i0, a]
            for i in range(i0 + 1, i0 + bs):
                sm += mag[i, a]
                sa += acc[i, a]
            mag_mean[b, a] = sm / bs
            acc_mean[b, a] = sa / bs
