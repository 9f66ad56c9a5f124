"""RSS scans and their positions: readings averaged per window, hyperbolic WLS (Tarrio eq. 1-2).

* :func:`scan_table` / :func:`group_scans` -- the readings of each localization period averaged
  per anchor in the dB domain (readings below the sensitivity dropped).
* :func:`hyperbolic_wls` -- weighted hyperbolic least squares (eq. 2). Subtracting the circle of
  a reference anchor ``r`` from the others linearizes the problem:
  ``2 (a_i - a_r)^T (p - a_r) = |a_i - a_r|^2 - d_i^2 + d_r^2`` with the covariance of the
  right-hand side proportional to ``S = diag(d_i^4) + d_r^4 1 1^T``.
  Reading: the paper writes ``H`` and ``b`` with the first anchor at the origin; we translate the
  coordinates so that the reference anchor is the origin, and choose as reference the anchor with
  the *smallest* estimated distance (its ``d^4`` weight, the common term of ``S``, is then
  smallest). The position covariance is ``4 sigma_ln^2 (H^T S^-1 H)^-1`` (first order,
  ``var(d^2) ~ 4 d^4 sigma_ln^2``).
* :func:`scan_position` -- eq. 1 distances of a scan, then eq. 2.
* :func:`average_rss_per_anchor` -- one mean reading per anchor and window (tight updates).

The maths is compiled once (:func:`hyperbolic_wls_kernel`, :func:`scan_fix`, on plain arrays);
the Python functions validate and call it, and so does the tracker's event loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RssReadings
from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar, finite_vector
from hrtls.fusion.path_loss import LN10, PathLossModel
from hrtls.kernels import njit


@dataclass(frozen=True, slots=True, eq=False)
class WlsFix:
    """Position from :func:`hyperbolic_wls`: ``xy`` (m), ``cov`` (2x2, m^2), reference index."""

    xy: FloatArray
    cov: FloatArray
    reference: int


@njit(cache=True, error_model="numpy")
def hyperbolic_wls_kernel(axy: FloatArray, d: FloatArray, sigma_ln: float, ref: int,
                          out: FloatArray) -> bool:  # pragma: no cover - compiled
    """Eq. 2 on plain arrays: ``out`` receives ``[x, y, cov_xx, cov_xy, cov_yy]``.

    ``axy`` (N, 2) anchors, ``d`` (N,) distances, ``ref`` the reference anchor. False when the
    anchors are collinear (the normal matrix is singular or worse conditioned than 1e12). With
    ``h_i = 2 (a_i - a_r)``, ``w_i = 1 / d_i^4`` and ``S^-1 = diag(w) - k w w^T``
    (Sherman-Morrison, ``k = d_r^4 / (1 + d_r^4 sum w)``): ``H^T S^-1 H = sum w_i h_i h_i^T -
    k g g^T`` with ``g = sum w_i h_i``, and ``H^T S^-1 b = sum w_i b_i h_i - k g (sum w_i b_i)``.
    """
    n = d.shape[0]
    ax = axy[ref, 0]
    ay = axy[ref, 1]
    dr2 = d[ref] * d[ref]
    c_ref = dr2 * dr2
    sw = 0.0
    for i in range(n):
        if i != ref:
            d2 = d[i] * d[i]
            sw += 1.0 / (d2 * d2)
    k = c_ref / (1.0 + c_ref * sw)
    i00 = 0.0
    i01 = 0.0
    i11 = 0.0
    gx = 0.0
    gy = 0.0
    wb = 0.0
    r0 = 0.0
    r1 = 0.0
    for i in range(n):
        if i == ref:
            continue
        rx = axy[i, 0] - ax
        ry = axy[i, 1] - ay
        hx = 2.0 * rx                                     # H of eq. 2
        hy = 2.0 * ry
        d2 = d[i] * d[i]
        w = 1.0 / (d2 * d2)
        b = (rx * rx + ry * ry) - d2 + dr2                # b~ of eq. 2
        i00 += w * hx * hx
        i01 += w * hx * hy
        i11 += w * hy * hy
        gx += w * hx
        gy += w * hy
        wb += w * b
        r0 += w * b * hx
        r1 += w * b * hy
    i00 -= k * gx * gx
    i01 -= k * gx * gy
    i11 -= k * gy * gy
    r0 -= k * gx * wb
    r1 -= k * gy * wb
    det = i00 * i11 - i01 * i01
    tr = i00 + i11
    disc = math.sqrt(max(0.25 * tr * tr - det, 0.0))
    lam_min = 0.5 * tr - disc
    lam_max = 0.5 * tr + disc
    # (det > 0: with anchors a few ulps apart the eigenvalues pass but det underflows)
    if not lam_min > 0.0 or lam_max / lam_min > 1e12 or not det > 0.0:
        return False
    v00 = i11 / det
    v01 = -i01 / det
    v11 = i00 / det
    out[0] = v00 * r0 + v01 * r1 + ax                    # (H^T S^-1 H)^-1 H^T S^-1 b
    out[1] = v01 * r0 + v11 * r1 + ay
    f = 4.0 * sigma_ln * sigma_ln
    out[2] = f * v00
    out[3] = f * v01
    out[4] = f * v11
    return bool(np.all(np.isfinite(out)))


@njit(cache=True, error_model="numpy")
def scan_fix(model: np.record, axy: FloatArray, rss_dbm: FloatArray, count: FloatArray,
             out: FloatArray) -> int:  # pragma: no cover - compiled
    """Eq. 1 distances of a scan's mean RSS, then eq. 2 (nearest reference) into ``out``.

    ``model`` is a :data:`~hrtls.fusion.path_loss.PATH_LOSS_DTYPE` record; ``count`` the
    readings averaged per anchor (averaging n readings in dB shrinks the shadowing spread by
    ``sqrt(n)``, with n the mean count). Needs N >= 1 rows. Returns the reference anchor, or -1
    when the anchors are collinear.
    """
    n = rss_dbm.shape[0]
    d = np.empty(n)
    mean_count = 0.0
    for i in range(n):
        d[i] = model.d0_m * 10.0 ** ((model.a_dbm - rss_dbm[i]) / (10.0 * model.eta))
        mean_count += count[i]
    mean_count /= n
    sigma_ln = model.sigma_db * LN10 / (10.0 * model.eta) / math.sqrt(mean_count)
    ref = int(np.argmin(d))
    return ref if hyperbolic_wls_kernel(axy, d, sigma_ln, ref, out) else -1


def hyperbolic_wls(anchors_xy: ArrayLike, distances_m: ArrayLike, *,
                   sigma_ln: float = 0.5,
                   reference: Literal["nearest", "first"] = "nearest") -> WlsFix:
    """Weighted hyperbolic least-squares position (Tarrio eq. 2, see the module docstring).

    Parameters
    ----------
    anchors_xy:
        Anchor positions, m (N, 2), N >= 3, not collinear.
    distances_m:
        Estimated distances, m (N,), > 0.
    sigma_ln:
        Standard deviation of ``ln d`` (scales the covariance only).
    reference:
        Anchor whose circle is subtracted: the one with the smallest distance (default) or the
        first one, as the paper writes eq. 2.
    """
    a = np.asarray(anchors_xy, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise InputError(f"shape {a.shape}", where="hyperbolic_wls anchors_xy",
                         expected="finite (N, 2) anchor positions")
    d = finite_vector(distances_m, where="hyperbolic_wls distances_m", length=a.shape[0])
    if a.shape[0] < 3:
        raise InputError(f"{a.shape[0]} anchors", where="hyperbolic_wls",
                         expected="at least 3 anchors")
    if np.any(d <= 0.0):
        raise InputError("distance <= 0", where="hyperbolic_wls distances_m",
                         expected="positive distances")
    if reference not in ("nearest", "first"):
        raise InputError(f"reference {reference!r}", where="hyperbolic_wls",
                         expected="'nearest' or 'first'")
    ref = int(np.argmin(d)) if reference == "nearest" else 0
    out = np.empty(5)
    if not hyperbolic_wls_kernel(np.ascontiguousarray(a), d,
                                 finite_scalar(sigma_ln, where="hyperbolic_wls sigma_ln"),
                                 ref, out):
        raise InputError("anchors are collinear", where="hyperbolic_wls",
                         expected="anchors spanning the plane")
    return WlsFix(out[:2].copy(), np.array([[out[2], out[3]], [out[3], out[4]]]), ref)


# ------------------------------------------------------------------------------------------
# scans: readings grouped per localization period
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, eq=False)
class RssScan:
    """Readings of one localization period, averaged per anchor (dB domain)."""

    t: float
    anchor: list[str]
    anchor_xyz: FloatArray
    rss_dbm: FloatArray
    count: FloatArray
    unknown: list[str] = field(default_factory=list)


@dataclass(frozen=True, slots=True, eq=False)
class ScanTable:
    """Scans as columns (what :func:`group_scans` returns, without per-scan objects).

    Attributes
    ----------
    t: scan times, s (S,). first, count: rows of each scan in the row columns (S,).
    anchor: anchor id per row (M,). anchor_xyz: its position, m (M, 3). rss_dbm: mean RSS per
    row, dBm (M,). n_readings: readings averaged per row (M,). unknown: per scan, the anchors
    heard without a known position.
    """

    t: FloatArray
    first: NDArray[np.int64]
    count: NDArray[np.int64]
    anchor: NDArray[np.str_]
    anchor_xyz: FloatArray
    rss_dbm: FloatArray
    n_readings: FloatArray
    unknown: list[list[str]]

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def scans(self) -> list[RssScan]:
        """One :class:`RssScan` per scan."""
        out: list[RssScan] = []
        for i in range(len(self)):
            a, b = int(self.first[i]), int(self.first[i] + self.count[i])
            out.append(RssScan(float(self.t[i]), self.anchor[a:b].tolist(),
                               self.anchor_xyz[a:b].copy(), self.rss_dbm[a:b].copy(),
                               self.n_readings[a:b].copy(), list(self.unknown[i])))
        return out


def scan_table(rss: RssReadings, landmarks: dict[str, Landmark], *, window_s: float,
               sensitivity_dbm: float = -95.0, t_origin: float | None = None) -> ScanTable:
    """:func:`group_scans` vectorized: the scans as columns (same windows, order and means)."""
    w = finite_scalar(window_s, where="group_scans window_s", positive=True)
    empty = ScanTable(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64),
                      np.zeros(0, dtype=str), np.zeros((0, 3)), np.zeros(0), np.zeros(0), [])
    if len(rss) == 0:
        return empty
    t0 = float(rss.t[0]) if t_origin is None else float(t_origin)
    keep = rss.rss_dbm >= sensitivity_dbm
    tt, ids, vals = rss.t[keep], rss.anchor[keep], rss.rss_dbm[keep]
    if tt.size == 0:
        return empty
    bins = np.floor((tt - t0) / w).astype(np.int64)
    # consecutive readings in one window form a scan; its time is that of its last reading
    grp = np.zeros(tt.size, dtype=np.int64)
    grp[1:] = np.cumsum(np.diff(bins) != 0)
    n_scans = int(grp[-1]) + 1
    last = np.flatnonzero(np.append(np.diff(grp) != 0, True))
    names, a_idx = np.unique(ids, return_inverse=True)
    key = grp * len(names) + a_idx.astype(np.int64)
    uk, inv = np.unique(key, return_inverse=True)   # by scan, then by anchor name
    sums = np.bincount(inv, weights=vals, minlength=len(uk))
    counts = np.bincount(inv, minlength=len(uk)).astype(np.float64)
    row_scan = uk // len(names)
    row_name = uk % len(names)
    xyz_of = np.full((len(names), 3), np.nan)
    known_name = np.zeros(len(names), dtype=bool)
    for j, name in enumerate(names.tolist()):
        lm = landmarks.get(str(name))
        if lm is not None and lm.position is not None:
            known_name[j] = True
            xyz_of[j] = lm.xyz()
    known = known_name[row_name]
    unknown: list[list[str]] = [[] for _ in range(n_scans)]
    for i in np.flatnonzero(~known).tolist():
        unknown[int(row_scan[i])].append(str(names[row_name[i]]))
    ks, kn = row_scan[known], row_name[known]
    first = np.searchsorted(ks, np.arange(n_scans), side="left").astype(np.int64)
    count = (np.searchsorted(ks, np.arange(n_scans), side="right") - first).astype(np.int64)
    return ScanTable(tt[last].astype(np.float64), first, count, names[kn].astype(str),
                     xyz_of[kn], sums[known] / counts[known], counts[known], unknown)


def group_scans(rss: RssReadings, landmarks: dict[str, Landmark], *, window_s: float,
                sensitivity_dbm: float = -95.0, t_origin: float | None = None) -> list[RssScan]:
    """Average the readings of each anchor over consecutive windows of ``window_s`` seconds.

    Readings below ``sensitivity_dbm`` are dropped (Tarrio Sec. IV); a scan's time is that of
    its last reading (the position can be computed then); anchors without a known position are
    listed in ``unknown``.
    """
    return scan_table(rss, landmarks, window_s=window_s, sensitivity_dbm=sensitivity_dbm,
                      t_origin=t_origin).scans()


def scan_position(scan: RssScan, model: PathLossModel) -> WlsFix:
    """Eq. 1 + eq. 2 on one scan (raises :class:`InputError` with < 3 anchors or collinear)."""
    n = len(scan.anchor_xyz)
    if n < 3:
        raise InputError(f"{n} anchors", where="hyperbolic_wls", expected="at least 3 anchors")
    out = np.empty(5)
    axy = np.ascontiguousarray(scan.anchor_xyz[:, :2], dtype=np.float64)
    ref = scan_fix(model.record()[0], axy, np.asarray(scan.rss_dbm, dtype=np.float64),
                   np.asarray(scan.count, dtype=np.float64), out)
    if ref < 0:
        raise InputError("anchors are collinear", where="hyperbolic_wls",
                         expected="anchors spanning the plane")
    return WlsFix(out[:2].copy(), np.array([[out[2], out[3]], [out[3], out[4]]]), ref)


def average_rss_per_anchor(rss: RssReadings, window_s: float, *,
                           t_origin: float | None = None) -> RssReadings:
    """One reading per anchor and window: the mean (dBm) of its readings in that window.

    Windows are ``[t_origin + i w, t_origin + (i + 1) w)`` (``t_origin``: the first reading
    when None); each mean is stamped with the time of the last reading it contains (it is
    known by then). Consecutive readings of one beacon share their shadowing error; averaging
    keeps them from entering the filter as independent measurements. Output in time order
    (ties: anchor name).
    """
    if not (math.isfinite(window_s) and window_s > 0):
        raise InputError(f"{window_s}", where="window_s", expected="a positive window (s)")
    if len(rss) == 0:
        return rss
    origin = float(rss.t[0]) if t_origin is None else float(t_origin)
    if not math.isfinite(origin) or origin > float(rss.t.min()):
        raise InputError(f"{t_origin}", where="t_origin",
                         expected="a finite time at or before the first reading")
    anchors, a_idx = np.unique(rss.anchor, return_inverse=True)
    bins = np.floor((rss.t - origin) / window_s).astype(np.int64)
    n_bins = int(bins.max()) + 1
    keys = a_idx.astype(np.int64) * n_bins + bins
    uniq, inv = np.unique(keys, return_inverse=True)
    mean = np.bincount(inv, weights=rss.rss_dbm) / np.bincount(inv)
    t_last = np.full(uniq.shape[0], -np.inf)
    np.maximum.at(t_last, inv, rss.t)
    anchor = anchors[uniq // n_bins]
    order = np.lexsort((anchor, t_last))
    return RssReadings(t_last[order], anchor[order], mean[order], rss.name)
