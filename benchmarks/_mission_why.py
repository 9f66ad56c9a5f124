"""Why a dropped node is not localized at the end of a simulated mission (scoring only).

Each node of a :class:`~hrtls.sim.mission.Mission` falls in one class, checked in this order:

* ``localized``: the mission tracker localized it (``localized, > 3 m off``: its error is above
  ``bad_m``, counted apart);
* ``never in range``: no agent's true track came within the radio's ``max_range_m`` of it;
* ``in range, no reading``: some agent passed within range, but no reading was kept;
* ``too few readings``: fewer than the estimator's ``min_ranges``;
* ``one straight pass / mirror``: the agents' positions are collinear, or a mirror solution
  explains the ranges about as well (geometry: a second bearing is missing);
* ``NLOS / pass gates``: the NLOS gate or the leave-one-pass-out check left too few readings;
* ``fit gate``: the kept readings are inconsistent with the solution;
* ``sigma too large``: above the estimator's ``max_sigma_m``;
* ``other``: anything else (singular geometry, no initial position).

For the nodes not localized but heard, the same readings placed at the agents' **true**
positions are solved again (``from true positions``): a node localized that way was lost to the
agents' own error, not to the readings' geometry; and ``rejected, within 3 m`` counts those whose
rejected solution lies within ``bad_m`` of the truth (a gate refused a good position).
"""

from __future__ import annotations

import numpy as np

from hrtls.mission.nodes import NodeEstimator, NodeRanges
from hrtls.mission.tracker import MissionResult, MissionTracker
from hrtls.sim.mission import Mission

CLASSES = ("localized", "localized, > 3 m off", "never in range", "in range, no reading",
           "too few readings", "one straight pass / mirror", "NLOS / pass gates", "fit gate",
           "sigma too large", "other")
EXTRA = ("from true positions", "rejected, within 3 m")


def reason_class(reason: str) -> str:
    """The class of an estimator's ``reason`` for a node with readings (module doc)."""
    if "ranges (needs" in reason:
        return "too few readings"
    if "collinear" in reason or "mirror" in reason:
        return "one straight pass / mirror"
    if "disagree" in reason or "NLOS gate" in reason:
        return "NLOS / pass gates"
    if "inconsistent" in reason:
        return "fit gate"
    if reason.startswith("sigma"):
        return "sigma too large"
    return "other"


def _closest_m(mission: Mission, xy: np.ndarray) -> float:
    best = np.inf
    for sim in mission.simulations.values():
        truth = sim.session.truth
        if truth is not None:
            best = min(best, float(np.min(np.hypot(*(truth.xyz[:, :2] - xy).T))))
    return best


def true_readings(mission: Mission, tracker: MissionTracker, node: str) -> NodeRanges:
    """The readings of ``node`` placed at the agents' true positions (zero covariance; scoring)."""
    rd = tracker.readings[node]
    obs = rd.ranges(tracker.params.pass_gap_s)
    ag, t = np.asarray(rd.agent), np.asarray(rd.t)
    xy = np.zeros((len(t), 2))
    for i, name in enumerate(tracker.names):
        truth = mission.simulations[name].session.truth
        assert truth is not None
        m = ag == i
        xy[m, 0] = np.interp(t[m], truth.t, truth.xyz[:, 0])
        xy[m, 1] = np.interp(t[m], truth.t, truth.xyz[:, 1])
    return NodeRanges.build(agent_xy_m=xy, agent_cov_m2=np.zeros((len(t), 2, 2)),
                            range_m=obs.range_m, range_sigma_m=obs.range_sigma_m,
                            group=obs.group, chain=obs.chain)


def why_not_localized(mission: Mission, tracker: MissionTracker, result: MissionResult, *,
                      bad_m: float = 3.0) -> dict[str, int]:
    """Nodes per class (module doc), plus the ``EXTRA`` counts of the nodes not localized."""
    out = dict.fromkeys((*CLASSES, *EXTRA), 0)
    est = NodeEstimator(tracker.params.nodes)
    for node, truth in mission.node_truth_m.items():
        e = result.nodes.get(node)
        if e is not None and e.localized:
            off = float(np.hypot(*(e.position_m - truth)))
            out["localized, > 3 m off" if off > bad_m else "localized"] += 1
            continue
        if e is None or node not in tracker.readings or not tracker.readings[node].r:
            near = _closest_m(mission, truth) <= mission.options.max_range_m
            out["in range, no reading" if near else "never in range"] += 1
            continue
        out[reason_class(e.reason)] += 1
        if np.all(np.isfinite(e.position_m)):
            out["rejected, within 3 m"] += float(np.hypot(*(e.position_m - truth))) <= bad_m
        out["from true positions"] += est.estimate(true_readings(mission, tracker,
                                                                  node)).localized
    return out


def why_table(rows: dict[str, list[dict[str, int]]]) -> str:
    """Markdown table: per class, nodes summed over seeds and their share, per column."""
    cols = list(rows)
    total = {c: sum(sum(v for k, v in d.items() if k in CLASSES) for d in rows[c])
             for c in cols}
    lines = ["| node class | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for k in (*CLASSES, *EXTRA):
        cells = []
        for c in cols:
            n = sum(d[k] for d in rows[c])
            cells.append(f"{n} ({n / max(total[c], 1):.2f})")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
