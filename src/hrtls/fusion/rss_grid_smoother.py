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

__all__ = ["MAX_KEPT_BYTES", "GridRecord", "backward_kernel", "check_smoothable",
           "smooth_rows"]

MAX_KEPT_BYTES = 2 ** 30
"""Most bytes of kept densities (1 GiB: about 53 min at 40 000 cells and 0.5 s scans)."""
WHERE = "[offline] grid_smoother"


@njit(cache=True, error_model="numpy")
def backward_kernel(kept: FloatArray, moved: FloatArray, x0: float, y0: float, cell: float,
                    sigma_m_per_sqrt_s: float, median_point: bool, out: FloatArray) -> None:
    # pragma: no cover - compiled
    """Rows of the smoothed densities (module docstring, eq. 1-2) into ``out`` (S, 5).

    ``kept`` (S, ny, nx): filtered densities; ``moved`` (S, 3): the persistent velocity (m/s)
    and dt (s) of each scan's prediction (row 0 unused); ``out``: mean x, y, covariance xx,
    xy, yy.
    """
    n, ny, nx = kept.shape
    smooth = kept[n - 1].astype(np.float64)
    pred = np.empty((ny, nx))
    tmp = np.empty((ny, nx))
    moments(smooth, x0, y0, cell, out[n - 1])
    if median_point:
        median_row(smooth, x0, y0, cell, out[n - 1])
    for k in range(n - 2, -1, -1):
        sx, sy = moved[k + 1, 0] * moved[k + 1, 2] / cell, moved[k + 1, 1] * moved[k + 1, 2] / cell
        spread = sigma_m_per_sqrt_s * math.sqrt(moved[k + 1, 2]) / cell
        pred[:] = kept[k]
        shift(pred, sx, sy, tmp)                    # eq. 1
        blur(pred, spread, tmp)
        for i in range(ny):
            for j in range(nx):
                smooth[i, j] = smooth[i, j] / pred[i, j] if pred[i, j] > 0.0 else 0.0
        blur(smooth, spread, tmp)                   # eq. 2: B^T = B, then S^T
        shift_adjoint(smooth, sx, sy, tmp)
        total = 0.0
        for i in range(ny):
            for j in range(nx):
                smooth[i, j] *= kept[k, i, j]
                total += smooth[i, j]
        if total > 0.0:
            smooth /= total
        else:                                       # a restart of the forward pass
            smooth[:] = kept[k]
        moments(smooth, x0, y0, cell, out[k])
        if median_point:
            median_row(smooth, x0, y0, cell, out[k])


def check_smoothable(params: GridParams) -> None:
    """Refuse settings the backward pass cannot undo exactly (velocity modes)."""
    if params.n_modes > 1:
        raise InputError(f"{params.n_modes} velocity modes (mode_turn_deg = "
                         f"{params.mode_turn_deg}, stopped_mode = {params.stopped_mode})",
                         where=WHERE, expected="one velocity mode ([prediction.grid] "
                         "mode_turn_deg = 0 and stopped_mode = false)")


def smooth_rows(t: FloatArray, kept: np.ndarray, moved: FloatArray, *,
                geometry: GridGeometry, params: GridParams) -> GridRows:
    """Rows at ``t`` (S,) of the smoothed densities (``kept``, ``moved``: module docstring)."""
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
    cov = np.stack([out[:, 2], out[:, 3], out[:, 3], out[:, 4]], axis=1).reshape(n, 2, 2)
    return GridRows(np.asarray(t, dtype=np.float64).copy(), out[:, :2].copy(), cov)


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
