"""Queue-based localization propagation shared by TLA and SELA (compiled kernel).

The kernel works on the CSR adjacency of the link graph. A node enters the work queue only when
one of its neighbours is localized (or, for SELA, when a node two hops away becomes a possible
shadow-edge witness), so the work is proportional to the number of links times the degree, never
to repeated sweeps over all nodes.

Rules (Inderst thesis Sec. 3.5 and 5.2):

* trilateration: >= 3 localized neighbours whose positions are not collinear (RMS distance from
  their best-fit line >= ``min_spread_m``) -> linear least squares, two Gauss-Newton iterations,
  accepted only if every range residual is <= ``range_tol_m`` (else flagged inconsistent);
* shadow edge (SELA only): >= 2 localized neighbours (or >= 3 collinear ones) -> the two circle
  intersections of the farthest-apart pair are the candidates (Definition 1). A candidate is
  rejected when it disagrees with another localized neighbour's range, or when a localized node
  ``j`` that is a neighbour of one of the localized neighbours (two-hop information, Remark 1)
  and is *not* linked to the node lies closer than ``rho - shadow_margin_m`` to the candidate
  (the shadow edge ``(i, j)``: under the disk model the node would have heard ``j``).
  Exactly one surviving candidate -> placed; none -> flagged inconsistent; two -> ambiguous.

A slow pure-Python version of the same rules, for the tests, is
:mod:`hrtls.wsn._propagation_reference`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.kernels import njit

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

# method codes (same as hrtls.wsn.network)
M_UNLOCALIZED, M_ANCHOR, M_TRILATERATION, M_SHADOW, M_AGENT = 0, 1, 2, 3, 4
# status codes of unlocalized nodes
S_OK, S_TOO_FEW, S_COLLINEAR, S_AMBIGUOUS, S_INCONSISTENT, S_UNCERTAIN = 0, 1, 2, 3, 4, 5
STATUS_NAMES = ("ok", "too-few-neighbours", "collinear", "ambiguous", "inconsistent", "uncertain")


@njit(cache=True)
def _centred_scatter(px: FloatArray, py: FloatArray,
                     c: int) -> tuple[float, float, float, float, float]:
    """Mean (mx, my) of the first ``c`` points and their centred scatter sums sxx, sxy, syy."""
    mx = 0.0
    my = 0.0
    for k in range(c):
        mx += px[k]
        my += py[k]
    mx /= c
    my /= c
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    for k in range(c):
        qx = px[k] - mx
        qy = py[k] - my
        sxx += qx * qx
        sxy += qx * qy
        syy += qy * qy
    return mx, my, sxx, sxy, syy


@njit(cache=True)
def _lls_gn(px: FloatArray, py: FloatArray, d: FloatArray, c: int) -> tuple[float, float, float]:
    """Least-squares position from ``c`` circles; returns x, y and the max |range residual|."""
    mx, my, sxx, sxy, syy = _centred_scatter(px, py, c)
    mq = (sxx + syy) / c
    md = 0.0
    for k in range(c):
        md += d[k] * d[k]
    md /= c
    # -2 q_k . y = d_k^2 - mean(d^2) - |q_k|^2 + mean(|q|^2), normal equations S y = rhs
    rx = 0.0
    ry = 0.0
    for k in range(c):
        qx = px[k] - mx
        qy = py[k] - my
        b = -0.5 * (d[k] * d[k] - md - (qx * qx + qy * qy) + mq)
        rx += qx * b
        ry += qy * b
    det = sxx * syy - sxy * sxy
    yx = (syy * rx - sxy * ry) / det
    yy = (sxx * ry - sxy * rx) / det
    x = mx + yx
    y = my + yy
    for _ in range(2):  # Gauss-Newton on the ranges
        a11 = 0.0
        a12 = 0.0
        a22 = 0.0
        g1 = 0.0
        g2 = 0.0
        for k in range(c):
            ex = x - px[k]
            ey = y - py[k]
            r = math.sqrt(ex * ex + ey * ey)
            if r <= 0.0:
                continue
            ux = ex / r
            uy = ey / r
            res = d[k] - r
            a11 += ux * ux
            a12 += ux * uy
            a22 += uy * uy
            g1 += ux * res
            g2 += uy * res
        dt = a11 * a22 - a12 * a12
        if dt <= 0.0:
            break
        x += (a22 * g1 - a12 * g2) / dt
        y += (a11 * g2 - a12 * g1) / dt
    worst = 0.0
    for k in range(c):
        ex = x - px[k]
        ey = y - py[k]
        res = abs(math.sqrt(ex * ex + ey * ey) - d[k])
        if res > worst:
            worst = res
    return x, y, worst


@njit(cache=True)
def _min_spread(px: FloatArray, py: FloatArray, c: int) -> float:
    """RMS distance of the points from their best-fit line (sqrt(small eigenvalue / c))."""
    _, _, sxx, sxy, syy = _centred_scatter(px, py, c)
    tr = 0.5 * (sxx + syy)
    disc = math.sqrt(max(0.25 * (sxx - syy) ** 2 + sxy * sxy, 0.0))
    lam = max(tr - disc, 0.0)
    return math.sqrt(lam / c)


@njit(cache=True)
def _farthest_pair(px: FloatArray, py: FloatArray, c: int) -> tuple[int, int]:
    """Indices of the two points farthest apart."""
    ia = 0
    ib = 1
    best = -1.0
    for a in range(c):
        for b in range(a + 1, c):
            q = (px[a] - px[b]) ** 2 + (py[a] - py[b]) ** 2
            if q > best:
                best = q
                ia = a
                ib = b
    return ia, ib


@njit(cache=True)
def _gdop(px: FloatArray, py: FloatArray, c: int, x: float, y: float) -> float:
    """sqrt(trace((J^T J)^-1)) of range observations from the points at (x, y)."""
    a11 = 0.0
    a12 = 0.0
    a22 = 0.0
    for k in range(c):
        ex = x - px[k]
        ey = y - py[k]
        r = math.sqrt(ex * ex + ey * ey)
        if r <= 0.0:
            continue
        a11 += ex * ex / (r * r)
        a12 += ex * ey / (r * r)
        a22 += ey * ey / (r * r)
    det = a11 * a22 - a12 * a12
    if det <= 0.0:
        return math.inf
    return math.sqrt((a11 + a22) / det)


@njit(cache=True)
def _gdop2(ax: float, ay: float, bx: float, by: float, x: float, y: float) -> float:
    """GDOP of a fix from the two ranges to a and b (2 / sin^2 of the angle between them)."""
    ux = x - ax
    uy = y - ay
    vx = x - bx
    vy = y - by
    ru = math.sqrt(ux * ux + uy * uy)
    rv = math.sqrt(vx * vx + vy * vy)
    if ru <= 0.0 or rv <= 0.0:
        return math.inf
    s = (ux * vy - uy * vx) / (ru * rv)
    if s == 0.0:
        return math.inf
    return math.sqrt(2.0) / abs(s)


@njit(cache=True)
def _flip_pair(
    px: FloatArray, py: FloatArray, pd: FloatArray, c: int, x: float, y: float, tol: float
) -> tuple[int, int]:
    """A pair (a, b) whose mirror image of (x, y) also fits all ranges within tol, else (-1, -1).

    Flip ambiguity: reflecting the solution across the line of two neighbours keeps their ranges;
    if the others cannot tell the reflection apart, trilateration could be wrong under noise.
    Only the first 8 neighbours are paired (cost 8^2 * c).
    """
    lim = min(c, 8)
    for a in range(lim):
        for b in range(a + 1, lim):
            dx = px[b] - px[a]
            dy = py[b] - py[a]
            ll = dx * dx + dy * dy
            if ll <= 0.0:
                continue
            t = ((x - px[a]) * dx + (y - py[a]) * dy) / ll
            fx = px[a] + t * dx
            fy = py[a] + t * dy
            mx = 2.0 * fx - x
            my = 2.0 * fy - y
            if (mx - x) ** 2 + (my - y) ** 2 <= (2.0 * tol) ** 2:
                continue  # the mirror is the same point: no ambiguity
            worst = 0.0
            for k in range(c):
                r = math.sqrt((mx - px[k]) ** 2 + (my - py[k]) ** 2)
                e = abs(r - pd[k])
                if e > worst:
                    worst = e
            if worst <= tol:
                return a, b
    return -1, -1


@njit(cache=True)
def _circle_candidates(
    ax: float, ay: float, ra: float, bx: float, by: float, rb: float, tol: float
) -> tuple[bool, float, float, float, float]:
    """Two intersections of circles (a, ra), (b, rb); ok False when they do not meet."""
    dx = bx - ax
    dy = by - ay
    dd = math.sqrt(dx * dx + dy * dy)
    if dd <= 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    ex = dx / dd
    ey = dy / dd
    along = (ra * ra - rb * rb + dd * dd) / (2.0 * dd)
    h2 = ra * ra - along * along
    if h2 < 0.0:
        # tangent within tolerance: |ra - along| small
        if math.sqrt(-h2) > math.sqrt(2.0 * tol * (ra + rb) + tol * tol):
            return False, 0.0, 0.0, 0.0, 0.0
        h2 = 0.0
    h = math.sqrt(h2)
    mx = ax + along * ex
    my = ay + along * ey
    return True, mx - h * ey, my + h * ex, mx + h * ey, my - h * ex


@njit(cache=True)
def propagate_kernel(
    indptr: IntArray,
    indices: IntArray,
    dist: FloatArray,
    pos: FloatArray,
    localized: BoolArray,
    method: NDArray[np.int8],
    status: NDArray[np.int8],
    witness: IntArray,
    order: IntArray,
    n_order: int,
    radius: float,
    use_shadow: bool,
    range_tol: float,
    min_spread: float,
    shadow_margin: float,
    max_gdop: float,
    flip_tol: float,
    sig: FloatArray,
    range_sigma: float,
    max_sig: float,
) -> int:
    """Propagate localization in place; returns the new length of ``order``."""
    n = indptr.size - 1
    need = 2 if use_shadow else 3
    count = np.zeros(n, dtype=np.int64)
    maxdeg = 1
    for u in range(n):
        deg = indptr[u + 1] - indptr[u]
        if deg > maxdeg:
            maxdeg = deg
        for k in range(indptr[u], indptr[u + 1]):
            if localized[indices[k]]:
                count[u] += 1
    queue = np.empty(n + 1, dtype=np.int64)
    inq = np.zeros(n, dtype=np.bool_)
    head = 0
    tail = 0
    qn = n + 1
    for u in range(n):
        if not localized[u]:
            if count[u] >= need:
                queue[tail] = u
                tail = (tail + 1) % qn
                inq[u] = True
            elif count[u] < need:
                status[u] = S_TOO_FEW
    mark = np.full(n, -1, dtype=np.int64)
    px = np.empty(maxdeg)
    py = np.empty(maxdeg)
    pd = np.empty(maxdeg)
    pid = np.empty(maxdeg, dtype=np.int64)
    while head != tail:
        u = queue[head]
        head = (head + 1) % qn
        inq[u] = False
        if localized[u]:
            continue
        c = 0
        smax = 0.0
        ssum = 0.0
        for k in range(indptr[u], indptr[u + 1]):
            j = indices[k]
            if localized[j]:
                px[c] = pos[j, 0]
                py[c] = pos[j, 1]
                pd[c] = dist[k]
                pid[c] = j
                if sig[j] > smax:
                    smax = sig[j]
                ssum += sig[j]
                c += 1
        smean = ssum / c if c > 0 else 0.0
        # tolerances grow with the uncertainty carried by the neighbours
        rt = range_tol + 4.0 * smax
        ft = flip_tol + 4.0 * smax
        # a common shift of the neighbours moves the node by the same amount; range noise is
        # amplified by the GDOP of the fix
        s_in = range_sigma
        su = 0.0
        placed = False
        xx = 0.0
        yy = 0.0
        how = M_TRILATERATION
        wit = -1
        st = S_TOO_FEW
        ia = -1
        ib = -1
        if c >= 3:
            if _min_spread(px, py, c) >= min_spread:
                xx, yy, worst = _lls_gn(px, py, pd, c)
                gd = _gdop(px, py, c, xx, yy)
                if worst > rt:
                    st = S_INCONSISTENT
                elif gd > max_gdop:
                    st = S_COLLINEAR
                else:
                    ia, ib = _flip_pair(px, py, pd, c, xx, yy, ft)
                    if ia >= 0:
                        st = S_AMBIGUOUS
                    elif math.hypot(gd * s_in, smean) > max_sig:
                        st = S_UNCERTAIN
                        ia = -2
                    else:
                        placed = True
                        su = math.hypot(gd * s_in, smean)
            else:
                st = S_COLLINEAR
        if (not placed) and use_shadow and c >= 2 and st != S_INCONSISTENT and ia != -2:
            if ia < 0:
                ia, ib = _farthest_pair(px, py, c)
            ok, c1x, c1y, c2x, c2y = _circle_candidates(
                px[ia], py[ia], pd[ia], px[ib], py[ib], pd[ib], rt
            )
            base = math.sqrt((px[ia] - px[ib]) ** 2 + (py[ia] - py[ib]) ** 2)
            if base < 2.0 * min_spread:
                st = S_COLLINEAR
            elif not ok:
                st = S_INCONSISTENT
            elif _gdop2(px[ia], py[ia], px[ib], py[ib], c1x, c1y) > max_gdop:
                st = S_COLLINEAR
            elif math.hypot(_gdop2(px[ia], py[ia], px[ib], py[ib], c1x, c1y) * s_in,
                            smean) > max_sig:
                st = S_UNCERTAIN
            else:
                ok1 = True
                ok2 = True
                for a in range(c):  # consistency with the other localized neighbours
                    if a in (ia, ib):
                        continue
                    r1 = math.sqrt((c1x - px[a]) ** 2 + (c1y - py[a]) ** 2)
                    r2 = math.sqrt((c2x - px[a]) ** 2 + (c2y - py[a]) ** 2)
                    if abs(r1 - pd[a]) > rt:
                        ok1 = False
                    if abs(r2 - pd[a]) > rt:
                        ok2 = False
                # negative information from two-hop localized nodes (shadow edges)
                for k in range(indptr[u], indptr[u + 1]):
                    mark[indices[k]] = u
                mark[u] = u
                w1 = -1
                w2 = -1
                lim0 = radius - shadow_margin - 3.0 * smax
                for a in range(c):
                    h = pid[a]
                    for k in range(indptr[h], indptr[h + 1]):
                        j = indices[k]
                        if mark[j] == u or not localized[j]:
                            continue
                        lim = lim0 - 3.0 * sig[j]
                        r1 = math.sqrt((c1x - pos[j, 0]) ** 2 + (c1y - pos[j, 1]) ** 2)
                        r2 = math.sqrt((c2x - pos[j, 0]) ** 2 + (c2y - pos[j, 1]) ** 2)
                        if ok1 and w1 < 0 and r1 < lim:
                            w1 = j
                        if ok2 and w2 < 0 and r2 < lim:
                            w2 = j
                if w1 >= 0:
                    ok1 = False
                if w2 >= 0:
                    ok2 = False
                su = math.hypot(_gdop2(px[ia], py[ia], px[ib], py[ib], c1x, c1y) * s_in, smean)
                if ok1 and not ok2:
                    placed = True
                    xx = c1x
                    yy = c1y
                    how = M_SHADOW
                    wit = w2
                elif ok2 and not ok1:
                    placed = True
                    xx = c2x
                    yy = c2y
                    how = M_SHADOW
                    wit = w1
                elif ok1 and ok2:
                    st = S_AMBIGUOUS
                else:
                    st = S_INCONSISTENT
        if not placed:
            status[u] = st
            continue
        localized[u] = True
        sig[u] = su
        pos[u, 0] = xx
        pos[u, 1] = yy
        method[u] = how
        status[u] = S_OK
        witness[u] = wit
        order[n_order] = u
        n_order += 1
        for k in range(indptr[u], indptr[u + 1]):
            w = indices[k]
            count[w] += 1
            if (not localized[w]) and count[w] >= need and not inq[w]:
                queue[tail] = w
                tail = (tail + 1) % qn
                inq[w] = True
        if use_shadow:
            # u may now be a shadow witness for nodes two hops away
            for k in range(indptr[u], indptr[u + 1]):
                h = indices[k]
                if not localized[h]:
                    continue
                for k2 in range(indptr[h], indptr[h + 1]):
                    v = indices[k2]
                    if (not localized[v]) and count[v] >= 2 and not inq[v]:
                        queue[tail] = v
                        tail = (tail + 1) % qn
                        inq[v] = True
    return n_order
