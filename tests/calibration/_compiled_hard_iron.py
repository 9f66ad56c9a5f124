"""The hard-iron fit as numba kernels, as it was compiled before it moved to numpy.

The reference of ``test_hard_iron_numpy.py``: the same algorithm with the same order of
operations in compiled loops (commit 08389f7 of ``hrtls.calibration.hard_iron`` and
``hard_iron_running``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hrtls.calibration.hard_iron import FIT_FAILED, FIT_NARROW, FIT_OK, FIT_SHORT_ARC
from hrtls.calibration.hard_iron_running import RunningHardIron

_GATE_PASSES = 3
FloatArray = np.ndarray


class CompiledRunningHardIron(RunningHardIron):
    """:class:`RunningHardIron` with its blocks closed by the compiled kernels."""

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



@njit
def _solve_kernel(p: FloatArray, keep: np.ndarray) -> tuple[FloatArray, float]:
    """Least-squares circle (sphere) through the rows ``keep`` of ``p``: ``(centre, r^2)``.

    ``|u|^2 = 2 c.u + k`` for ``u = p - mean``, by the normal equations of its (k+1) unknowns
    (Gaussian elimination with partial pivoting); ``r^2 = k + |c|^2``.
    """
    dim = p.shape[1]
    if dim == 2:
        return _solve_plane(p, keep)
    n = 0
    mean = np.zeros(dim)
    for i in range(p.shape[0]):
        if keep[i]:
            n += 1
            for a in range(dim):
                mean[a] += p[i, a]
    for a in range(dim):
        mean[a] /= n
    m = np.zeros((dim + 1, dim + 2))      # [A^T A | A^T b], A = [2u, 1], b = |u|^2
    row = np.empty(dim + 1)
    row[dim] = 1.0
    for i in range(p.shape[0]):
        if not keep[i]:
            continue
        bb = 0.0
        for a in range(dim):
            u = p[i, a] - mean[a]
            row[a] = 2.0 * u
            bb += u * u
        for a in range(dim + 1):
            for b in range(a, dim + 1):
                m[a, b] += row[a] * row[b]
            m[a, dim + 1] += row[a] * bb
    for a in range(dim + 1):    # A^T A is symmetric: the lower triangle from the upper
        for b in range(a):
            m[a, b] = m[b, a]
    return _eliminate(m, mean)


@njit
def _eliminate(m: FloatArray, mean: FloatArray) -> tuple[FloatArray, float]:
    # pragma: no cover - compiled
    """Centre and ``r^2`` from the normal equations ``m = [A^T A | A^T b]`` of the rows ``u``.

    Gaussian elimination with partial pivoting (``m`` is overwritten).
    """
    dim = mean.shape[0]
    k = dim + 1
    for col in range(k):
        piv = col
        for r in range(col + 1, k):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if piv != col:
            for c in range(k + 1):
                tmp = m[col, c]
                m[col, c] = m[piv, c]
                m[piv, c] = tmp
        for r in range(col + 1, k):
            f = m[r, col] / m[col, col]
            for c in range(col, k + 1):
                m[r, c] -= f * m[col, c]
    x = np.zeros(k)
    for r in range(k - 1, -1, -1):
        acc = m[r, k]
        for c in range(r + 1, k):
            acc -= m[r, c] * x[c]
        x[r] = acc / m[r, r]
    centre = np.empty(dim)
    r2 = float(x[dim])
    for a in range(dim):
        r2 += x[a] * x[a]
        centre[a] = mean[a] + x[a]
    return centre, r2


@njit
def _solve_plane(p: FloatArray, keep: np.ndarray) -> tuple[FloatArray, float]:
    # pragma: no cover - compiled
    """:func:`_solve_kernel` for 2-D rows, its sums in scalars (the same order of operations)."""
    n = 0
    m0 = 0.0
    m1 = 0.0
    for i in range(p.shape[0]):
        if keep[i]:
            n += 1
            m0 += p[i, 0]
            m1 += p[i, 1]
    m0 /= n
    m1 /= n
    a00 = a01 = a02 = a11 = a12 = a22 = b0 = b1 = b2 = 0.0
    for i in range(p.shape[0]):
        if not keep[i]:
            continue
        u0 = p[i, 0] - m0
        u1 = p[i, 1] - m1
        r0 = 2.0 * u0
        r1 = 2.0 * u1
        bb = 0.0 + u0 * u0
        bb += u1 * u1
        a00 += r0 * r0
        a01 += r0 * r1
        a02 += r0
        b0 += r0 * bb
        a11 += r1 * r1
        a12 += r1
        b1 += r1 * bb
        a22 += 1.0
        b2 += bb
    m = np.array([[a00, a01, a02, b0], [a01, a11, a12, b1], [a02, a12, a22, b2]])
    mean = np.array([m0, m1])
    return _eliminate(m, mean)


@njit
def _gated_fit_kernel(p: FloatArray, gate_fraction: float, min_samples: int, passes: int
                      ) -> tuple[FloatArray, float, np.ndarray, bool]:
    """The fit, then up to ``passes`` refits on the samples within the gate of the latest.

    Each pass judges all samples (inliers a biased first fit dropped come back); it stops when
    fewer than ``min_samples`` would be kept or the kept set no longer changes in size. Returns
    ``(centre, r, kept rows, ok)``; ``ok`` false: a fit gave ``r^2 <= 0``.
    """
    n = p.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    c, r2 = _solve_kernel(p, keep)
    if not r2 > 0.0:
        return c, 0.0, keep, False
    r = math.sqrt(r2)
    n_used = n
    first = True
    for _ in range(passes):
        new = np.empty(n, dtype=np.bool_)
        n_new = 0
        for i in range(n):
            d2 = 0.0
            for a in range(p.shape[1]):
                d = p[i, a] - c[a]
                d2 += d * d
            new[i] = abs(math.sqrt(d2) - r) <= gate_fraction * r
            n_new += new[i]
        if n_new < min_samples or (n_used == n_new and not first):
            break
        keep = new
        n_used = n_new
        first = False
        c, r2 = _solve_kernel(p, keep)
        if not r2 > 0.0:
            return c, 0.0, keep, False
        r = math.sqrt(r2)
    return c, r, keep, True


@njit
def _spread_kernel(d: FloatArray) -> tuple[float, float]:
    """Angle covered by the 2-D vectors ``d`` (N, 2) around the origin, deg; their extent.

    The angle is 360 deg less the widest gap between neighbouring directions (the wrap-around
    gap included), found without sorting: N directions over a range R leave a gap of at least
    R / (N - 1), wider than each of N + 1 buckets of width R / N, so the widest gap lies between
    the largest direction of a bucket and the smallest of the next non-empty one (the bucket
    index never decreases with the direction). The extent is the largest range of one
    coordinate.
    """
    n = d.shape[0]
    ang = np.empty(n)
    lo, hi = math.inf, -math.inf
    for i in range(n):
        ang[i] = math.atan2(d[i, 1], d[i, 0])
        lo = min(lo, ang[i])
        hi = max(hi, ang[i])
    gap = lo + 2.0 * math.pi - hi
    if hi > lo:
        b_min = np.full(n + 1, math.inf)
        b_max = np.full(n + 1, -math.inf)
        scale = n / (hi - lo)
        for i in range(n):
            k = min(int((ang[i] - lo) * scale), n)
            b_min[k] = min(b_min[k], ang[i])
            b_max[k] = max(b_max[k], ang[i])
        prev = b_max[0]
        for k in range(1, n + 1):
            if b_min[k] <= b_max[k]:
                gap = max(gap, b_min[k] - prev)
                prev = b_max[k]
    extent = 0.0
    for a in range(d.shape[1]):
        extent = max(extent, d[:, a].max() - d[:, a].min())
    return 360.0 - math.degrees(gap), extent


@njit
def _fit_kernel(m: FloatArray, basis: FloatArray, gate_fraction: float, min_samples: int,
                passes: int) -> tuple[bool, FloatArray, float, float, FloatArray]:
    """Samples ``m`` (N, 3) projected on the rows of ``basis``, gated fit, residual.

    Returns ``(ok, c, r, residual, d)`` with the centre ``c`` in the projected coordinates and
    ``d`` the kept samples about it (``n_used`` rows); ``ok`` false: a fit gave ``r^2 <= 0``
    (the rest is then unset).
    """
    n, dim = m.shape[0], basis.shape[0]
    p = np.empty((n, dim))
    for i in range(n):
        for a in range(dim):
            p[i, a] = m[i, 0] * basis[a, 0] + m[i, 1] * basis[a, 1] + m[i, 2] * basis[a, 2]
    c, r, keep, ok = _gated_fit_kernel(p, gate_fraction, min_samples, passes)
    if not ok:
        return False, c, 0.0, math.nan, np.empty((0, dim))
    n_used = int(keep.sum())
    d = np.empty((n_used, dim))
    k = 0
    for i in range(n):
        if keep[i]:
            for a in range(dim):
                d[k, a] = p[i, a] - c[a]
            k += 1
    resid = 0.0
    for i in range(n_used):
        d2 = 0.0
        for a in range(dim):
            d2 += d[i, a] * d[i, a]
        resid += (math.sqrt(d2) - r) ** 2
    resid = math.sqrt(resid / n_used)
    return True, c, r, resid, d


@njit
def plane_basis_kernel(up_d: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """Rows (2, 3) spanning the plane perpendicular to ``up_d`` (finite, non-zero)."""
    up = up_d / math.sqrt(up_d[0] * up_d[0] + up_d[1] * up_d[1] + up_d[2] * up_d[2])
    axis = np.zeros(3)
    axis[np.argmin(np.abs(up))] = 1.0
    e1 = _cross3(up, axis)            # up x its least aligned axis
    e1 /= math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    e2 = _cross3(up, e1)
    out = np.empty((2, 3))
    for a in range(3):   # element by element: no numba shape-mismatch message to compile
        out[0, a] = e1[a]
        out[1, a] = e2[a]
    return out


@njit
def _cross3(a: FloatArray, b: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """``a x b`` of two 3-vectors."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@njit
def checked_fit_kernel(m: FloatArray, basis: FloatArray, gate_fraction: float,
                       min_samples: int, min_field_ut: float, min_arc_deg: float
                       ) -> tuple[int, FloatArray, float, float, float, float, int]:
    # pragma: no cover - compiled
    """:func:`_fit_kernel` on a plane ``basis`` (2, 3), coverage and the acceptance tests.

    Returns ``(code, c, r, residual, arc_deg, extent, n_used)``: ``code`` one of ``FIT_*``,
    ``c`` the offset in the device frame (``centre @ basis``, valid with ``FIT_OK``).
    """
    ok, cp, r, resid, d = _fit_kernel(m, basis, gate_fraction, min_samples, _GATE_PASSES)
    arc, extent = _spread_kernel(d) if ok else (math.nan, math.nan)
    return _accept_fit(ok, cp, basis, r, resid, arc, extent, d.shape[0], min_field_ut,
                      min_arc_deg)


@njit
def _accept_fit(ok: bool, cp: FloatArray, basis: FloatArray, r: float, resid: float, arc: float,
               extent: float, n_used: int, min_field_ut: float, min_arc_deg: float
               ) -> tuple[int, FloatArray, float, float, float, float, int]:
    # pragma: no cover - compiled
    """The acceptance tests of a fit: :func:`checked_fit_kernel`'s result from its parts."""
    c = np.zeros(3)
    if not ok:
        return FIT_FAILED, c, r, resid, arc, extent, n_used
    for j in range(3):
        for a in range(basis.shape[0]):
            c[j] += cp[a] * basis[a, j]
    # samples that hardly move (no turning) fit a small circle around their own noise
    code = (FIT_NARROW if r < min_field_ut or extent < r
            else FIT_SHORT_ARC if arc < min_arc_deg else FIT_OK)
    return code, c, r, resid, arc, extent, n_used


@njit
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


@njit
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
