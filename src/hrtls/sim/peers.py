"""Simulated inter-agent ranges (UWB between teammates and robots).

Each agent ranges to every other agent at ``rate_hz`` while both are in their sessions and
within ``max_range_m``, with the node radio model of :class:`hrtls.sim.infrastructure.RangeModel`
(Gaussian noise, exponential NLOS bias behind walls, dropouts), drawn by the same
:func:`hrtls.sim.infrastructure.draw_ranges` as node ranges. The readings go to the agent's
``ranges`` with the other agent's name as node id (``ranges.csv`` holds them like node ranges).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hrtls.data import Session
from hrtls.data.observations import RangeMeasurements
from hrtls.sim.infrastructure import RangeModel, draw_ranges


def _truth_at(session: Session, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Truth xy at ``t`` and whether ``t`` is inside the truth's span."""
    g = session.truth
    assert g is not None
    xy = np.column_stack([np.interp(t, g.t, g.xyz[:, 0]), np.interp(t, g.t, g.xyz[:, 1])])
    return xy, (t >= g.t[0]) & (t <= g.t[-1])


def peer_ranges(agents: dict[str, Session], model: RangeModel, rng: np.random.Generator
                ) -> dict[str, Session]:
    """The agents' sessions with their ranges to the other agents added (module doc)."""
    out: dict[str, Session] = {}
    for a, sa in agents.items():
        assert sa.truth is not None
        tq = np.arange(float(sa.truth.t[0]), float(sa.truth.t[-1]), 1.0 / model.rate_hz)
        tq = tq + rng.uniform(0.0, 1.0 / model.rate_hz)
        xa, _ = _truth_at(sa, tq)
        parts = [] if sa.ranges is None else [sa.ranges]
        for b, sb in agents.items():
            if b == a:
                continue
            xb, inside = _truth_at(sb, tq)
            d = np.linalg.norm(xa - xb, axis=1)
            got = draw_ranges(distance_m=d, from_xy_m=xa, to_xy_m=xb, model=model, rng=rng,
                              eligible=inside)
            n = len(got.range_m)
            if n == 0:
                continue
            parts.append(RangeMeasurements(tq[got.keep], np.full(n, b, dtype=object),
                                           got.range_m, got.sigma_m))
        if len(parts) <= (sa.ranges is not None):
            out[a] = sa
            continue
        t = np.concatenate([p.t for p in parts])
        o = np.argsort(t, kind="stable")
        node = np.concatenate([np.asarray(p.node, dtype=object) for p in parts])[o]
        merged = RangeMeasurements(t[o], node.astype(str),
                                   np.concatenate([p.range_m for p in parts])[o],
                                   np.concatenate([p.sigma_m for p in parts])[o])
        out[a] = dataclasses.replace(sa, ranges=merged)
    return out
