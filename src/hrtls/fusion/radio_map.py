"""Radio map: each anchor's RSS over the path-loss law, surveyed on a walk with known positions.

A *survey* is a list of readings taken at known horizontal positions (a walk along a measured
path, or points with a tape): per reading the position ``x_m``, ``y_m`` (the session's frame),
the anchor id and the RSS, dBm. The residual of a reading is its RSS minus the path-loss mean
at its position (the tracker's channel model, horizontal distance at least ``d0``).

On the grid filter's cells (:class:`hrtls.fusion.rss_grid.GridGeometry`) the map of an anchor
is a kernel regression of its residuals that shrinks to zero away from the survey: with
Gaussian weights ``k_i = exp(-|c - x_i|^2 / (2 l^2))`` (``l``: ``length_m``) and ``W = sum
k_i``, the map at cell ``c`` is ``sum k_i e_i / (W + n0)`` and its variance ``s0^2 n0 / (W +
n0)`` (``n0``: ``prior_readings``, ``s0``: ``prior_sigma_db``): where the survey holds many
readings within ``l`` the map is their mean and certain; far from it the map is 0 with the
prior variance. Readings are binned to their nearest cell first (readings off the grid are not
used), so ``W`` is exact to a cell. The grid filter adds the map to the mean RSS of every cell
and its variance to the likelihood's variance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hrtls.errors import InputError
from hrtls.fusion._checks import FloatArray, finite_scalar
from hrtls.fusion.path_loss import PathLossModel, mean_rss_dbm
from hrtls.fusion.rss_grid import GridGeometry

__all__ = ["RSS_RANGE_DBM", "SURVEY_COLUMNS", "RadioMapParams", "RadioSurvey",
           "kernel_sum", "residual_map"]

SURVEY_COLUMNS = ("x_m", "y_m", "anchor", "rss_dbm")
"""Columns of a survey CSV file (a header row with these names, in any order)."""
RSS_RANGE_DBM = (-130.0, 0.0)
"""Plausible RSS of a received beacon, dBm (values outside: wrong units, e.g. mW or dB)."""


@dataclass(frozen=True, kw_only=True)
class RadioMapParams:
    """The radio map (``[prediction.radio_map]``).

    Attributes
    ----------
    survey: path of the survey CSV file (:data:`SURVEY_COLUMNS`; relative: to the folder of
        the configuration file that names it, else to the working directory; empty: no map).
    length_m: length scale of the kernel regression, m.
    prior_sigma_db: spread of the residual where nothing is surveyed, dB.
    prior_readings: readings within ``length_m`` that weigh as much as the prior (``n0``).
    """

    survey: str = ""
    length_m: float = 4.0
    prior_sigma_db: float = 6.0
    prior_readings: float = 20.0

    def __post_init__(self) -> None:
        for name in ("length_m", "prior_readings"):
            finite_scalar(getattr(self, name), where=f"RadioMapParams.{name}", positive=True)
        finite_scalar(self.prior_sigma_db, where="RadioMapParams.prior_sigma_db",
                      non_negative=True)


@dataclass(frozen=True, slots=True, eq=False)
class RadioSurvey:
    """Readings at known positions: ``x_m``, ``y_m`` (N,), m; ``anchor`` (N,) ids; RSS, dBm.

    ``source`` names where they came from (the file), for error messages.
    """

    x_m: FloatArray
    y_m: FloatArray
    anchor: np.ndarray
    rss_dbm: FloatArray
    source: str = "survey"

    def __post_init__(self) -> None:
        n = len(self.rss_dbm)
        for name in ("x_m", "y_m", "anchor"):
            if len(getattr(self, name)) != n:
                raise InputError(f"{len(getattr(self, name))} values of {name!r}, {n} RSS",
                                 where=self.source, expected="one value per reading")
        for name in ("x_m", "y_m", "rss_dbm"):
            bad = np.flatnonzero(~np.isfinite(np.asarray(getattr(self, name), dtype=float)))
            if len(bad):
                raise InputError(f"{name!r} is not finite at reading {bad[0]}",
                                 where=self.source, expected="finite numbers")
        lo, hi = RSS_RANGE_DBM
        out = np.flatnonzero((self.rss_dbm < lo) | (self.rss_dbm > hi))
        if len(out):
            raise InputError(f"'rss_dbm' = {self.rss_dbm[out[0]]} at reading {out[0]}",
                             where=self.source, expected=f"dBm within [{lo:g}, {hi:g}]",
                             hint="wrong units?")


def kernel_sum(values: FloatArray, sigma_cells: float) -> FloatArray:
    """``sum_c' v[c'] exp(-|c - c'|^2 / (2 sigma^2))`` at every cell ``c`` of (A, ny, nx).

    Distances in cells; separable, truncated at 4 sigma; zero off the grid.
    """
    from scipy.ndimage import convolve1d  # only with a survey: `hrtls track` stays light

    h = max(math.ceil(4.0 * sigma_cells), 1)
    k = np.exp(-0.5 * (np.arange(-h, h + 1) / sigma_cells) ** 2)
    out = convolve1d(values, k, axis=1, mode="constant")
    return np.asarray(convolve1d(out, k, axis=2, mode="constant"), dtype=np.float64)


def residual_map(survey: RadioSurvey, *, anchor_ids: list[str], anchors_xy: FloatArray,
                 geometry: GridGeometry, model: PathLossModel,
                 params: RadioMapParams) -> tuple[FloatArray, FloatArray]:
    """Mean (dB) and variance (dB^2) of each anchor's residual on the cells: (A, ny, nx) each.

    Every survey anchor must be among ``anchor_ids``; an anchor without readings gets 0 and the
    prior variance everywhere.
    """
    index = {a: k for k, a in enumerate(anchor_ids)}
    unknown = sorted(set(survey.anchor.tolist()) - set(index))
    if unknown:
        raise InputError(f"anchor {unknown[0]!r} is not a positioned anchor of the session",
                         where=f"{survey.source} column 'anchor'",
                         expected=f"one of {', '.join(anchor_ids)}")
    a = np.array([index[x] for x in survey.anchor.tolist()], dtype=np.int64)
    xy = np.asarray(anchors_xy, dtype=np.float64).reshape(-1, 2)
    d = np.maximum(np.hypot(survey.x_m - xy[a, 0], survey.y_m - xy[a, 1]), model.d0_m)
    e = survey.rss_dbm - mean_rss_dbm(model.a_dbm, model.eta, model.d0_m, d)
    g = geometry
    j = np.rint((survey.x_m - g.x0_m) / g.cell_m).astype(np.int64)
    i = np.rint((survey.y_m - g.y0_m) / g.cell_m).astype(np.int64)
    on = (i >= 0) & (i < g.ny) & (j >= 0) & (j < g.nx)
    shape = (len(anchor_ids), g.ny, g.nx)
    sums = np.zeros(shape)
    counts = np.zeros(shape)
    np.add.at(sums, (a[on], i[on], j[on]), e[on])
    np.add.at(counts, (a[on], i[on], j[on]), 1.0)
    w = kernel_sum(counts, params.length_m / g.cell_m)
    s = kernel_sum(sums, params.length_m / g.cell_m)
    w = np.maximum(w, 0.0)
    n0 = params.prior_readings
    return s / (w + n0), params.prior_sigma_db ** 2 * n0 / (w + n0)
