"""Node readings at a rescuer's smoothed positions (fixed-lag, causal; opt-in).

A reading of a node is stored with its agent's *filtered* estimate at the reading's time
(:mod:`hrtls.mission.readings`). When a later correction (a tag fix) moves the agent, the
positions it had since the previous correction were wrong by about the same error; a
Rauch-Tung-Striebel pass over the agent's rows carries the correction back. With
``MissionParams.smooth_readings_s = L > 0`` the mission keeps each rescuer's rows of the last
``L`` seconds (its tracker's output: time, horizontal position and covariance, and whether the
row is a correction), smooths them after every window in which a correction or a reading
arrived, and places the agent's readings of that span at the smoothed positions with the
smoothed covariances; a node whose readings moved is estimated again. The agent's own tracker is
untouched (its live estimate stays the filtered one); the smoother reads only rows up to the
processed window (causal), so its result is a fixed-lag smoother of lag ``L``.

Model (position only). The rows carry the filter's horizontal position ``x_k`` and covariance
``P_k`` but not its position-heading cross-covariance, so the step model is taken as
``x_{k+1} = x_k + u_k + w_k`` (``F = I``). A row between corrections is a pure prediction: its
predicted values are its filtered ones, ``x^-_{k+1} = x_{k+1}``, ``P^-_{k+1} = P_{k+1}``. A
correction has a row of its own at its time (the tracker writes one per fix, tag, RSS, range or
heading update, ``since_correction_s`` 0) whose prior is the previous row:
``x^-_{k+1} = x_k``, ``P^-_{k+1} = P_k``. The backward pass, from the latest row
(``x^s_n = x_n``, ``P^s_n = P_n``; ``[.]+`` the positive semi-definite part):

    G_k = P_k (P_k + Q_k)^-1,  Q_k = [P^-_{k+1} - P_k]+
    x^s_k = x_k + G_k (x^s_{k+1} - x^-_{k+1})
    P^s_k = [P_k - G_k [P^-_{k+1} - P^s_{k+1}]+ G_k^T]+

For a random walk ``P^-_{k+1} = P_k + Q_k`` and this is the exact RTS smoother; with the
heading in the filter's state the position block can shrink along one axis between
corrections, and ``Q_k >= 0`` keeps the gains at most one. A correction row has ``Q_k = 0``,
``G_k = I``: the row before it takes the smoothed value at the correction. Rows after the
latest correction are unchanged (zero innovations, ``P^s = P``). Over a stretch of random-walk
predictions ``a < k < c`` ending in a correction the gains telescope:
``x^s_k = x_k + P_k (P^-_c)^-1 (x_c - x^-_c)`` and
``P^s_k = P_k - P_k (P^-_c)^-1 (P^-_c - P_c) (P^-_c)^-1 P_k``. In one dimension, a random walk of
step variance ``q`` from an exact fix at 0 to an exact fix at ``n`` gives the Brownian bridge,
``P^s_k = q k (n - k) / n``.

What changes for the node estimator (:mod:`hrtls.mission.nodes`). Its pass offsets are a random
walk per agent, ``b_j = b_{j-1} + w_j``, ``D_j = [P_j - S_{j-1}]+``. The smoothed errors are a
backward Markov sequence instead, ``e^s_k = G_k e^s_{k+1} + v_k`` with ``v_k`` independent of
``e^s_{k+1}``, so two readings ``i < j`` of one stretch have
``cov(e^s_i, e^s_j) = P_i P_j^-1 P^s_j`` (``F = I``): the correlation of two passes falls to 0
across an exact fix instead of being carried on. With ``P_j = P^s_j`` the estimator's prior
``S_j >= P^s_j`` stays conservative: where ``P^s`` falls (the second half of a stretch)
``D_j = 0`` and a pass keeps the earlier pass's offset and its larger prior ``S_{j-1}``; where
it grows the walk adds the growth. The drift within a pass (:func:`~hrtls.mission.nodes.
drift_variance`) is the growth of ``P^s`` away from the pass's middle reading: 0 where ``P^s``
falls, while the true spread there is ``var(e^s_j - e^s_i) = P^s_i + P^s_j - 2 P_i P_j^-1 P^s_j``
(under-modelled; the pass inflation and ``agent_cov_scale`` cover it in part).
Robots are not smoothed (their range updates share rows with odometry steps, so the rows do
not hold a correction's prior).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hrtls.kernels import njit
from hrtls.mission.nodes import psd_part_kernel
from hrtls.pipeline.tracker import Tracker

if TYPE_CHECKING:
    from hrtls.mission.tracker import MissionTracker

FloatArray = NDArray[np.float64]

MIN_SHIFT_M = 0.5
"""A node is estimated again once one of its readings moved at least this far, m."""
REFRESH_S = 15.0
"""... and at most once every this long for moved readings (by its agents' rows' time), s."""


@njit(cache=True)
def rts_bridge_kernel(xy: FloatArray, cov: FloatArray, corr: NDArray[np.bool_],
                      xs: FloatArray, ps: FloatArray) -> None:
    """Backward RTS pass of the module doc over rows ``(n, 2)``, ``(n, 2, 2)``, into xs, ps.

    ``corr[k]``: row ``k`` is a correction whose prior is row ``k - 1``.
    """
    n = xy.shape[0]
    if n == 0:
        return
    xs[n - 1] = xy[n - 1]
    ps[n - 1] = cov[n - 1]
    for k in range(n - 2, -1, -1):
        if corr[k + 1]:                                 # G = I, prior P_k
            xs[k] = xs[k + 1]
            p = cov[k] - psd_part_kernel(cov[k] - ps[k + 1])
        else:
            pp = cov[k] + psd_part_kernel(cov[k + 1] - cov[k])
            a, b, c = pp[0, 0], 0.5 * (pp[0, 1] + pp[1, 0]), pp[1, 1]
            det = a * c - b * b
            if not det > 1e-18 * max(a * c, 1e-300):
                xs[k] = xy[k]
                ps[k] = cov[k]
                continue
            inv = np.empty((2, 2))
            inv[0, 0], inv[0, 1], inv[1, 0], inv[1, 1] = c / det, -b / det, -b / det, a / det
            g = cov[k] @ inv
            xs[k] = xy[k] + g @ (xs[k + 1] - xy[k + 1])
            p = cov[k] - g @ psd_part_kernel(cov[k + 1] - ps[k + 1]) @ g.T
        ps[k] = psd_part_kernel(p)


def smooth_rows(xy_m: FloatArray, cov_m2: FloatArray, correction: NDArray[np.bool_]
                ) -> tuple[FloatArray, FloatArray]:
    """Smoothed positions and covariances of rows ``(n, 2)``, ``(n, 2, 2)`` (module doc)."""
    xy = np.ascontiguousarray(xy_m, dtype=np.float64).reshape(-1, 2)
    cov = np.ascontiguousarray(cov_m2, dtype=np.float64).reshape(-1, 2, 2)
    corr = np.ascontiguousarray(correction, dtype=np.bool_).reshape(-1)
    xs, ps = np.empty_like(xy), np.empty_like(cov)
    rts_bridge_kernel(xy, cov, corr, xs, ps)
    return xs, ps


def place(t_s: FloatArray, t: FloatArray, xy: FloatArray, cov: FloatArray
          ) -> tuple[FloatArray, FloatArray]:
    """Readings' positions (interpolated) and covariances (first row at or after) at ``t_s``."""
    pos = np.column_stack([np.interp(t_s, t, xy[:, 0]), np.interp(t_s, t, xy[:, 1])])
    j = np.clip(np.searchsorted(t, t_s), 0, len(t) - 1)
    return pos, cov[j]


@dataclass
class BridgeState:
    """What the mission keeps for the smoothing (plain arrays and lists: snapshot-ready).

    ``rows``: per agent its rows of the last ``smooth_readings_s``: t (n,), xy (n, 2), covariance
    (n, 2, 2), correction (n,) as 0/1; ``pulled``: time after which its tracker's rows are read
    next; ``notes``: per agent its readings that may still move, ``[node, indices]`` into that
    node's readings; ``seen``: per node its readings already noted; ``due``: agents with a new
    correction or reading since the last smoothing; ``stale``: nodes whose readings moved since
    their last estimate; ``refreshed``: when each was last made due for that.
    """

    rows: dict[str, list[FloatArray]] = field(default_factory=dict)
    pulled: dict[str, float] = field(default_factory=dict)
    notes: dict[str, list[list[Any]]] = field(default_factory=dict)
    seen: dict[str, int] = field(default_factory=dict)
    due: set[str] = field(default_factory=set)
    stale: set[str] = field(default_factory=set)
    refreshed: dict[str, float] = field(default_factory=dict)


def _note(mt: MissionTracker, nodes: set[str]) -> None:
    """Record the rescuers' readings of ``nodes`` stored since the last look, per agent."""
    st = mt.bridge
    assert st is not None
    for node in sorted(nodes):
        rd = mt.readings.get(node)
        a, b = st.seen.get(node, 0), 0 if rd is None else len(rd.r)
        if b <= a:
            continue
        st.seen[node] = b
        agents = np.asarray(rd.agent[a:b]) if rd is not None else np.zeros(0, np.int64)
        for i in np.unique(agents).tolist():
            name = mt.names[i]
            if isinstance(mt.trackers[name], Tracker):
                idx = np.flatnonzero(agents == i) + a
                st.notes.setdefault(name, []).append([node, idx])
                st.due.add(name)


def pull(mt: MissionTracker, name: str) -> None:
    """Append the agent's new rows; keep those of the last ``smooth_readings_s``.

    A row the tracker replaced (same time) replaces the kept one. Nothing without the bridge.
    """
    st = mt.bridge
    if st is None:
        return
    est = mt.trackers[name].estimates_since(st.pulled.get(name, -np.inf))
    if not len(est):
        return
    corr = (est.since_correction_s <= 1e-9).astype(np.float64)
    old = st.rows.get(name)
    new = [est.t, est.xyz[:, :2], est.cov_xy, corr]
    if old is not None:
        k = int(np.searchsorted(old[0], est.t[0]))   # a repeated time: the newer row
        new = [np.concatenate([o[:k], x]) for o, x in zip(old, new, strict=True)]
    keep = new[0] >= new[0][-1] - mt.params.smooth_readings_s
    keep[max(int(np.argmax(keep)) - 1, 0):] = True     # one row before the span: interpolation
    st.rows[name] = [np.ascontiguousarray(x[keep]) for x in new]
    if len(est) > 1:
        st.pulled[name] = float(est.t[-2])
    if corr.any():
        st.due.add(name)


def revise(mt: MissionTracker, name: str, touched: set[str]) -> set[str]:
    """Smooth agent ``name``'s kept rows when due and move its readings there.

    ``touched``: the nodes given new readings so far in the window. Returns the nodes one of
    whose readings moved by at least :data:`MIN_SHIFT_M` in a smoothing since their last
    estimate, each at most every :data:`REFRESH_S`: due for estimation again (its estimated
    reading count is reset).
    """
    st = mt.bridge
    if st is None:
        return set()
    _note(mt, touched)
    if name not in mt.started or not isinstance(mt.trackers[name], Tracker):
        return set()
    pull(mt, name)
    rows = st.rows.get(name)
    if name not in st.due or rows is None or len(rows[0]) < 2:
        return set()
    st.due.discard(name)
    t = rows[0]
    xs, ps = smooth_rows(rows[1], rows[2], rows[3] > 0)
    moved: set[str] = set()
    kept: list[list[Any]] = []
    for node, idx_all in st.notes.get(name, []):
        rd = mt.readings[node]
        ts = np.array([rd.t[k] for k in idx_all.tolist()])
        m = ts >= t[0]
        if not m.any():
            continue                                   # out of the span: final
        kept.append([node, idx_all])
        pos, cov = place(ts[m], t, xs, ps)
        idx = idx_all[m]
        shift = np.linalg.norm(pos - np.array([rd.xy[k] for k in idx.tolist()]), axis=1)
        for q, k in enumerate(idx.tolist()):
            rd.xy[k], rd.cov[k] = pos[q], cov[q]
        if shift.size and float(shift.max()) >= MIN_SHIFT_M:
            moved.add(node)
    st.notes[name] = kept
    st.stale |= moved
    now = float(t[-1])
    ready = {n for n in st.stale if now >= st.refreshed.get(n, -np.inf) + REFRESH_S}
    for node in ready:
        mt.estimated_at[node] = 0
        st.refreshed[node] = now
    st.stale -= ready
    return ready


def state_of(st: BridgeState | None) -> dict[str, Any] | None:
    """Plain values of the state (snapshot)."""
    if st is None:
        return None
    return {"rows": {k: list(v) for k, v in st.rows.items()}, "pulled": dict(st.pulled),
            "notes": {k: [[n, np.asarray(i, np.int64)] for n, i in v] for k, v in st.notes.items()},
            "seen": dict(st.seen), "due": sorted(st.due), "stale": sorted(st.stale),
            "refreshed": dict(st.refreshed)}


def state_from(d: dict[str, Any] | None) -> BridgeState | None:
    """The state from :func:`state_of` values."""
    if d is None:
        return None
    return BridgeState(
        rows={k: [np.ascontiguousarray(np.asarray(x, np.float64)) for x in v]
              for k, v in d["rows"].items()},
        pulled={k: float(v) for k, v in d["pulled"].items()},
        notes={k: [[str(n), np.asarray(i, np.int64).reshape(-1)] for n, i in v]
               for k, v in d["notes"].items()},
        seen={k: int(v) for k, v in d["seen"].items()}, due=set(d["due"]),
        stale=set(d["stale"]), refreshed={k: float(v) for k, v in d["refreshed"].items()})
