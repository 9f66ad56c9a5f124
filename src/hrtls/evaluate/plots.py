"""PNG plots of an evaluation: trajectory over truth, error over time, error CDF.

Figures are drawn with matplotlib's object API on the Agg canvas (no global backend state,
no display needed).
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
from hrtls.evaluate.metrics import error_cdf

FloatArray = NDArray[np.float64]


def _save(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)
    return path


def plot_trajectory(path: Path, estimate: Trajectory, truth: GroundTruth | None = None, *,
                    checkpoints: Checkpoints | None = None,
                    landmarks: Mapping[str, Landmark] | None = None,
                    fixes_xy: FloatArray | None = None, title: str = "",
                    ellipses: int = 0) -> Path:
    """Top view (x east, y north, equal axes) of the estimate over the truth.

    ``ellipses`` > 0 draws that many 2-sigma ellipses of the horizontal covariance, evenly
    spaced in time along the estimate.
    """
    fig = Figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot()
    if truth is not None:
        ax.plot(truth.xyz[:, 0], truth.xyz[:, 1], "-", color="0.55", lw=2.0, label="truth")
    if fixes_xy is not None and len(fixes_xy):
        ax.plot(fixes_xy[:, 0], fixes_xy[:, 1], "x", color="tab:green", ms=4, label="fixes")
    ax.plot(estimate.xyz[:, 0], estimate.xyz[:, 1], "-", color="tab:blue", lw=1.0,
            label="estimate")
    ax.plot(estimate.xyz[:1, 0], estimate.xyz[:1, 1], "o", color="tab:blue", ms=6)
    if ellipses > 0 and len(estimate) > 1:
        _draw_ellipses(ax, estimate, ellipses)
    if checkpoints is not None and len(checkpoints):
        ax.plot(checkpoints.xyz[:, 0], checkpoints.xyz[:, 1], "D", mfc="none",
                color="tab:red", ms=7, label="checkpoints")
        seen = set()
        for lab, p in zip(checkpoints.label, checkpoints.xyz, strict=True):
            if lab not in seen:
                ax.annotate(str(lab), (p[0], p[1]), xytext=(4, 4), textcoords="offset points",
                            color="tab:red", fontsize=8)
                seen.add(lab)
    if landmarks:
        pts = np.array([lm.position for lm in landmarks.values() if lm.position is not None])
        if len(pts):
            ax.plot(pts[:, 0], pts[:, 1], "s", color="tab:orange", ms=5, label="landmarks")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or "trajectory")
    fig.tight_layout()
    return _save(fig, path)


def _draw_ellipses(ax: Axes, estimate: Trajectory, count: int) -> None:
    """2-sigma ellipses of ``cov_xy`` at ``count`` evenly spaced times."""
    idx = np.unique(np.searchsorted(estimate.t, np.linspace(estimate.t[0], estimate.t[-1],
                                                            count)).clip(0, len(estimate) - 1))
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 48)),
                       np.sin(np.linspace(0, 2 * np.pi, 48))])
    for k, i in enumerate(idx):
        vals, vecs = np.linalg.eigh(estimate.cov_xy[i])
        axes = vecs @ np.diag(2.0 * np.sqrt(np.clip(vals, 0.0, None))) @ circle
        ax.plot(estimate.xyz[i, 0] + axes[0], estimate.xyz[i, 1] + axes[1], "-",
                color="tab:blue", alpha=0.35, lw=0.8, label="2-sigma" if k == 0 else None)


def plot_error_over_time(path: Path, t: FloatArray, error_m: FloatArray, *,
                         checkpoint_t: FloatArray | None = None,
                         checkpoint_error_m: FloatArray | None = None,
                         title: str = "") -> Path:
    """Horizontal position error against time, with checkpoint errors as markers."""
    fig = Figure(figsize=(8.0, 3.6))
    ax = fig.add_subplot()
    if len(t):
        ax.plot(t, error_m, "-", color="tab:blue", lw=1.0, label="vs continuous truth")
    if checkpoint_t is not None and checkpoint_error_m is not None and len(checkpoint_t):
        ax.plot(checkpoint_t, checkpoint_error_m, "D", color="tab:red", ms=5,
                label="at checkpoints")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [m]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title or "position error")
    fig.tight_layout()
    return _save(fig, path)


def plot_cdf(path: Path, errors: Mapping[str, FloatArray], *, title: str = "") -> Path:
    """Empirical CDFs of one or more error sets (Tarrio Fig. 1 style)."""
    fig = Figure(figsize=(6.0, 4.2))
    ax = fig.add_subplot()
    for label, e in errors.items():
        x, p = error_cdf(e)
        if x.size:
            ax.step(np.concatenate([[0.0], x]), np.concatenate([[0.0], p]), where="post",
                    label=label)
    ax.axhline(0.9, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("position error [m]")
    ax.set_ylabel("fraction of samples")
    ax.set_ylim(0.0, 1.0)
    ax.set_xlim(left=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title or "error CDF")
    fig.tight_layout()
    return _save(fig, path)
