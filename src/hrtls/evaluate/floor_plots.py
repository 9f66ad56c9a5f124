"""The track plot of ``hrtls track``: one panel per floor, start and end, checkpoint errors.

Floors are ``round(z / floor_height)`` of the estimate (and of the truth for its own line).
Every panel has the same axes, fitted to the estimate, the truth and the checkpoints with a
margin; each checkpoint is joined to the estimate at its time (the error drawn) and labelled
with its error; labels are pushed apart so that they do not overlap.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from hrtls.data import Checkpoints, GroundTruth, Landmark, Trajectory
from hrtls.fusion.floors import floor_index

FloatArray = NDArray[np.float64]


def _masked(xy: FloatArray, keep: NDArray[np.bool_]) -> FloatArray:
    """``xy`` with rows outside ``keep`` as NaN (lines break instead of jumping)."""
    out = np.array(xy, dtype=np.float64, copy=True)
    out[~keep] = np.nan
    return out


def _limits(points: list[FloatArray]) -> tuple[tuple[float, float], tuple[float, float]]:
    xy = np.vstack([p[:, :2] for p in points if len(p)])
    lo, hi = np.nanmin(xy, axis=0), np.nanmax(xy, axis=0)
    margin = 0.06 * float(max(hi - lo)) + 0.5
    return (lo[0] - margin, hi[0] + margin), (lo[1] - margin, hi[1] + margin)


def spread_labels(xy: FloatArray, *, min_distance: float) -> FloatArray:
    """Label positions near ``xy`` at least ``min_distance`` apart (greedy, in order)."""
    placed: list[FloatArray] = []
    angles = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    for p in np.asarray(xy, dtype=np.float64):
        best = p + np.array([0.0, 0.6 * min_distance])
        for ring in (0.6, 1.2, 2.0, 3.0):
            candidates = p + ring * min_distance * np.column_stack([np.sin(angles),
                                                                    np.cos(angles)])
            ok = [c for c in candidates
                  if all(np.hypot(*(c - q)) >= min_distance for q in placed)]
            if ok:
                best = ok[0]
                break
        placed.append(best)
    return np.array(placed).reshape(-1, 2)


def plot_track_by_floor(path: Path, estimate: Trajectory, truth: GroundTruth | None = None, *,
                        floor_height_m: float, checkpoints: Checkpoints | None = None,
                        landmarks: Mapping[str, Landmark] | None = None,
                        fixes_xy: FloatArray | None = None, title: str = "",
                        ellipses: int = 0) -> Path:
    """:func:`track_figure` as a PNG at ``path``."""
    fig = track_figure(estimate, truth, floor_height_m=floor_height_m, checkpoints=checkpoints,
                       landmarks=landmarks, fixes_xy=fixes_xy, title=title, ellipses=ellipses)
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)
    return path


def track_figure(estimate: Trajectory, truth: GroundTruth | None = None, *,
                 floor_height_m: float, checkpoints: Checkpoints | None = None,
                 landmarks: Mapping[str, Landmark] | None = None,
                 fixes_xy: FloatArray | None = None, title: str = "",
                 ellipses: int = 0) -> Figure:
    """Top views, one per floor the estimate or the truth visits (highest floor first)."""
    est_floor = floor_index(estimate.xyz[:, 2], floor_height_m)
    true_floor = None if truth is None else floor_index(truth.xyz[:, 2], floor_height_m)
    floors = sorted({int(f) for f in est_floor} | (
        set() if true_floor is None else {int(f) for f in true_floor}))
    if not floors:
        floors = [0]
    n = len(floors)
    fig = Figure(figsize=(7.0 * min(n, 3), 6.2 * ((n + 2) // 3)))
    limits = _limits([estimate.xyz, *([] if truth is None else [truth.xyz]),
                      *([] if checkpoints is None else [checkpoints.xyz])])
    cp_est = None if checkpoints is None or len(estimate) == 0 else estimate.position_at(
        checkpoints.t)
    cp_floor = None if checkpoints is None else floor_index(checkpoints.xyz[:, 2],
                                                            floor_height_m)
    for k, floor in enumerate(reversed(floors)):
        ax = fig.add_subplot((n + 2) // 3, min(n, 3), k + 1)
        _panel(ax, floor, estimate, est_floor, truth, true_floor, checkpoints, cp_est, cp_floor,
               landmarks, fixes_xy, ellipses, limits)
        ax.set_title(f"{title or 'track'}: floor {floor}" if n > 1 else (title or "track"))
    fig.tight_layout()
    return fig


def _panel(ax: Axes, floor: int, estimate: Trajectory, est_floor: NDArray[np.int64],
           truth: GroundTruth | None, true_floor: NDArray[np.int64] | None,
           checkpoints: Checkpoints | None, cp_est: FloatArray | None,
           cp_floor: NDArray[np.int64] | None, landmarks: Mapping[str, Landmark] | None,
           fixes_xy: FloatArray | None, ellipses: int,
           limits: tuple[tuple[float, float], tuple[float, float]]) -> None:
    if truth is not None and true_floor is not None:
        xy = _masked(truth.xyz[:, :2], true_floor == floor)
        ax.plot(xy[:, 0], xy[:, 1], "-", color="0.6", lw=2.0, label="truth")
    if fixes_xy is not None and len(fixes_xy):
        ax.plot(fixes_xy[:, 0], fixes_xy[:, 1], "x", color="tab:green", ms=4, label="fixes")
    on = est_floor == floor
    xy = _masked(estimate.xyz[:, :2], on)
    ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:blue", lw=1.0, label="estimate")
    if ellipses > 0 and np.any(on):
        _ellipses(ax, estimate, on, ellipses)
    if len(estimate) and on[0]:
        ax.plot(*estimate.xyz[0, :2], "o", color="tab:green", ms=9, label="start")
    if len(estimate) and on[-1]:
        ax.plot(*estimate.xyz[-1, :2], "s", color="tab:red", ms=8, label="end")
    if checkpoints is not None and cp_est is not None and cp_floor is not None:
        here = cp_floor == floor
        if np.any(here):
            cp = checkpoints.xyz[here]
            est = cp_est[here]
            for a, b in zip(cp, est, strict=True):
                ax.plot([a[0], b[0]], [a[1], b[1]], "-", color="tab:red", lw=0.8, alpha=0.7)
            ax.plot(cp[:, 0], cp[:, 1], "D", mfc="none", color="tab:red", ms=7,
                    label="checkpoints (error drawn)")
            span = max(limits[0][1] - limits[0][0], limits[1][1] - limits[1][0])
            labels = spread_labels(cp[:, :2], min_distance=0.045 * span)
            errors = np.hypot(*(cp[:, :2] - est[:, :2]).T)
            for text, p, q, e in zip(checkpoints.label[here], cp, labels, errors, strict=True):
                ax.annotate(f"{text} {e:.1f} m", (p[0], p[1]), xytext=(q[0], q[1]),
                            textcoords="data", color="tab:red", fontsize=7,
                            arrowprops={"arrowstyle": "-", "color": "tab:red", "lw": 0.4})
    if landmarks:
        pts = np.array([lm.position for lm in landmarks.values() if lm.position is not None])
        if len(pts):
            ax.plot(pts[:, 0], pts[:, 1], "s", color="tab:orange", ms=5, label="landmarks")
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=7)


def _ellipses(ax: Axes, estimate: Trajectory, on: NDArray[np.bool_], count: int) -> None:
    idx = np.flatnonzero(on)
    pick = idx[np.unique(np.linspace(0, len(idx) - 1, count).round().astype(int))]
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 48)),
                       np.sin(np.linspace(0, 2 * np.pi, 48))])
    for k, i in enumerate(pick):
        vals, vecs = np.linalg.eigh(estimate.cov_xy[i])
        axes = vecs @ np.diag(2.0 * np.sqrt(np.clip(vals, 0.0, None))) @ circle
        ax.plot(estimate.xyz[i, 0] + axes[0], estimate.xyz[i, 1] + axes[1], "-",
                color="tab:blue", alpha=0.35, lw=0.8, label="2-sigma" if k == 0 else None)
