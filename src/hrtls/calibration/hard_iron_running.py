"""Causal hard-iron estimate: the circle fit of :mod:`~hrtls.calibration.hard_iron` as data come.

The raw field is averaged over consecutive blocks of ``block_samples`` samples (about one second,
see the fit's module notes), together with the accelerometer (the device's up direction). Every
``refit_blocks`` completed blocks, the fit and the acceptance tests of
:func:`~hrtls.calibration.hard_iron.fit_hard_iron` (one compiled pass per chunk) are run on
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

from hrtls.calibration.hard_iron import FIT_OK, checked_fit_kernel, plane_basis_kernel
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
            m_mean, a_mean = np.empty((k, 3)), np.empty((k, 3))
            good = np.empty(k, dtype=np.bool_)
            block_means_kernel(np.ascontiguousarray(mag_ut[pos:end], dtype=np.float64),
                               np.ascontiguousarray(acc_m_s2[pos:end], dtype=np.float64), bs,
                               m_mean, a_mean, good)
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
        """Completed blocks (``good``: no gap) in one compiled pass; ``out``: their samples."""
        st, prm = self.state, self.params
        ints = np.array([st.n_kept, st.n_good, st.n_closed, st.stride, st.n_used, st.n_fits])
        fl = np.array([st.field_ut, st.residual_ut, st.arc_deg, st.t_accepted])
        st.acc_sum = st.acc_sum.copy()
        st.c_ut = st.c_ut.copy()
        close_blocks_kernel(mag_mean, acc_mean, good, t_end, st.blocks_mag, st.acc_sum, st.c_ut,
                            ints, fl, out, prm.refit_blocks, prm.max_blocks, prm.min_samples,
                            prm.gate_fraction, prm.min_field_ut, prm.min_arc_deg)
        st.n_kept, st.n_good, st.n_closed, st.stride, st.n_used, st.n_fits = \
            (int(v) for v in ints)
        st.field_ut, st.residual_ut, st.arc_deg, st.t_accepted = (float(v) for v in fl)


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


@njit(cache=True)
def close_blocks_kernel(mag_mean: FloatArray, acc_mean: FloatArray, good: np.ndarray,
                        t_end: FloatArray, blocks_mag: FloatArray, acc_sum: FloatArray,
                        c_ut: FloatArray, ints: np.ndarray, fl: FloatArray, out: FloatArray,
                        refit_blocks: int, max_blocks: int, min_samples: int,
                        gate_fraction: float, min_field_ut: float,
                        min_arc_deg: float) -> None:  # pragma: no cover - compiled
    """Close blocks in order, keeping their means and refitting when due (state in place).

    ``ints``: ``[n_kept, n_good, n_closed, stride, n_used, n_fits]``; ``fl``: ``[field_ut,
    residual_ut, arc_deg, t_accepted]`` of :class:`RunningHardIronState`. ``out`` (``k bs``,
    3) gets, for the samples of each block, the offset in force before the block closed
    (``out`` may be empty: not written). Rows are copied element by element (no numba
    shape-mismatch message to compile, :func:`hrtls.data._interp_kernel.interp_columns_kernel`).
    """
    n_kept, n_good, n_closed, stride = ints[0], ints[1], ints[2], ints[3]
    bs = out.shape[0] // mag_mean.shape[0]
    for b in range(mag_mean.shape[0]):
        for i in range(b * bs, (b + 1) * bs):
            for a in range(3):
                out[i, a] = c_ut[a]
        n_closed += 1
        if good[b]:
            if n_good % stride == 0:
                for a in range(3):
                    blocks_mag[n_kept, a] = mag_mean[b, a]
                n_kept += 1
                if n_kept > max_blocks:   # thin evenly: every second kept mean
                    half = (n_kept + 1) // 2
                    for k in range(half):   # row k <- row 2k (k <= 2k: in place)
                        for a in range(3):
                            blocks_mag[k, a] = blocks_mag[2 * k, a]
                    n_kept = half
                    stride *= 2
            acc_sum += acc_mean[b]
            n_good += 1
        if n_closed % refit_blocks != 0 or n_kept < min_samples:
            continue
        up = acc_sum / max(n_good, 1)
        norm2 = up[0] * up[0] + up[1] * up[1] + up[2] * up[2]
        if not (math.isfinite(norm2) and norm2 > 0.0):
            continue
        code, c, r, resid, arc, _, n_used = checked_fit_kernel(
            blocks_mag[:n_kept], plane_basis_kernel(up), gate_fraction, min_samples,
            min_field_ut, min_arc_deg)
        if code != FIT_OK:
            continue   # a refused refit keeps the last accepted offset
        if not np.all(np.isfinite(c_ut)):
            fl[3] = t_end[b]
        for a in range(3):
            c_ut[a] = c[a]
        fl[0], fl[1], fl[2] = r, resid, arc
        ints[4] = n_used
        ints[5] += 1
    ints[0], ints[1], ints[2], ints[3] = n_kept, n_good, n_closed, stride
