"""Offline forward-backward smoother of the grid filter's position density.

The forward pass (:func:`hrtls.fusion.rss_grid.grid_kernel` with ``kept`` / ``moved``) keeps,
for every scan ``k``, the filtered density ``f_k = p(x_k | y_1:k)`` and the transition it
applied from scan ``k - 1``: the shift ``S_k`` by its own persistent velocity times ``dt_k``
(bilinear, mass leaving the grid dropped), then the Gaussian blur ``B_k`` of standard deviation
``sigma_speed_m_per_sqrt_s sqrt(dt_k)`` (symmetric, truncated at 3 sigma). The backward pass
(the discrete-state Rauch-Tung-Striebel recursion) is, from ``s_N = f_N`` down:

* eq. 1: ``p_{k+1} = B_{k+1} S_{k+1} f_k`` (the forward prediction, recomputed from ``f_k``);
* eq. 2: ``s_k = f_k * S_{k+1}^T B_{k+1} [s_{k+1} / p_{k+1}]`` (cell-wise product and ratio,
  zero where ``p_{k+1}`` is), normalised to sum 1.

The forward pass renormalises after the shift and the blur; those scalars cancel in eq. 2.
``S^T`` gathers each cell's bilinear destinations
(:func:`~hrtls.fusion.rss_grid_kernels.shift_adjoint`); ``B`` is its own transpose. Each row
is the mean and covariance of ``s_k`` (or, with ``point_estimate = "median"``, its per-axis
median and the spread about it), as the forward pass's rows are of ``f_k``.

Exact for one velocity mode only: with modes each mode's mass is renormalised on its own after
its move (a per-mode scalar) and the modes mix, so :func:`check_smoothable` refuses them. The
per-anchor bias and burst states and the persistent velocity stay the forward pass's (each
scan's likelihood is the one the forward pass applied): the smoother refines the position.

Memory: one float32 density per scan, ``4 nx ny`` bytes: at :class:`GridParams` ``max_cells``
(40 000 cells) and 0.5 s scans, 1.15 GB per hour of recording; a recording that needs more than
:data:`MAX_KEPT_BYTES` is refused (:meth:`GridRecord.new`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray
from hrtls.fusion.rss_grid import GridGeometry, GridParams, GridRows
from hrtls.fusion.rss_grid_kernels import blur, median_row, moments, shift, shift_adjoint
from hrtls.kernels import njit

__all__ = ["MAX_KEPT_BYTES", "FixedLag", "GridRecord", "backward_kernel", "backward_step",
           "check_smoothable", "fixed_lag_kernel", "smooth_rows"]

MAX_KEPT_BYTES = 2 ** 30
"""Most bytes of kept densities (1 GiB: about 56 min at 40 000 cells and 0.5 s scans)."""
WHERE = "[offline] grid_smoother"


@njit(cache=True, error_model="numpy")
def backward_step(filtered: FloatArray, move: FloatArray, cell: float,
                  sigma_m_per_sqrt_s: float, smooth: FloatArray, pred: FloatArray,
                  tmp: FloatArray) -> None:   # pragma: no cover - compiled
    """``smooth`` (ny, nx): ``s_{k+1}`` in, ``s_k`` out (eq. 1-2), in place.

    ``filtered``: ``f_k``; ``move``: v x, v y (m/s) and dt (s) of scan ``k + 1``'s prediction.
    ``pred``, ``tmp``: (ny, nx) work arrays.
    """
    sx, sy = move[0] * move[2] / cell, move[1] * move[2] / cell
    spread = sigma_m_per_sqrt_s * math.sqrt(move[2]) / cell
    ny, nx = smooth.shape
    pred[:] = filtered
    shift(pred, sx, sy, tmp)                        # eq. 1
    blur(pred, spread, tmp)
    for i in range(ny):
        for j in range(nx):
            smooth[i, j] = smooth[i, j] / pred[i, j] if pred[i, j] > 0.0 else 0.0
    blur(smooth, spread, tmp)                       # eq. 2: B^T = B, then S^T
    shift_adjoint(smooth, sx, sy, tmp)
    total = 0.0
    for i in range(ny):
        for j in range(nx):
            smooth[i, j] *= filtered[i, j]
            total += smooth[i, j]
    if total > 0.0:
        smooth /= total
    else:                                           # a restart of the forward pass
        smooth[:] = filtered


@njit(cache=True, error_model="numpy")
def backward_kernel(kept: FloatArray, moved: FloatArray, x0: float, y0: float, cell: float,
                    sigma_m_per_sqrt_s: float, median_point: bool, out: FloatArray) -> None:
    # pragma: no cover - compiled
    """Rows of the smoothed densities (module docstring, eq. 1-2) into ``out`` (S, 5).

    ``kept`` (S, ny, nx): filtered densities, overwritten by the smoothed ones; ``moved``
    (S, 3): the persistent velocity (m/s) and dt (s) of each scan's prediction (row 0 unused);
    ``out``: mean x, y, covariance xx, xy, yy.
    """
    n, ny, nx = kept.shape
    smooth = kept[n - 1].astype(np.float64)
    pred = np.empty((ny, nx))
    tmp = np.empty((ny, nx))
    for k in range(n - 1, -1, -1):
        if k < n - 1:
            backward_step(kept[k], moved[k + 1], cell, sigma_m_per_sqrt_s, smooth, pred, tmp)
            kept[k] = smooth
        moments(smooth, x0, y0, cell, out[k])
        if median_point:
            median_row(smooth, x0, y0, cell, out[k])


@njit(cache=True, error_model="numpy")
def fixed_lag_kernel(kept: FloatArray, moved: FloatArray, t: FloatArray, lag_s: float,
                     x0: float, y0: float, cell: float, sigma_m_per_sqrt_s: float,
                     median_point: bool, out: FloatArray) -> None:
    # pragma: no cover - compiled
    """Rows ``out`` (R, 5) of scans 0 ... R - 1, each smoothed over the scans up to ``lag_s``.

    Scan ``r``'s row: eq. 1-2 from the last scan at most ``lag_s`` after it down to ``r``;
    ``kept``, ``moved``, ``t``: (S, ...) as :func:`backward_kernel`'s, ``t`` in s.
    """
    n, ny, nx = kept.shape
    smooth = np.empty((ny, nx))
    pred = np.empty((ny, nx))
    tmp = np.empty((ny, nx))
    for r in range(out.shape[0]):
        m = r
        while m + 1 < n and t[m + 1] <= t[r] + lag_s:
            m += 1
        smooth[:] = kept[m]
        for k in range(m - 1, r - 1, -1):
            backward_step(kept[k], moved[k + 1], cell, sigma_m_per_sqrt_s, smooth, pred, tmp)
        moments(smooth, x0, y0, cell, out[r])
        if median_point:
            median_row(smooth, x0, y0, cell, out[r])


def check_smoothable(params: GridParams, *, where: str = WHERE) -> None:
    """Refuse settings the backward pass cannot undo exactly (velocity modes)."""
    if params.n_modes > 1:
        raise InputError(f"{params.n_modes} velocity modes (mode_turn_deg = "
                         f"{params.mode_turn_deg}, stopped_mode = {params.stopped_mode})",
                         where=where, expected="one velocity mode ([prediction.grid] "
                         "mode_turn_deg = 0 and stopped_mode = false)")


def _rows(t: FloatArray, out: FloatArray) -> GridRows:
    """:class:`GridRows` at ``t`` of kernel rows ``out`` (mean x, y, covariance xx, xy, yy)."""
    n = len(out)
    cov = np.stack([out[:, 2], out[:, 3], out[:, 3], out[:, 4]], axis=1).reshape(n, 2, 2)
    return GridRows(np.asarray(t, dtype=np.float64).copy(), out[:, :2].copy(), cov)


def smooth_rows(t: FloatArray, kept: np.ndarray, moved: FloatArray, *,
                geometry: GridGeometry, params: GridParams) -> GridRows:
    """Rows at ``t`` (S,) of the smoothed densities (``kept``, ``moved``: module docstring).

    ``kept``, when float32 and C-contiguous, is overwritten by the smoothed densities.
    """
    check_smoothable(params)
    n = len(t)
    if kept.shape != (n, geometry.ny, geometry.nx) or moved.shape != (n, 3):
        raise InputError(f"kept {kept.shape}, moved {moved.shape} for {n} scans", where=WHERE,
                         expected=f"({n}, {geometry.ny}, {geometry.nx}) and ({n}, 3)")
    out = np.zeros((n, 5))
    if n:
        backward_kernel(np.ascontiguousarray(kept, dtype=np.float32),
                        np.ascontiguousarray(moved, dtype=np.float64), geometry.x0_m,
                        geometry.y0_m, geometry.cell_m, params.sigma_speed_m_per_sqrt_s,
                        params.point_estimate == "median", out)
    return _rows(t, out)


@dataclass(slots=True, eq=False)
class GridRecord:
    """The forward pass's kept densities and moves, one block per filter call."""

    kept: list[np.ndarray] = field(default_factory=list)
    moved: list[FloatArray] = field(default_factory=list)
    max_bytes: int = MAX_KEPT_BYTES

    def new(self, n_scans: int, geometry: GridGeometry) -> tuple[np.ndarray, FloatArray]:
        """Arrays for the next ``n_scans`` scans (kept here), refused beyond ``max_bytes``."""
        size = 4 * geometry.nx * geometry.ny
        total = size * (sum(len(k) for k in self.kept) + n_scans)
        if total > self.max_bytes:
            raise InputError(f"{total / 1e9:.2f} GB of densities ({total // size} scans of "
                             f"{geometry.nx * geometry.ny} cells)", where=WHERE,
                             expected=f"at most {self.max_bytes / 1e9:.2f} GB: a shorter "
                             "recording or larger [prediction.grid] cell_m")
        kept = np.zeros((n_scans, geometry.ny, geometry.nx), dtype=np.float32)
        moved = np.zeros((n_scans, 3))
        self.kept.append(kept)
        self.moved.append(moved)
        return kept, moved

    def smooth(self, t: FloatArray, *, geometry: GridGeometry, params: GridParams) -> GridRows:
        """:func:`smooth_rows` of every scan kept, at their times ``t``."""
        empty = np.zeros((0, geometry.ny, geometry.nx), dtype=np.float32)
        kept = np.concatenate(self.kept) if self.kept else empty
        moved = np.concatenate(self.moved) if self.moved else np.zeros((0, 3))
        return smooth_rows(t, kept, moved, geometry=geometry, params=params)


@dataclass(slots=True, eq=False)
class FixedLag:
    """Fixed-lag smoother (``[prediction.grid] smoother_lag_s``): causal, ``lag_s`` late.

    The row of a scan is out once a scan more than ``lag_s`` after it has been filtered (or at
    :meth:`flush`), smoothed over the scans up to ``lag_s`` after it (:func:`fixed_lag_kernel`),
    so chunks give the rows of one call. State (snapshot): the scans whose rows are not out yet,
    ``t`` (B,), ``kept`` (B, ny, nx) float32 filtered densities, ``moved`` (B, 3).
    """

    lag_s: float
    t: FloatArray
    kept: np.ndarray
    moved: FloatArray

    @classmethod
    def empty(cls, geometry: GridGeometry, *, lag_s: float) -> FixedLag:
        """No scan yet."""
        return cls(lag_s, np.zeros(0), np.zeros((0, geometry.ny, geometry.nx), np.float32),
                   np.zeros((0, 3)))

    def push(self, t: FloatArray, kept: np.ndarray, moved: FloatArray, *,
             geometry: GridGeometry, params: GridParams, final: bool = False) -> GridRows:
        """Add a filter call's scans; the rows out now (every pending one if ``final``).

        ``t`` (n,): the scans' times, s; ``kept``, ``moved``: as :func:`grid_kernel` filled them.
        """
        self.t = np.concatenate([self.t, np.asarray(t, dtype=np.float64)])
        self.kept = np.concatenate([self.kept, kept.astype(np.float32)])
        self.moved = np.concatenate([self.moved, moved])
        n = len(self.t) if final or not len(self.t) else \
            int(np.searchsorted(self.t, self.t[-1] - self.lag_s, side="left"))
        out = np.zeros((n, 5))
        if n:
            fixed_lag_kernel(self.kept, self.moved, self.t, self.lag_s, geometry.x0_m,
                             geometry.y0_m, geometry.cell_m, params.sigma_speed_m_per_sqrt_s,
                             params.point_estimate == "median", out)
        rows = _rows(self.t[:n], out)
        self.t, self.kept, self.moved = self.t[n:], self.kept[n:], self.moved[n:]
        return rows

    def flush(self, *, geometry: GridGeometry, params: GridParams) -> GridRows:
        """The rows of every pending scan (end of the recording)."""
        return self.push(np.zeros(0), self.kept[:0], self.moved[:0], geometry=geometry,
                         params=params, final=True)
