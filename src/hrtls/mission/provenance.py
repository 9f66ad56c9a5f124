"""Whose errors are inside each agent's estimate and each node's: the mission's provenance.

An agent's estimate holds its own error and, once it used a node, the errors of the agents that
localized that node (their estimates at their readings are inside the node's estimate). With
``S(n)`` the agents whose errors are in node ``n`` and ``I(a)`` those in agent ``a``::

    I(a) = {a} at the start;   a reads n:  S(n) <- S(n) | I(a);   a uses n:  I(a) <- I(a) | S(n)

A use of ``n`` by ``a`` is *direct* when ``a`` read ``n`` itself (a loop closure), *second-order*
when ``a`` is in ``S(n)`` without having read ``n`` (A localizes n, B corrected by n localizes m,
A uses m), otherwise *independent*. The sets only grow (an error, once passed on, is not known
to have decayed), which makes the classes conservative. Every use is logged (:class:`NodeUse`).

Information of a pass (:func:`pool_factor`). Scalar model: agent error ``e_x`` (variance ``P``)
independent of the node; its filter takes ranges ``z_k = x + e_k + v_k`` with node errors ``e_k``
of any correlation (``var e_k <= P_k``, covariance ``C``; over one pass by one node they are all
the same error) and range noise ``v_k`` (``s^2``) as independent, with variances
``R_k = s^2 + a_k P_k``, weights ``w_k = 1 / R_k``. It claims ``1 / (1/P + sum w)``; its error
``(e_x / P + sum w_k (e_k + v_k)) / (1/P + sum w)`` has the variance
``(1/P + w^T C w + s^2 sum w_k^2) / (1/P + sum w)^2``, at most the claim iff
``w^T C w + s^2 sum w_k^2 <= sum w_k``. Cauchy-Schwarz, twice::

    w^T C w <= (sum w_k sqrt(P_k))^2 <= (sum 1/a_k) (sum a_k P_k w_k^2)

so ``sum 1/a_k <= 1`` makes the left side at most ``sum w_k^2 (a_k P_k + s^2) = sum w_k``: the
claim is never below the truth. The ``m_j`` ranges of the pass's ``j``-th window get
``a = (N_{j-1} + 1)(N_j + 1)`` (``N_j`` the ranges used up to it): ``m_j / a = 1/(N_{j-1} + 1) -
1/(N_j + 1)`` telescopes to ``sum 1/a_k = 1 - 1/(N + 1)``. (The count of uses alone, ``a = N_j``,
sums to ``1 + 1/2 + ... + 1/J`` over ``J`` windows of a pass, about ``ln J + 0.58``: above 1 from
the second window on.) Passes of one agent by different nodes are taken as independent of each
other, as are passes separated by ``pass_gap_s`` (the agent's drift in between).

Information gate (:func:`informative`). A range from agent position ``x`` (covariance ``P_a``)
to node ``n`` (``P_n``) constrains ``u^T (x - n)``, ``u`` the unit line of sight, with the
variance ``u^T P_a u + u^T P_n u`` of its prior: the share of the range's correction that goes
to the agent is ``u^T P_a u / (u^T P_a u + u^T P_n u + s^2)``, and whatever part of the node's
error the claimed ``P_n`` misses (its correlation with the agent, an under-modelled node) is
passed on to the agent with that share. With ``u^T P_n u <= rho u^T P_a u`` the agent takes at
least ``1 / (1 + rho)`` of it (range noise aside) and the range is mostly about the agent;
beyond, the range is mostly about the node and goes to the node's estimate as a reading.
"""

from __future__ import annotations

import math
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


@dataclass(frozen=True)
class UsePool:
    """An agent's current pass by a node: time of its last used range, the ranges used in it."""

    t_last_s: float = -math.inf
    ranges: int = 0


def informative(node_m: FloatArray, node_cov_m2: FloatArray, agent_m: FloatArray,
                agent_cov_m2: FloatArray, *, ratio: float) -> bool:
    """Whether an agent at ``agent_m`` may take ranges to a node at ``node_m`` (module doc).

    True when the node's variance along the line of sight is at most ``ratio`` times the
    agent's (``ratio`` inf: always); at a common position, the largest variances are compared.
    """
    if math.isinf(ratio):
        return True
    d = np.asarray(node_m, np.float64)[:2] - np.asarray(agent_m, np.float64)[:2]
    norm = float(np.hypot(d[0], d[1]))
    if norm < 1e-9:
        var_n = float(np.linalg.eigvalsh(node_cov_m2)[-1])
        var_a = float(np.linalg.eigvalsh(agent_cov_m2)[-1])
    else:
        u = d / norm
        var_n, var_a = float(u @ node_cov_m2 @ u), float(u @ agent_cov_m2 @ u)
    return var_n <= ratio * var_a


def pool_factor(pool: UsePool, *, t_first_s: float, t_last_s: float, ranges: int,
                gap_s: float) -> tuple[UsePool, float]:
    """The pass after a window's ``ranges`` and the factor ``a`` of the node's variance.

    A new pass starts after a gap above ``gap_s``; ``a = (N_before + 1)(N_after + 1)`` (module
    doc).
    """
    if t_first_s - pool.t_last_s > gap_s:
        pool = UsePool()
    after = pool.ranges + ranges
    return UsePool(t_last_s, after), float((pool.ranges + 1) * (after + 1))


def widening(pool: UsePool, *, t_first_s: float, t_last_s: float, ranges: int, gap_s: float,
             kind: str, cap: bool) -> tuple[UsePool, float]:
    """The pass after a window's ``ranges`` to a node and the factor ``a c`` of its variance.

    ``cap``: ``a`` of :func:`pool_factor`, ``c`` 2 unless the use is independent; else the
    earlier rule, ``a = N_after`` (the uses in the pass), ``c`` 2 for a direct use only.
    """
    pool, a = pool_factor(pool, t_first_s=t_first_s, t_last_s=t_last_s, ranges=ranges,
                          gap_s=gap_s)
    if not cap:
        return pool, pool.ranges * (2.0 if kind == "direct" else 1.0)
    return pool, a * (1.0 if kind == "independent" else 2.0)


@dataclass
class Provenance:
    """``I(a)`` per agent index, ``S(n)`` per node and the use log (module doc)."""

    inside_agent: dict[int, set[int]] = field(default_factory=dict)
    inside_node: dict[str, set[int]] = field(default_factory=dict)
    uses: list[NodeUse] = field(default_factory=list)
    passes: dict[tuple[int, str], UsePool] = field(default_factory=dict)

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
                "passes": [[i, n, p.t_last_s, p.ranges] for (i, n), p in self.passes.items()],
                "uses": [[u.t_s, u.agent, u.node, u.kind, u.ranges, u.position_m.tolist(),
                          u.covariance_m2.tolist(), u.sigma_m] for u in self.uses]}

    @classmethod
    def from_state(cls, d: dict[str, object]) -> Provenance:
        """Inverse of :meth:`state`."""
        agents = d["agents"]
        nodes = d["nodes"]
        uses = d["uses"]
        passes = d["passes"]
        assert isinstance(agents, list) and isinstance(nodes, dict) and isinstance(uses, list)
        assert isinstance(passes, list)
        return cls({int(i): {int(x) for x in s} for i, s in agents},
                   {str(n): {int(x) for x in s} for n, s in nodes.items()},
                   [NodeUse(float(t), int(a), str(n), str(k), int(c), np.asarray(p, np.float64),
                            np.asarray(cv, np.float64), float(sg))
                    for t, a, n, k, c, p, cv, sg in uses],
                   {(int(i), str(n)): UsePool(float(t), int(c)) for i, n, t, c in passes})
