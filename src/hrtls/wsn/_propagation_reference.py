"""Slow pure-Python localization propagation by repeated sweeps (test reference).

Same rules as the compiled :func:`~hrtls.wsn._propagation.propagate_kernel`, other order; the
least-squares fix is computed by scipy instead of the compiled solver.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrtls.wsn._propagation import M_SHADOW, M_TRILATERATION, _circle_candidates, _gdop2

__all__ = ["propagate_reference"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


def propagate_reference(
    indptr: IntArray,
    indices: IntArray,
    dist: FloatArray,
    pos: FloatArray,
    localized: BoolArray,
    radius: float,
    use_shadow: bool,
    range_tol: float,
    min_spread: float,
    shadow_margin: float,
    max_gdop: float,
    flip_tol: float,
) -> tuple[BoolArray, FloatArray, NDArray[np.int8]]:
    """Slow pure-Python version by repeated sweeps (test reference; same rules, other order).

    The least-squares fix is computed by scipy instead of the compiled solver.
    """
    n = indptr.size - 1
    loc = localized.copy()
    p = pos.copy()
    meth = np.zeros(n, dtype=np.int8)
    changed = True
    while changed:
        changed = False
        for u in range(n):
            if loc[u]:
                continue
            nb = [(int(indices[k]), float(dist[k])) for k in range(indptr[u], indptr[u + 1])]
            nbset = {j for j, _ in nb}
            ln = [(j, d) for j, d in nb if loc[j]]
            pts = np.array([p[j] for j, _ in ln]).reshape(-1, 2)
            ds = np.array([d for _, d in ln])
            kind, x, pair = ("shadow", None, None) if len(ln) < 3 else _reference_trilateration(
                pts, ds, range_tol=range_tol, min_spread=min_spread, max_gdop=max_gdop,
                flip_tol=flip_tol)
            if kind == "fix" and x is not None:
                loc[u], p[u], meth[u], changed = True, x, M_TRILATERATION, True
            if kind != "shadow" or not use_shadow or len(ln) < 2:
                continue
            witnesses = {
                int(indices[k])
                for j, _ in ln
                for k in range(indptr[j], indptr[j + 1])
                if loc[indices[k]] and indices[k] not in nbset and indices[k] != u
            }
            c = _reference_shadow(pts, ds, pair, [p[w] for w in witnesses],
                                  radius=radius, range_tol=range_tol, min_spread=min_spread,
                                  shadow_margin=shadow_margin, max_gdop=max_gdop)
            if c is not None:
                loc[u], p[u], meth[u], changed = True, c, M_SHADOW, True
    return loc, p, meth


def _reference_trilateration(
    pts: FloatArray, ds: FloatArray, *, range_tol: float, min_spread: float, max_gdop: float,
    flip_tol: float
) -> tuple[str, FloatArray | None, tuple[int, int] | None]:
    """Trilateration of a node from three or more localized neighbours (test reference).

    ``("fix", x, None)``: localized at ``x``; ``("skip", None, None)``: the ranges do not fit
    the least-squares position (the node waits); ``("shadow", None, pair)``: the neighbours
    are too collinear, the geometry too poor or the fix ambiguous (``pair``: the neighbours
    whose reflection also fits, else None); the shadow edge may still place it.
    """
    q = pts - pts.mean(axis=0)
    lam = np.linalg.eigvalsh(q.T @ q)[0]
    if np.sqrt(max(lam, 0.0) / len(ds)) < min_spread:
        return "shadow", None, None
    x = _reference_lsq(pts, ds)
    if np.max(np.abs(np.linalg.norm(pts - x, axis=1) - ds)) > range_tol:
        return "skip", None, None
    u_vec = (x - pts) / np.linalg.norm(x - pts, axis=1)[:, None]
    if np.sqrt(np.trace(np.linalg.inv(u_vec.T @ u_vec))) > max_gdop:
        return "shadow", None, None
    pair = _reference_flip(pts, ds, x, flip_tol)
    return ("fix", x, None) if pair is None else ("shadow", None, pair)


def _reference_shadow(
    pts: FloatArray, ds: FloatArray, pair: tuple[int, int] | None, witness_xy: list[FloatArray],
    *, radius: float, range_tol: float, min_spread: float, shadow_margin: float,
    max_gdop: float
) -> FloatArray | None:
    """Shadow-edge position of a node from two neighbours (test reference), or None.

    The two candidates of the neighbours ``pair`` (default: the farthest apart) that fit all
    ranges; a candidate within the link radius (less ``shadow_margin``) of a witness that is
    not a neighbour is ruled out. A position only when exactly one candidate is left.
    """
    if pair is None:
        dmat = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
        flat = np.unravel_index(int(np.argmax(np.triu(dmat, 1))), dmat.shape)
        ia, ib = int(flat[0]), int(flat[1])
    else:
        ia, ib = pair
    ok, c1x, c1y, c2x, c2y = _circle_candidates.py_func(
        pts[ia, 0], pts[ia, 1], ds[ia], pts[ib, 0], pts[ib, 1], ds[ib], range_tol
    )
    if np.linalg.norm(pts[ia] - pts[ib]) < 2.0 * min_spread or not ok:
        return None
    if _gdop2.py_func(pts[ia, 0], pts[ia, 1], pts[ib, 0], pts[ib, 1], c1x, c1y) > max_gdop:
        return None
    cands = [np.array([c1x, c1y]), np.array([c2x, c2y])]
    alive = []
    for cand in cands:
        good = bool(np.all(np.abs(np.linalg.norm(pts - cand, axis=1) - ds) <= range_tol))
        if good and any(np.linalg.norm(cand - w) < radius - shadow_margin for w in witness_xy):
            good = False
        alive.append(good)
    if alive[0] == alive[1]:
        return None
    return cands[0] if alive[0] else cands[1]


def _reference_flip(
    pts: FloatArray, ds: FloatArray, x: FloatArray, tol: float
) -> tuple[int, int] | None:
    """Pair whose reflection of ``x`` also fits all ranges (first 8 neighbours), else None."""
    lim = min(len(ds), 8)
    for a in range(lim):
        for b in range(a + 1, lim):
            t = pts[b] - pts[a]
            foot = pts[a] + np.dot(x - pts[a], t) / np.dot(t, t) * t
            mirror = 2.0 * foot - x
            if np.linalg.norm(mirror - x) <= 2.0 * tol:
                continue
            if np.max(np.abs(np.linalg.norm(pts - mirror, axis=1) - ds)) <= tol:
                return a, b
    return None


def _reference_lsq(pts: FloatArray, ds: FloatArray) -> FloatArray:
    """Nonlinear least squares by scipy (reference for the compiled solver)."""
    from scipy.optimize import least_squares

    x0 = pts.mean(axis=0) + 1e-3 * (pts.max() - pts.min() + 1.0)
    a = 2.0 * (pts[1:] - pts[0])
    b = (ds[0] ** 2 - ds[1:] ** 2) + np.sum(pts[1:] ** 2, axis=1) - np.sum(pts[0] ** 2)
    x0 = np.linalg.lstsq(a, b, rcond=None)[0]
    sol = least_squares(lambda x: np.linalg.norm(pts - x, axis=1) - ds, x0, xtol=1e-15,
                        ftol=1e-15, gtol=1e-15)
    return np.asarray(sol.x, dtype=np.float64)
