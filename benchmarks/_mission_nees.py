"""Agents' NEES split by their uses of the mission's nodes (``benchmarks/mission.py --nees-split``).

Every agent's error at 1 Hz over its track (truth read here, for scoring only) and its NEES
(2 dof, expected 2) are put in bins of five splits, from the mission's use log
(:mod:`hrtls.mission.provenance`):

* ``since use``: time since the agent's latest range to a mission node taken by its filter;
* ``worst use``: the worst class of its uses so far (independent < second-order < direct);
* ``last node``: the NEES of the node's estimate the agent took at its latest use, against the
  chi-square 2-dof 95 % gate (the node's own error large against its claimed covariance);
* ``loop closures``: the uses of nodes the agent read itself, so far (none, 1, 2+);
* ``kind``: rescuer or robot;
* ``walked``: time since the agent's start, 100 s bins (its own filter's NEES changes along
  its walk with or without cooperation: the other splits are read against this one, and against
  the same bins with cooperation off).

:func:`nees_split` gives per bin the sum of the NEES and the number of samples; the table pools
them over the seeds (mean NEES per bin and its share of the samples).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from hrtls.mission.provenance import USE_KINDS
from hrtls.mission.tracker import MissionResult
from hrtls.sim.mission import Mission

SINCE_BINS_S = (5.0, 15.0, 30.0, 60.0)
NODE_GATE = float(chi2.ppf(0.95, 2))


def time_bin(dt: float, bins_s: tuple[float, ...]) -> tuple[float, float]:
    """Bounds ``(lo, hi)`` of the bin of ``dt`` among the upper edges ``bins_s`` (hi inf: last)."""
    lo = 0.0
    for hi in bins_s:
        if dt < hi:
            return lo, hi
        lo = hi
    return lo, math.inf


def since_label(dt: float) -> str:
    """Bin of the time since the latest use, s."""
    lo, hi = time_bin(dt, SINCE_BINS_S)
    return f"{lo:02g}-{hi:g} s" if math.isfinite(hi) else f">= {lo:g} s"


def _agent_nees(mission: Mission, name: str, result: MissionResult
                ) -> tuple[np.ndarray, np.ndarray]:
    truth = mission.simulations[name].session.truth
    assert truth is not None
    tr = result.agents[name].trajectory
    tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
    d = np.column_stack([np.interp(tq, tr.t, tr.xyz[:, k]) - np.interp(tq, truth.t, truth.xyz[:, k])
                         for k in (0, 1)])
    j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
    return tq, np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d)


def nees_split(mission: Mission, result: MissionResult) -> dict[str, list[float]]:
    """Per ``"split: bin"``, ``[sum of NEES, samples]`` over every agent's 1 Hz track."""
    out: dict[str, list[float]] = {}
    names = list(mission.agents)
    for i, name in enumerate(names):
        if name not in result.agents:
            continue
        tq, nees = _agent_nees(mission, name, result)
        uses = sorted((u for u in result.uses if u.agent == i), key=lambda u: u.t_s)
        t_use = np.array([u.t_s for u in uses])
        rank = np.array([USE_KINDS.index(u.kind) for u in uses], dtype=np.int64)
        node_nees = np.array([float((u.position_m - mission.node_truth_m[u.node]) @ np.linalg.solve(
            u.covariance_m2, u.position_m - mission.node_truth_m[u.node])) for u in uses])
        k = np.searchsorted(t_use, tq, side="right")          # uses at or before each sample
        worst = np.maximum.accumulate(rank) if len(rank) else rank
        closures = np.cumsum(rank == USE_KINDS.index("direct")) if len(rank) else rank
        kind = mission.kinds.get(name, "rescuer")
        for q, (t, v) in enumerate(zip(tq, nees, strict=True)):
            n = int(k[q])
            start = 100.0 * int((t - tq[0]) // 100.0)
            labels = [f"kind: {kind}", f"walked: {start:g}-{start + 100.0:g} s"]
            if n == 0:
                labels += ["since use: no use yet", "worst use: no use yet",
                           "last node: no use yet", "loop closures: none"]
            else:
                c = int(closures[n - 1])
                labels += [f"since use: {since_label(float(t - t_use[n - 1]))}",
                           f"worst use: {USE_KINDS[int(worst[n - 1])]}",
                           "last node: NEES " + ("<=" if node_nees[n - 1] <= NODE_GATE else ">")
                           + f" {NODE_GATE:.2f}",
                           "loop closures: " + ("none" if c == 0 else "1" if c == 1 else "2+")]
            for lab in labels:
                acc = out.setdefault(lab, [0.0, 0.0])
                acc[0] += float(v)
                acc[1] += 1.0
    return out


def nees_split_table(per_seed: list[dict[str, list[float]]]) -> str:
    """Markdown table: per bin the pooled mean NEES, its samples' share of the split, seeds."""
    pooled: dict[str, list[float]] = {}
    seeds: dict[str, int] = {}
    for d in per_seed:
        for lab, (s, n) in d.items():
            acc = pooled.setdefault(lab, [0.0, 0.0])
            acc[0] += s
            acc[1] += n
            seeds[lab] = seeds.get(lab, 0) + 1
    totals: dict[str, float] = {}
    for lab, (_, n) in pooled.items():
        split = lab.split(":")[0]
        totals[split] = totals.get(split, 0.0) + n
    lines = ["| split: bin | agent NEES (mean) | share of samples | seeds |", "|---|---|---|---|"]
    for lab in sorted(pooled):
        s, n = pooled[lab]
        share = n / totals[lab.split(":")[0]]
        lines.append(f"| {lab} | {s / n:.2f} | {share:.2f} | {seeds[lab]} |")
    return "\n".join(lines)
