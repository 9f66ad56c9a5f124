"""Whose errors are inside each agent's estimate and each node's: the mission's provenance.

An agent's estimate holds its own error and, once it used a node, the errors of the agents that
localized that node (their estimates at their readings are inside the node's estimate). With
``S(n)`` the agents whose errors are in node ``n`` and ``I(a)`` those in agent ``a``::

    I(a) = {a} at the start;   a reads n:  S(n) <- S(n) | I(a);   a uses n:  I(a) <- I(a) | S(n)

A use of ``n`` by ``a`` is *direct* when ``a`` read ``n`` itself (a loop closure), *second-order*
when ``a`` is in ``S(n)`` without having read ``n`` (A localizes n, B corrected by n localizes m,
A uses m), otherwise *independent*. The sets only grow (an error, once passed on, is not known
to have decayed), which makes the classes conservative. Every use is logged (:class:`NodeUse`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

USE_KINDS = ("independent", "second-order", "direct")
"""Classes of a use (module doc)."""


@dataclass(frozen=True, eq=False)
class NodeUse:
    """One agent's ranges to one node in one window, taken by its filter.

    ``t_s``: the first range's time; ``ranges``: how many; ``kind``: one of :data:`USE_KINDS`;
    ``position_m`` / ``covariance_m2``: the node's estimate the agent took (``(2,)``, ``(2, 2)``);
    ``sigma_m``: the widened range sigma of the window's last range.
    """

    t_s: float
    agent: int
    node: str
    kind: str
    ranges: int
    position_m: FloatArray
    covariance_m2: FloatArray
    sigma_m: float


@dataclass
class Provenance:
    """``I(a)`` per agent index, ``S(n)`` per node and the use log (module doc)."""

    inside_agent: dict[int, set[int]] = field(default_factory=dict)
    inside_node: dict[str, set[int]] = field(default_factory=dict)
    uses: list[NodeUse] = field(default_factory=list)

    def agent(self, i: int) -> set[int]:
        """``I(i)``."""
        return self.inside_agent.setdefault(i, {i})

    def node(self, node: str) -> set[int]:
        """``S(node)`` (empty before its first reading)."""
        return self.inside_node.get(node, set())

    def read(self, i: int, node: str) -> None:
        """Agent ``i`` gave readings of ``node``: ``S(n) <- S(n) | I(a)``."""
        self.inside_node.setdefault(node, set()).update(self.agent(i))

    def kind(self, i: int, node: str, *, contributor: bool) -> str:
        """Class of a use of ``node`` by agent ``i`` (``contributor``: ``i`` read it)."""
        if contributor:
            return "direct"
        return "second-order" if i in self.node(node) else "independent"

    def use(self, u: NodeUse) -> None:
        """Agent ``u.agent`` used ``u.node``: ``I(a) <- I(a) | S(n)``; the use logged."""
        self.agent(u.agent).update(self.node(u.node))
        self.uses.append(u)

    def state(self) -> dict[str, object]:
        """Plain values for :mod:`hrtls.mission.snapshot`."""
        return {"agents": [[i, sorted(s)] for i, s in self.inside_agent.items()],
                "nodes": {n: sorted(s) for n, s in self.inside_node.items()},
                "uses": [[u.t_s, u.agent, u.node, u.kind, u.ranges, u.position_m.tolist(),
                          u.covariance_m2.tolist(), u.sigma_m] for u in self.uses]}

    @classmethod
    def from_state(cls, d: dict[str, object]) -> Provenance:
        """Inverse of :meth:`state`."""
        agents = d["agents"]
        nodes = d["nodes"]
        uses = d["uses"]
        assert isinstance(agents, list) and isinstance(nodes, dict) and isinstance(uses, list)
        return cls({int(i): {int(x) for x in s} for i, s in agents},
                   {str(n): {int(x) for x in s} for n, s in nodes.items()},
                   [NodeUse(float(t), int(a), str(n), str(k), int(c), np.asarray(p, np.float64),
                            np.asarray(cv, np.float64), float(sg))
                    for t, a, n, k, c, p, cv, sg in uses])
