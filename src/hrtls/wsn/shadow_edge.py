"""Shadow-edge localization algorithm (SELA), Inderst thesis Sec. 5.2.

A node linked to only two localized nodes ``h, k`` has two admissible positions, the
intersections of the circles of radius ``d_ih`` and ``d_ik`` (Definition 1). Under the disk model
the node hears every node within ``rho``; so if a localized node ``j`` that it does *not* hear lies
within ``rho`` of one candidate, that candidate is impossible and ``(i, j)`` is a shadow edge.
SELA applies trilateration where it can and shadow edges where trilateration cannot, starting from
the same seeds as TLA, hence it localizes a superset of TLA (Corollary 2).

Distributed in spirit (Remark 1): a node decides with its own ranges, the positions of its
localized one-hop neighbours and the positions of *their* localized neighbours (two-hop
information). Witnesses are the localized neighbours of either ``h`` or ``k`` (Definition 1 asks
for neighbours of both; accepting either is still a valid disk-model argument and is a superset).
When both candidates are ruled out the node is flagged inconsistent and left unlocalized; when
neither is, it stays ambiguous. A node is never placed at a guessed candidate.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.wsn._propagation import _circle_candidates
from hrtls.wsn.network import Network
from hrtls.wsn.trilateration import Localization, PropagationParams, propagate, seeds_of

FloatArray = NDArray[np.float64]


def shadow_edge_localize(
    net: Network, *, params: PropagationParams | None = None
) -> Localization:
    """SELA from the network's anchors (trilateration first, shadow edges where it cannot)."""
    pos, loc = seeds_of(net)
    return propagate(net.n_nodes, net.adjacency, net.radius_m, positions_m=pos, localized=loc,
                     use_shadow=True, params=params)


def circle_candidates(
    center_a_m: FloatArray, range_a_m: float, center_b_m: FloatArray, range_b_m: float,
    *, tolerance_m: float = 0.0,
) -> FloatArray:
    """The two admissible positions of a node with two ranges (Definition 1), ``(2, 2)``.

    Raises :class:`InputError` when the circles do not intersect (beyond ``tolerance_m``) or the
    centres coincide. Tangent circles give the same point twice.
    """
    a = np.asarray(center_a_m, dtype=np.float64).reshape(2)
    b = np.asarray(center_b_m, dtype=np.float64).reshape(2)
    ok, x1, y1, x2, y2 = _circle_candidates(float(a[0]), float(a[1]), float(range_a_m),
                                            float(b[0]), float(b[1]), float(range_b_m),
                                            float(tolerance_m))
    if not ok:
        raise InputError("circles do not intersect", where="circle_candidates",
                         expected="|r_a - r_b| <= |a - b| <= r_a + r_b and a != b")
    return np.array([[x1, y1], [x2, y2]])


__all__ = ["circle_candidates", "shadow_edge_localize"]
