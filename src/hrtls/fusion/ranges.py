"""Range to a known radio node by EKF (Inderst thesis Sec. 4.3.3, eq. 4.34-4.35).

Expected measurement (eq. 4.34), the horizontal distance to node ``i`` at ``(x_i, y_i)``::

    h(p) = sqrt((x - x_i)^2 + (y - y_i)^2)

with Jacobian ``H = [(x - x_i)/h, (y - y_i)/h, 0, 0]``; the update of eq. 4.35 is the
compiled scalar Joseph update :func:`hrtls.fusion.gating.scalar_update` (NIS gate), called by
:func:`range_correction` on plain arrays (the tracker's event loop calls it too). With
``use_3d=True`` the slant range including ``z - z_i`` is used instead (the thesis works in the
plane).

Near the node the range carries no direction: when the predicted distance is below
``min_distance_m`` the reading is rejected (the Jacobian is undefined at 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements
from hrtls.fusion._checks import FloatArray, finite_scalar, finite_vector, probability
from hrtls.fusion.gating import (
    TOO_NEAR,
    UpdateDiagnostics,
    chi2_threshold,
    positioned_readings,
    rejected,
    scalar_diagnostics,
    scalar_update,
)
from hrtls.fusion.state import FilterState
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True)
class RangeParams:
    """Parameters of the range correction.

    Attributes
    ----------
    default_sigma_m:
        1-sigma of a reading whose own sigma is unknown (NaN), m (``V_j`` of eq. 4.35).
    min_distance_m:
        Predicted distances below this are not used (undefined direction).
    use_3d:
        Slant range with z instead of the planar range of eq. 4.34.
    gate_probability:
        Chi-square gate; None disables it.
    """

    default_sigma_m: float = 0.5
    min_distance_m: float = 0.1
    use_3d: bool = False
    gate_probability: float | None = 0.999

    def __post_init__(self) -> None:
        finite_scalar(self.default_sigma_m, where="RangeParams.default_sigma_m", positive=True)
        finite_scalar(self.min_distance_m, where="RangeParams.min_distance_m", positive=True)
        if self.gate_probability is not None:
            probability(self.gate_probability, where="RangeParams.gate_probability")


@dataclass(frozen=True, slots=True, eq=False)
class RangeUpdate:
    """New state and diagnostics of one range."""

    state: FilterState
    diagnostics: UpdateDiagnostics


@njit(cache=True, error_model="numpy")
def range_correction(x: FloatArray, p: FloatArray, node_x: float, node_y: float, node_z: float,
                     range_m: float, sigma_m: float, min_distance_m: float, threshold: float,
                     gated: bool, use_3d: bool
                     ) -> tuple[int, float, float, float]:  # pragma: no cover - compiled
    """Eq. 4.34-4.35 with one range on plain arrays, in place.

    Returns ``(code, nis, S, nu)``: :data:`~hrtls.fusion.gating.TOO_NEAR` (state unchanged,
    NaNs) when the predicted distance is below ``min_distance_m``, else the outcome of
    :func:`~hrtls.fusion.gating.scalar_update`.
    """
    dx = x[0] - node_x
    dy = x[1] - node_y
    if use_3d:
        dz = x[2] - node_z
        pred = math.sqrt(dx * dx + dy * dy + dz * dz)                 # eq. 4.34
    else:
        dz = 0.0
        pred = math.sqrt(dx * dx + dy * dy)
    if pred < min_distance_m:
        return TOO_NEAR, math.nan, math.nan, math.nan
    nu = range_m - pred
    code, nis, s = scalar_update(x, p, (dx / pred, dy / pred, dz / pred, 0.0),
                                 sigma_m * sigma_m, nu, threshold, gated)   # eq. 4.35
    return code, nis, s, nu


def range_update(state: FilterState, node_xyz: ArrayLike, range_m: float, sigma_m: float, *,
                 params: RangeParams | None = None, t: float | None = None, source: str = "",
                 kind: str = "range") -> RangeUpdate:
    """EKF update with one range (eq. 4.34-4.35).

    Parameters
    ----------
    state:
        Prior state at the reading's time.
    node_xyz:
        Node position, m (3,).
    range_m:
        Measured distance, m (>= 0).
    sigma_m:
        1-sigma of the distance, m (> 0; NaN uses ``default_sigma_m``).
    params:
        See :class:`RangeParams`.
    t, source, kind:
        Copied into the diagnostics (``t`` defaults to ``state.t``).
    """
    prm = params or RangeParams()
    node = finite_vector(node_xyz, where="range node_xyz", length=3)
    z = finite_scalar(range_m, where="range range_m", non_negative=True)
    sig = prm.default_sigma_m if not math.isfinite(float(sigma_m)) else finite_scalar(
        sigma_m, where="range sigma_m", positive=True)
    tt = state.t if t is None else float(t)
    gated = prm.gate_probability is not None
    threshold = chi2_threshold(1, prm.gate_probability) if prm.gate_probability is not None \
        else math.inf
    x, p = state.x.copy(), state.P.copy()
    code, nis, s, nu = range_correction(x, p, node[0], node[1], node[2], z, sig,
                                        prm.min_distance_m, threshold, gated, prm.use_3d)
    if code == TOO_NEAR:
        return RangeUpdate(state, rejected(kind, tt, "estimate on top of the node", source))
    diag = scalar_diagnostics(kind, tt, code, nis, s, nu, threshold, source)
    return RangeUpdate(state.evolve(x=x, P=p) if diag.accepted else state, diag)


def ranges_at(measurements: RangeMeasurements, t_from: float, t_to: float) -> np.ndarray:
    """Indices of the readings with ``t_from < t <= t_to`` (for interleaving with prediction)."""
    lo = int(np.searchsorted(measurements.t, t_from, side="right"))
    hi = int(np.searchsorted(measurements.t, t_to, side="right"))
    return np.arange(lo, hi)


def update_ranges(state: FilterState, measurements: RangeMeasurements, indices: ArrayLike,
                  landmarks: dict[str, Landmark], *, params: RangeParams | None = None
                  ) -> tuple[FilterState, list[UpdateDiagnostics]]:
    """Apply the readings ``indices`` one after the other (unknown nodes are skipped)."""
    diags: list[UpdateDiagnostics] = []
    for i, t, node_id, xyz in positioned_readings(indices, measurements.node, measurements.t,
                                                  landmarks, kind="range", what="node",
                                                  diagnostics=diags):
        upd = range_update(state, xyz, float(measurements.range_m[i]),
                           float(measurements.sigma_m[i]), params=params, t=t, source=node_id)
        state = upd.state
        diags.append(upd.diagnostics)
    return state, diags
