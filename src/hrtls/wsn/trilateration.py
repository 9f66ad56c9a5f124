"""Trilateration propagation (TLA), Inderst thesis Sec. 3.5.

A node that knows its distances to >= 3 localized, non-collinear neighbours computes its position
(least squares when there are more than three) and becomes localized itself; localization spreads
from the seeds until nothing changes. The propagation is queue based (see
:mod:`hrtls.wsn._propagation`): a node is examined again only when a neighbour is localized.

This module also defines what TLA and SELA share: the parameters, the result and the array-level
entry point :func:`propagate`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.wsn._propagation import (
    M_AGENT,
    M_ANCHOR,
    M_SHADOW,
    M_UNLOCALIZED,
    STATUS_NAMES,
    _lls_gn,
    _min_spread,
    propagate_kernel,
)
from hrtls.wsn.network import METHOD_NAMES, Adjacency, Network

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, kw_only=True)
class PropagationParams:
    """Tolerances of TLA / SELA, as fractions of the communication radius ``rho``.

    Attributes
    ----------
    range_tolerance_fraction:
        Largest accepted |range residual| of a placed node (and of a shadow-edge candidate against
        the other localized neighbours). Exact ranges: tiny; noisy ranges: a few sigma.
    flip_tolerance_fraction:
        A trilateration fix is flip-ambiguous when its reflection across the line of two
        neighbours fits every range within this tolerance (default: ``range_tolerance_fraction``);
        such a node is left to the shadow-edge rule.
    range_sigma_fraction:
        Standard deviation of a range of length ``rho``, as a fraction of ``rho`` (0 = exact).
        Each placed node gets a propagated standard deviation ``sigma_i = GDOP *
        sqrt(sigma_range^2 + max sigma_neighbour^2)``; the residual, flip and shadow tolerances
        of a node grow by 4 (3) times the largest ``sigma`` of the nodes it uses.
    max_sigma_fraction:
        A node whose propagated ``sigma`` would exceed this times ``rho`` is left unlocalized
        (status ``uncertain``): error accumulation along long chains stops instead of turning
        into wrong placements (graceful degradation with noisy ranges).
    max_gdop:
        Largest accepted geometric dilution of precision of a fix (position sigma / range
        sigma); ``inf`` accepts any geometry that passes the spread check.
    min_spread_fraction:
        Non-collinearity check of trilateration: RMS distance of the localized neighbours from
        their best-fit line must be at least this times ``rho``.
    shadow_margin_fraction:
        A candidate is ruled out by a non-linked localized node only when it is closer than
        ``rho * (1 - shadow_margin_fraction)`` to it (guards the disk-model boundary).
    """

    range_tolerance_fraction: float = 1e-7
    min_spread_fraction: float = 1e-3
    shadow_margin_fraction: float = 1e-7
    max_gdop: float = 1e4
    flip_tolerance_fraction: float | None = None
    range_sigma_fraction: float = 0.0
    max_sigma_fraction: float = float("inf")

    def __post_init__(self) -> None:
        if not self.max_gdop > 0:
            raise InputError(f"max_gdop = {self.max_gdop}", where="PropagationParams",
                             expected="a positive number (inf = no limit)")
        if not (self.max_sigma_fraction > 0):
            raise InputError(f"max_sigma_fraction = {self.max_sigma_fraction}",
                             where="PropagationParams", expected="> 0 (inf = no limit)")
        for name in ("range_tolerance_fraction", "min_spread_fraction", "shadow_margin_fraction",
                     "range_sigma_fraction"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 <= v < 1.0):
                raise InputError(f"{name} = {v}", where="PropagationParams",
                                 expected="a number in [0, 1)")

    @property
    def flip_tolerance(self) -> float:
        """Flip tolerance as a fraction of rho."""
        if self.flip_tolerance_fraction is None:
            return self.range_tolerance_fraction
        return self.flip_tolerance_fraction

    @classmethod
    def for_noise(cls, range_noise_fraction: float) -> PropagationParams:
        """Tolerances for ranges with relative noise ``range_noise_fraction`` (e.g. 0.02).

        Residual (and flip) tolerance 6 sigma of a range of length ``rho``, shadow margin
        3 sigma, spread 0.1 rho, GDOP <= 2.5 (noisy ranges need good geometry), propagated node
        sigma at most 0.15 rho.
        """
        s = float(range_noise_fraction)
        if s <= 0:
            return cls()
        return cls(range_tolerance_fraction=min(0.5, 6.0 * s),
                   min_spread_fraction=0.1,
                   shadow_margin_fraction=min(0.5, 3.0 * s),
                   max_gdop=2.5, range_sigma_fraction=s, max_sigma_fraction=0.15)


@dataclass(frozen=True, eq=False)
class Localization:
    """Result of TLA / SELA (and of the agent-assisted algorithms).

    Attributes
    ----------
    estimate_m:
        ``(n, 2)`` positions (meaningful where ``localized``; zeros elsewhere).
    localized:
        ``(n,)`` mask of localized nodes (anchors included).
    method:
        ``(n,)`` method codes, names in :data:`hrtls.wsn.network.METHOD_NAMES`.
    status:
        ``(n,)`` why a node is unlocalized (``STATUS_NAMES``): too few localized neighbours,
        collinear neighbours (or too large GDOP), ambiguous candidates (two candidates survive, or
        a flip-ambiguous trilateration), inconsistent candidates/residuals, or uncertain (its
        propagated sigma would exceed ``max_sigma_fraction``).
    witness:
        ``(n,)`` for shadow-edge nodes the localized node that ruled out the other candidate (the
        shadow edge is ``(i, witness[i])``), else -1.
    order:
        Indices of the nodes localized by the propagation, in the order they were placed.
    sigma_m:
        ``(n,)`` propagated position standard deviation (0 for seeds and with exact ranges;
        see ``PropagationParams.range_sigma_fraction``); the refinement gives the full
        covariance.
    """

    estimate_m: FloatArray
    localized: BoolArray
    method: NDArray[np.int8]
    status: NDArray[np.int8]
    witness: IntArray
    order: IntArray
    sigma_m: FloatArray

    @property
    def method_names(self) -> list[str]:
        """Method name of every node."""
        return [METHOD_NAMES[int(m)] for m in self.method]

    @property
    def status_names(self) -> list[str]:
        """Status name of every node."""
        return [STATUS_NAMES[int(s)] for s in self.status]

    @property
    def shadow_edges(self) -> IntArray:
        """``(s, 2)`` shadow edges ``(node, witness)`` used to place shadow-edge nodes."""
        i = np.flatnonzero((self.method == M_SHADOW) & (self.witness >= 0))
        return np.stack([i, self.witness[i]], axis=1).astype(np.int64)

    @property
    def n_localized(self) -> int:
        """Number of localized nodes."""
        return int(np.count_nonzero(self.localized))

    def inconsistent(self) -> IntArray:
        """Indices of unlocalized nodes whose candidates or residuals were inconsistent."""
        return np.flatnonzero(~self.localized & (self.status == 4))


def propagate(
    n_nodes: int,
    adjacency: Adjacency,
    radius_m: float,
    *,
    positions_m: FloatArray,
    localized: BoolArray,
    method: NDArray[np.int8] | None = None,
    use_shadow: bool,
    params: PropagationParams | None = None,
    initial_sigma_m: FloatArray | None = None,
) -> Localization:
    """Array-level TLA (``use_shadow=False``) or SELA (``True``) from an initial localized set.

    ``positions_m`` must be valid where ``localized`` is True; ``method`` gives the codes of the
    initially localized nodes (default: anchor); ``initial_sigma_m`` their position standard
    deviation (default 0).
    """
    prm = params or PropagationParams()
    pos = np.array(positions_m, dtype=np.float64, copy=True).reshape(n_nodes, 2)
    loc = np.array(localized, dtype=np.bool_, copy=True).reshape(n_nodes)
    if not np.all(np.isfinite(pos[loc])):
        raise InputError("non-finite position of a localized node", where="propagate",
                         expected="finite seed positions")
    pos[~loc] = 0.0
    if method is None:
        meth = np.where(loc, M_ANCHOR, M_UNLOCALIZED).astype(np.int8)
    else:
        meth = np.array(method, dtype=np.int8, copy=True)
        meth[~loc] = M_UNLOCALIZED
    status = np.zeros(n_nodes, dtype=np.int8)
    witness = np.full(n_nodes, -1, dtype=np.int64)
    order = np.zeros(n_nodes, dtype=np.int64)
    rho = float(radius_m)
    sig = np.zeros(n_nodes)
    if initial_sigma_m is not None:
        sig[loc] = np.asarray(initial_sigma_m, dtype=np.float64).reshape(n_nodes)[loc]
    k = propagate_kernel(
        adjacency.indptr, adjacency.indices, adjacency.distance_m, pos, loc, meth, status,
        witness, order, 0, rho, bool(use_shadow), prm.range_tolerance_fraction * rho,
        prm.min_spread_fraction * rho, prm.shadow_margin_fraction * rho, float(prm.max_gdop),
        prm.flip_tolerance * rho, sig, prm.range_sigma_fraction * rho,
        prm.max_sigma_fraction * rho,
    )
    return Localization(estimate_m=pos, localized=loc, method=meth, status=status,
                        witness=witness, order=order[:k].copy(), sigma_m=sig)


def seeds_of(net: Network) -> tuple[FloatArray, BoolArray]:
    """Initial positions and mask from the network's anchors."""
    pos = np.where(net.anchor[:, None], net.position_m, 0.0)
    return pos, net.anchor.copy()


def trilaterate_network(net: Network, *, params: PropagationParams | None = None) -> Localization:
    """Trilateration propagation (TLA) from the network's anchors."""
    pos, loc = seeds_of(net)
    return propagate(net.n_nodes, net.adjacency, net.radius_m, positions_m=pos, localized=loc,
                     use_shadow=False, params=params)


def trilaterate(points_m: FloatArray, ranges_m: FloatArray) -> tuple[FloatArray, float]:
    """Least-squares position from >= 3 non-collinear points and ranges.

    Returns the position and the largest |range residual| (m).
    """
    p = np.asarray(points_m, dtype=np.float64)
    d = np.asarray(ranges_m, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3 or d.shape != (p.shape[0],):
        raise InputError(f"points {p.shape}, ranges {d.shape}", where="trilaterate",
                         expected="(k, 2) points and (k,) ranges with k >= 3")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(d))):
        raise InputError("non-finite input", where="trilaterate", expected="finite numbers")
    px = np.ascontiguousarray(p[:, 0])
    py = np.ascontiguousarray(p[:, 1])
    scale = float(np.max(np.ptp(p, axis=0)))
    if _min_spread(px, py, p.shape[0]) <= 1e-12 * max(scale, 1.0):
        raise InputError("points are collinear", where="trilaterate",
                         expected="three or more non-collinear points")
    x, y, worst = _lls_gn(px, py, d, p.shape[0])
    return np.array([x, y]), float(worst)


__all__ = [
    "M_AGENT",
    "Localization",
    "PropagationParams",
    "propagate",
    "seeds_of",
    "trilaterate",
    "trilaterate_network",
]
