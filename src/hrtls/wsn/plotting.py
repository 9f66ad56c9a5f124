"""Figures in the style of the thesis' network plots (Fig. 6.11-6.17); used by the CLI only.

Seeds/anchors magenta squares, trilateration nodes green stars, shadow-edge nodes red circles
with their shadow edges as red dashed lines, agent-assigned nodes blue filled circles,
unlocalized nodes hollow blue circles, links light grey, the agent path black with way points as
black triangles and the agent's links as dashed cyan lines. Uncertainty is drawn as 2-sigma
ellipses: a node's covariance when one is given (least-squares refinement), otherwise the circle
of its propagated position sigma; the agent's temporary nodes get the circle of the agent's own
position sigma at the way point. The legend sits outside the axes so it hides no node.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse
from numpy.typing import NDArray

from hrtls.wsn._propagation import (
    M_AGENT,
    M_ANCHOR,
    M_SHADOW,
    M_TRILATERATION,
    M_UNLOCALIZED,
)
from hrtls.wsn.network import Network
from hrtls.wsn.trilateration import Localization

FloatArray = NDArray[np.float64]


def plot_network(
    net: Network,
    loc: Localization | None = None,
    *,
    title: str = "",
    agent_path_m: FloatArray | None = None,
    waypoints_m: FloatArray | None = None,
    agent_links: list[tuple[int, int, float]] | None = None,
    labels: bool = False,
    covariance_m2: FloatArray | None = None,
) -> Figure:
    """Draw a network with its localization state; returns the matplotlib figure.

    ``covariance_m2`` (``(n, 2, 2)``, m^2) are the nodes' position covariances; without it the
    isotropic ``loc.sigma_m`` is drawn.
    """
    fig, ax = plt.subplots(figsize=(8.5, 6.5))
    n = net.n_nodes
    if loc is not None:
        pos = np.where(loc.localized[:n, None], loc.estimate_m[:n], net.position_m)
        meth = loc.method[:n]
    else:
        pos = net.position_m
        meth = np.where(net.anchor, M_ANCHOR, M_UNLOCALIZED)
    shown = net.has_position | (meth != M_UNLOCALIZED)
    for i, j in net.edges:
        if shown[i] and shown[j]:
            ax.plot(pos[[i, j], 0], pos[[i, j], 1], color="0.85", lw=0.6, zorder=1)
    if loc is not None:
        for i, w in loc.shadow_edges:
            if i < n and w < loc.estimate_m.shape[0]:
                q = loc.estimate_m[[i, w]]
                ax.plot(q[:, 0], q[:, 1], color="red", lw=1.0, ls="--", zorder=2)
    style = {
        M_ANCHOR: {"marker": "s", "color": "magenta", "label": "seed / anchor", "s": 60},
        M_TRILATERATION: {"marker": "*", "color": "green", "label": "trilateration", "s": 80},
        M_SHADOW: {"marker": "o", "color": "red", "label": "shadow edge", "s": 45},
        M_AGENT: {"marker": "o", "color": "tab:blue", "label": "agent", "s": 45},
    }
    for code, st in style.items():
        m = (meth == code) & shown
        if m.any():
            ax.scatter(pos[m, 0], pos[m, 1], zorder=3, **st)  # type: ignore[arg-type]
    m = (meth == M_UNLOCALIZED) & shown
    if m.any():
        ax.scatter(pos[m, 0], pos[m, 1], facecolors="none", edgecolors="tab:blue", s=45,
                   zorder=3, label="unlocalized (true position)")
    if agent_links and waypoints_m is not None:
        for t, k, _ in agent_links:
            if shown[k] and t < len(waypoints_m):
                q = np.vstack([waypoints_m[t], pos[k]])
                ax.plot(q[:, 0], q[:, 1], color="cyan", lw=0.8, ls="--", zorder=2)
    if agent_path_m is not None and len(agent_path_m):
        ax.plot(agent_path_m[:, 0], agent_path_m[:, 1], color="black", lw=0.8, zorder=2,
                label="agent path")
    if waypoints_m is not None and len(waypoints_m):
        ax.scatter(waypoints_m[:, 0], waypoints_m[:, 1], marker="^", color="black", s=50,
                   zorder=4, label="agent way points")
    if loc is not None:
        _uncertainty(ax, pos, loc, covariance_m2, waypoints_m, n)
    if labels:
        for i in range(n):
            if shown[i]:
                ax.annotate(str(i), pos[i], fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
    ax.set_aspect("equal")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, framealpha=0.8,
              borderaxespad=0.0)
    fig.tight_layout()
    return fig


def _ellipse(ax: Axes, centre: FloatArray, cov: FloatArray, color: str, label: str | None) -> None:
    """2-sigma ellipse of a 2x2 covariance."""
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    w = np.maximum(w, 0.0)
    angle = float(np.degrees(np.arctan2(v[1, 1], v[0, 1])))
    ax.add_patch(Ellipse((float(centre[0]), float(centre[1])), 4.0 * np.sqrt(w[1]),
                         4.0 * np.sqrt(w[0]), angle=angle, fill=False, color=color, lw=0.7,
                         zorder=2, label=label))


def _uncertainty(ax: Axes, pos: FloatArray, loc: Localization, cov: FloatArray | None,
                 waypoints_m: FloatArray | None, n: int) -> None:
    sig = loc.sigma_m
    first = True
    for i in np.flatnonzero(loc.localized[:n]):
        c = cov[i] if cov is not None else np.eye(2) * float(sig[i]) ** 2
        if np.all(np.isfinite(c)) and np.trace(c) > 0.0:
            _ellipse(ax, pos[i], c, "tab:purple", "node 2-sigma" if first else None)
            first = False
    if waypoints_m is None:
        return
    first = True
    for k in range(min(len(waypoints_m), sig.size - n)):
        s = float(sig[n + k])
        if np.isfinite(s) and s > 0.0:
            _ellipse(ax, waypoints_m[k], np.eye(2) * s * s, "0.3",
                     "agent 2-sigma" if first else None)
            first = False


def save_figure(fig: Figure, path: str | Path) -> None:
    """Write a figure as PNG and close it."""
    fig.savefig(str(path), dpi=120)
    plt.close(fig)
