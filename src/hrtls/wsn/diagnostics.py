"""Why nodes stay unlocalized: the reasons a user can act on.

A node of the link graph is localized by propagation when it gets three ranges to localized
nodes (trilateration) or two and a shadow edge (SELA). Nodes that stay unlocalized fall in one of
three groups, each with its own remedy:

* ``unreachable``: no path of links leads from it to a localized node; no amount of propagation
  or loose-cooperation way points reaches it (a robot searching beyond links can, tight
  cooperation);
* ``inconsistent``: its ranges contradicted every candidate position (noisy ranges, a wrong
  anchor); the node was left out rather than placed wrongly;
* ``under_covered``: connected to the localized part but with fewer than three localized
  neighbours; a mobile agent standing near it adds the missing ranges (loose cooperation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrtls.wsn.network import Network, connected_components
from hrtls.wsn.trilateration import Localization

IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class UnlocalizedReasons:
    """Indices of the unlocalized real nodes, by reason (disjoint groups)."""

    unreachable: IntArray
    inconsistent: IntArray
    under_covered: IntArray

    @property
    def n_unlocalized(self) -> int:
        """Number of unlocalized nodes."""
        return int(self.unreachable.size + self.inconsistent.size + self.under_covered.size)


def unlocalized_reasons(net: Network, loc: Localization) -> UnlocalizedReasons:
    """Group the unlocalized nodes among the first ``net.n_nodes`` entries of ``loc``."""
    n = net.n_nodes
    localized = loc.localized[:n]
    labels = connected_components(net)
    seeded = np.zeros(int(labels.max()) + 1 if n else 0, dtype=bool)
    seeded[labels[localized]] = True
    unloc = ~localized
    unreachable = unloc & ~seeded[labels]
    bad = np.zeros(n, dtype=bool)
    inc = loc.inconsistent()
    bad[inc[inc < n]] = True
    inconsistent = unloc & ~unreachable & bad
    under = unloc & ~unreachable & ~inconsistent
    return UnlocalizedReasons(unreachable=np.flatnonzero(unreachable),
                              inconsistent=np.flatnonzero(inconsistent),
                              under_covered=np.flatnonzero(under))
