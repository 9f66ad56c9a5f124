"""Compiled kernels of the grid filter (:mod:`hrtls.fusion.rss_grid`): motion, likelihood, bias.

Each works on a density of shape (ny, nx) (one velocity mode) except :func:`mix_modes` and
:func:`move_modes`, which work on the joint density of position and velocity mode (K, ny, nx).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrtls.fusion._checks import FloatArray
from hrtls.fusion.path_loss import mean_rss_dbm
from hrtls.kernels import njit

IntArray = NDArray[np.int64]

RSS_SPAN_DB = 60.0
"""Width of the uniform outlier density of a reading, dB."""

@njit(cache=True, error_model="numpy")
def blur(density: FloatArray, sigma_cells: float, tmp: FloatArray) -> None:
    # pragma: no cover - compiled
    """Convolve ``density`` (ny, nx) in place with a Gaussian of ``sigma_cells`` per axis.

    Zero outside the grid; truncated at 3 sigma; renormalised to sum 1. ``tmp``: (ny, nx).
    """
    if sigma_cells <= 1e-6:
        return
    h = math.ceil(3.0 * sigma_cells)
    w = np.empty(2 * h + 1)
    for k in range(-h, h + 1):
        w[k + h] = math.exp(-0.5 * (k / sigma_cells) ** 2)
    w /= w.sum()
    ny, nx = density.shape
    for i in range(ny):
        for j in range(nx):
            s = 0.0
            for k in range(max(-h, -j), min(h, nx - 1 - j) + 1):
                s += w[k + h] * density[i, j + k]
            tmp[i, j] = s
    total = 0.0
    for i in range(ny):
        for j in range(nx):
            s = 0.0
            for k in range(max(-h, -i), min(h, ny - 1 - i) + 1):
                s += w[k + h] * tmp[i + k, j]
            density[i, j] = s
            total += s
    if total > 0.0:
        density /= total


@njit(cache=True, error_model="numpy")
def shift(density: FloatArray, sx_cells: float, sy_cells: float, tmp: FloatArray) -> None:
    # pragma: no cover - compiled
    """Move ``density`` (ny, nx) in place by ``sx_cells`` columns and ``sy_cells`` rows.

    Bilinear between the four cells a mass lands among (its mean moves by the shift exactly);
    mass that leaves the grid is dropped and the rest renormalised (unchanged if none stays).
    """
    if sx_cells == 0.0 and sy_cells == 0.0:
        return
    ix, iy = math.floor(sx_cells), math.floor(sy_cells)
    fx, fy = sx_cells - ix, sy_cells - iy
    ny, nx = density.shape
    tmp[:] = 0.0
    for i in range(ny):
        for j in range(nx):
            p = density[i, j]
            if p == 0.0:
                continue
            for di in range(2):
                ii = i + iy + di
                if ii < 0 or ii >= ny:
                    continue
                wy = fy if di else 1.0 - fy
                for dj in range(2):
                    jj = j + ix + dj
                    if 0 <= jj < nx:
                        tmp[ii, jj] += p * wy * (fx if dj else 1.0 - fx)
    total = tmp.sum()
    if total > 0.0:
        density[:] = tmp / total


@njit(cache=True, error_model="numpy")
def shift_adjoint(field: FloatArray, sx_cells: float, sy_cells: float, tmp: FloatArray) -> None:
    # pragma: no cover - compiled
    """Transpose of :func:`shift` (before its renormalisation), in place on ``field`` (ny, nx).

    Each cell gathers ``field`` over the (up to four) cells its mass lands among, with the same
    bilinear weights; zero beyond the grid's edge; nothing renormalised. ``tmp``: (ny, nx).
    """
    if sx_cells == 0.0 and sy_cells == 0.0:
        return
    ix, iy = math.floor(sx_cells), math.floor(sy_cells)
    fx, fy = sx_cells - ix, sy_cells - iy
    ny, nx = field.shape
    for i in range(ny):
        for j in range(nx):
            s = 0.0
            for di in range(2):
                ii = i + iy + di
                if ii < 0 or ii >= ny:
                    continue
                wy = fy if di else 1.0 - fy
                for dj in range(2):
                    jj = j + ix + dj
                    if 0 <= jj < nx:
                        s += field[ii, jj] * wy * (fx if dj else 1.0 - fx)
            tmp[i, j] = s
    field[:] = tmp


@njit(cache=True, error_model="numpy")
def shift_field(field: FloatArray, sx_cells: float, sy_cells: float, tmp: FloatArray) -> None:
    # pragma: no cover - compiled
    """``field(x) <- field(x - s)`` in place, ``s`` = (``sx_cells``, ``sy_cells``) cells.

    Bilinear between cells; beyond the grid's edge the edge value is held (a log-likelihood
    field, not a density: nothing is renormalised). ``tmp``: (ny, nx).
    """
    if sx_cells == 0.0 and sy_cells == 0.0:
        return
    ny, nx = field.shape
    for i in range(ny):
        yc = min(max(i - sy_cells, 0.0), ny - 1.0)
        i0 = min(int(yc), max(ny - 2, 0))
        fy = yc - i0
        i1 = min(i0 + 1, ny - 1)
        for j in range(nx):
            xc = min(max(j - sx_cells, 0.0), nx - 1.0)
            j0 = min(int(xc), max(nx - 2, 0))
            fx = xc - j0
            j1 = min(j0 + 1, nx - 1)
            tmp[i, j] = (1.0 - fy) * ((1.0 - fx) * field[i0, j0] + fx * field[i0, j1]) \
                + fy * ((1.0 - fx) * field[i1, j0] + fx * field[i1, j1])
    field[:] = tmp


@njit(cache=True, error_model="numpy")
def follow_velocity(velocity: FloatArray, prev_xy: FloatArray, mean_xy: FloatArray, dt: float,
                    time_s: float, max_m_per_s: float) -> None:   # pragma: no cover - compiled
    """Exponential average of the mean's displacement per second into ``velocity`` (in place).

    Gain ``dt / (time_s + dt)``; the speed is clipped to ``max_m_per_s``.
    """
    if dt <= 0.0:
        return
    g = dt / (time_s + dt)
    for c in range(2):
        velocity[c] += g * ((mean_xy[c] - prev_xy[c]) / dt - velocity[c])
    speed = math.hypot(velocity[0], velocity[1])
    if speed > max_m_per_s:
        velocity *= max_m_per_s / speed


@njit(cache=True, error_model="numpy")
def map_mean(dist: FloatArray, rmap: FloatArray, a: int, i: int, j: int,
             model: np.record) -> float:   # pragma: no cover - compiled
    """Mean RSS of anchor ``a`` at cell (i, j): the path loss plus the radio map, if any, dBm."""
    mu = mean_rss_dbm(model.a_dbm, model.eta, model.d0_m, dist[a, i, j])
    return mu + rmap[a, i, j] if rmap.shape[0] > 0 else mu


@njit(cache=True, error_model="numpy")
def cell_log_likelihood(e: float, sig: float, pb: float, prm: np.record) -> float:
    # pragma: no cover - compiled
    """``log l`` of a residual ``e`` (dB) with spread ``sig`` and burst probability ``pb``."""
    outlier, q = prm.outlier_probability, prm.attenuation_probability
    z = e / sig
    g = (1.0 - q) * math.exp(-0.5 * z * z) + \
        q * math.exp(-0.5 * (z + prm.attenuation_db / sig) ** 2)
    v = (1.0 - outlier) * (1.0 - pb) / (math.sqrt(2.0 * math.pi) * sig) * g \
        + outlier / RSS_SPAN_DB
    if pb > 0.0:
        sb = math.sqrt(sig ** 2 + prm.burst_sigma_db ** 2)
        v += (1.0 - outlier) * pb / (math.sqrt(2.0 * math.pi) * sb) * math.exp(-0.5 * (e / sb) ** 2)
    return math.log(v)


@njit(cache=True, error_model="numpy")
def log_likelihood(dist: FloatArray, rmap: FloatArray, rvar: FloatArray, anchor: IntArray,
                   rss_dbm: FloatArray, weight: FloatArray, offsets_db: FloatArray,
                   offsets_var: FloatArray, burst: FloatArray, model: np.record,
                   prm: np.record, out: FloatArray) -> None:
    # pragma: no cover - compiled
    """Sum over rows of ``weight log l`` per cell into ``out`` (ny, nx) (module docstring).

    The offset's variance ``offsets_var`` adds to the shadowing variance (bias marginalised),
    and so does the radio map's variance ``rvar`` (A, ny, nx) of each cell; the map ``rmap``
    (A, ny, nx) adds to the mean (both (0, 0, 0): no map).
    An anchor in a burst (probability ``burst``) reads with ``burst_sigma_db`` more spread:
    ``l = (1 - b) l_normal + b (1 - e) N(r; mu + o, sqrt(s^2 + burst_sigma_db^2))``.
    """
    out[:] = 0.0
    ny, nx = out.shape
    has_var = rvar.shape[0] > 0
    for r in range(anchor.shape[0]):
        a = anchor[r]
        sig = model.sigma_db if offsets_var[a] == 0.0 else \
            math.sqrt(model.sigma_db ** 2 + offsets_var[a])
        for i in range(ny):
            for j in range(nx):
                e = rss_dbm[r] - map_mean(dist, rmap, a, i, j, model) - offsets_db[a]
                s = math.sqrt(sig ** 2 + rvar[a, i, j]) if has_var else sig
                out[i, j] += weight[r] * cell_log_likelihood(e, s, burst[a], prm)


@njit(cache=True, error_model="numpy")
def burst_update(dist: FloatArray, rmap: FloatArray, rvar: FloatArray, density: FloatArray,
                 anchor: IntArray, rss_dbm: FloatArray, weight: FloatArray,
                 offsets_db: FloatArray, offsets_var: FloatArray, burst: FloatArray,
                 model: np.record, prm: np.record) -> None:
    # pragma: no cover - compiled
    """Posterior burst probability of each heard anchor from its reading, in place.

    Over the (predicted) position ``density``: ``L_n = sum p N(r; mu + o, s)`` and
    ``L_b = sum p N(r; mu + o, sqrt(s^2 + burst_sigma_db^2))``, ``s^2 = sigma^2 + P`` (plus
    the radio map's variance of the cell; ``mu`` includes the map); the odds
    ``b / (1 - b)`` are multiplied by ``(L_b / L_n)^w``.
    """
    ny, nx = density.shape
    for r in range(anchor.shape[0]):
        a, w = anchor[r], weight[r]
        pb = burst[a]
        if w <= 0.0 or pb <= 0.0 or pb >= 1.0:
            continue
        sig = math.sqrt(model.sigma_db ** 2 + offsets_var[a])
        sb = math.sqrt(sig ** 2 + prm.burst_sigma_db ** 2)
        ln = lb = 0.0
        for i in range(ny):
            for j in range(nx):
                p = density[i, j]
                if p == 0.0:
                    continue
                if rvar.shape[0] > 0:
                    sig = math.sqrt(model.sigma_db ** 2 + offsets_var[a] + rvar[a, i, j])
                    sb = math.sqrt(sig ** 2 + prm.burst_sigma_db ** 2)
                e = rss_dbm[r] - map_mean(dist, rmap, a, i, j, model) - offsets_db[a]
                ln += p * math.exp(-0.5 * (e / sig) ** 2) / sig
                lb += p * math.exp(-0.5 * (e / sb) ** 2) / sb
        if ln <= 0.0 or lb <= 0.0:
            continue
        odds = pb / (1.0 - pb) * (lb / ln) ** w
        burst[a] = odds / (1.0 + odds)


@njit(cache=True, error_model="numpy")
def burst_predict(burst: FloatArray, dt: float, enter_per_s: float, exit_per_s: float) -> None:
    # pragma: no cover - compiled
    """Two-state Markov chain of each anchor's burst over ``dt``, in place.

    ``b <- b_inf + (b - b_inf) exp(-(enter + exit) dt)``, ``b_inf = enter / (enter + exit)``.
    """
    rate = enter_per_s + exit_per_s
    if rate <= 0.0 or dt <= 0.0:
        return
    stay = math.exp(-rate * dt)
    b_inf = enter_per_s / rate
    for a in range(burst.shape[0]):
        burst[a] = b_inf + (burst[a] - b_inf) * stay


@njit(cache=True, error_model="numpy")
def bias_update(dist: FloatArray, rmap: FloatArray, rvar: FloatArray, density: FloatArray,
                anchor: IntArray, rss_dbm: FloatArray, weight: FloatArray,
                offsets_db: FloatArray, offsets_var: FloatArray,
                model: np.record) -> None:   # pragma: no cover - compiled
    """Kalman update of each heard anchor's offset from the residual over ``density``.

    The predicted RSS is marginalised over the (predicted) position density: residual
    ``e = r - E[mu] - o``, variance ``S = sigma^2 / w + Var[mu] + P`` (plus the mean radio
    map variance ``E[rvar]``; ``mu`` includes the map); a residual beyond 3 sqrt(S) is not used
    (an outlier or an attenuated reading).
    """
    ny, nx = density.shape
    has_var = rvar.shape[0] > 0
    for r in range(anchor.shape[0]):
        a, w = anchor[r], weight[r]
        if w <= 0.0:
            continue
        m1 = m2 = mv = 0.0
        for i in range(ny):
            for j in range(nx):
                mu = map_mean(dist, rmap, a, i, j, model)
                m1 += density[i, j] * mu
                m2 += density[i, j] * mu * mu
                if has_var:
                    mv += density[i, j] * rvar[a, i, j]
        p = offsets_var[a]
        s = model.sigma_db ** 2 / w + max(m2 - m1 * m1, 0.0) + p + mv
        e = rss_dbm[r] - m1 - offsets_db[a]
        if e * e > 9.0 * s:
            continue
        offsets_db[a] += p / s * e
        offsets_var[a] = p - p * p / s


@njit(cache=True, error_model="numpy")
def moments(density: FloatArray, x0: float, y0: float, cell: float, out: FloatArray) -> None:
    # pragma: no cover - compiled
    """Mean (out[0:2]) and covariance xx, xy, yy (out[2:5]) of the density, m and m^2."""
    ny, nx = density.shape
    sx = sy = sxx = sxy = syy = 0.0
    for i in range(ny):
        y = y0 + cell * i
        for j in range(nx):
            p = density[i, j]
            x = x0 + cell * j
            sx += p * x
            sy += p * y
            sxx += p * x * x
            sxy += p * x * y
            syy += p * y * y
    out[0], out[1] = sx, sy
    out[2] = max(sxx - sx * sx, 0.0)
    out[3] = sxy - sx * sy
    out[4] = max(syy - sy * sy, 0.0)


@njit(cache=True, error_model="numpy")
def mix_modes(density: FloatArray, leave: float) -> None:   # pragma: no cover - compiled
    """Markov switching of the velocity mode, in place on the joint density (K, ny, nx).

    Each mode is left with probability ``leave``, to each of the other ``K - 1`` alike:
    ``p'(x, m) = (1 - leave) p(x, m) + leave / (K - 1) (P(x) - p(x, m))``, ``P(x)`` the position
    density (unchanged, as is the total mass).
    """
    k, ny, nx = density.shape
    if k < 2 or leave <= 0.0:
        return
    c = leave / (k - 1)
    for i in range(ny):
        for j in range(nx):
            total = 0.0
            for m in range(k):
                total += density[m, i, j]
            for m in range(k):
                p = density[m, i, j]
                density[m, i, j] = (1.0 - leave) * p + c * (total - p)


@njit(cache=True, error_model="numpy")
def move_modes(density: FloatArray, velocity: FloatArray, turn_rad: float, stopped: bool,
               dt: float, cell: float, sigma_cells: float, tmp: FloatArray) -> None:
    # pragma: no cover - compiled
    """Shift each mode of the joint density (K, ny, nx) by its velocity times ``dt``, then blur.

    Mode ``m`` moves at ``velocity`` (x, y, m/s) turned by ``m turn_rad``; with ``stopped`` the
    last mode does not move. With one mode this is :func:`shift` then :func:`blur`; with more,
    each mode keeps its mass (mass leaving the grid is given back to the cells inside).
    """
    k = density.shape[0]
    n_turn = k - 1 if stopped else k
    for m in range(k):
        vx = vy = 0.0
        if m < n_turn:
            c, s = math.cos(m * turn_rad), math.sin(m * turn_rad)
            vx = c * velocity[0] - s * velocity[1]
            vy = s * velocity[0] + c * velocity[1]
        mass = density[m].sum() if k > 1 else 1.0
        if mass <= 0.0:
            continue
        shift(density[m], vx * dt / cell, vy * dt / cell, tmp)
        blur(density[m], sigma_cells, tmp)
        if k > 1:
            density[m] *= mass / density[m].sum()


@njit(cache=True, error_model="numpy")
def apply_likelihood(density: FloatArray, ll: FloatArray, marginal: FloatArray) -> None:
    # pragma: no cover - compiled
    """Multiply every mode of ``density`` (K, ny, nx) by ``exp(ll)`` (ny, nx) and renormalise.

    If that leaves no mass (the scan excludes the whole prior), the density restarts from the
    likelihood, shared equally among the modes. ``marginal`` (ny, nx): the position density
    after the update. ``ll`` is overwritten.
    """
    k, ny, nx = density.shape
    top = ll.max()
    for i in range(ny):
        for j in range(nx):
            ll[i, j] = math.exp(ll[i, j] - top)
    total = 0.0
    for m in range(k):
        for i in range(ny):
            for j in range(nx):
                density[m, i, j] *= ll[i, j]
                total += density[m, i, j]
    if total <= 0.0:
        for m in range(k):
            density[m] = ll
        total = k * ll.sum()
    density /= total
    marginal[:] = density[0]
    for m in range(1, k):
        marginal += density[m]


@njit(cache=True, error_model="numpy")
def window_medians(values: FloatArray, lo: IntArray, hi: IntArray) -> FloatArray:
    # pragma: no cover - compiled
    """Median of ``values[lo[k]:hi[k]]`` for every k (each slice non-empty)."""
    out = np.empty(lo.shape[0])
    for k in range(lo.shape[0]):
        out[k] = np.median(values[lo[k]:hi[k]])
    return out


@njit(cache=True, error_model="numpy")
def marginal_median(marginal: FloatArray, origin: float, cell: float) -> float:
    # pragma: no cover - compiled
    """Median of a marginal density on cells ``origin + cell j`` (sums to 1), m.

    Linear between the two cell centres where the cumulative sum crosses 1/2 (the first
    centre if the first cell already holds half the mass).
    """
    cum_prev = 0.0
    for j in range(marginal.shape[0]):
        cum = cum_prev + marginal[j]
        if cum >= 0.5:
            if j == 0:
                return origin
            return origin + cell * (j - 1 + (0.5 - cum_prev) / (cum - cum_prev))
        cum_prev = cum
    return origin + cell * (marginal.shape[0] - 1)


@njit(cache=True, error_model="numpy")
def median_row(density: FloatArray, x0: float, y0: float, cell: float, row: FloatArray) -> None:
    # pragma: no cover - compiled
    """Replace the mean of a :func:`moments` row by the density's per-axis median, in place.

    ``density`` (ny, nx) sums to 1; the covariance becomes the spread about the new point,
    ``C + (m - p)(m - p)^T``.
    """
    px = density.sum(axis=0)
    py = density.sum(axis=1)
    mx = marginal_median(px, x0, cell)
    my = marginal_median(py, y0, cell)
    dx, dy = row[0] - mx, row[1] - my
    row[2] += dx * dx
    row[3] += dx * dy
    row[4] += dy * dy
    row[0], row[1] = mx, my
