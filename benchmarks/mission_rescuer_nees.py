"""Rescuers' NEES without cooperation split by time since their latest tag read, along / across.

Runs the hybrid mission (door tags, one robot, 2 % ranges) with cooperation off and the
``rescue-mission`` preset (``--cfg`` overrides its tables, JSON), and splits every rescuer's
error at 1 Hz against the truth (read here, for scoring only): the 2-dof NEES per bin of the
time since the rescuer's latest tag read, and, while walking (true speed > 0.2 m/s), the 1-dof
NEES along and across the true walking direction with the mean square error and the mean
claimed variance on each axis, and the 1-dof NEES of the heading (state heading against the
true heading).

    python benchmarks/mission_rescuer_nees.py --seeds 0-9 \
        [--cfg '{"attitude": {"mag_heading": {"offset_model": "independent"}},
                 "prediction": {"sigma_heading_increment_rad": 0.02}}']
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from _engine import parse_seeds
from _mission_nees import time_bin
from hrtls.data.results import Trajectory
from hrtls.frames import wrap_angle
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline import preset
from hrtls.pipeline.config import TrackerConfig
from hrtls.sim.mission import Mission, MissionOptions, inderst_hybrid_mission

BINS_S = (2.0, 5.0, 15.0, 30.0, 60.0)
COLUMNS = ("nees", "n", "along_nees", "cross_nees", "moving", "along_mse", "cross_mse",
           "along_var", "cross_var", "heading_nees")


def bin_label(dt: float) -> str:
    """Bin of the time since the latest tag read, s."""
    lo, hi = time_bin(dt, BINS_S)
    return f"{lo:g}-{hi:g} s" if math.isfinite(hi) else f">= {lo:g} s (or none yet)"


def rescuer_terms(mission: Mission, name: str, tr: Trajectory
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per 1 Hz sample: the ``COLUMNS`` terms, the time since the latest tag read, the error."""
    sess = mission.simulations[name].session
    truth = sess.truth
    assert truth is not None and truth.heading_rad is not None
    t, xy, cov = tr.t, tr.xyz[:, :2], tr.cov_xy
    tq = np.arange(float(t[0]), float(t[-1]), 1.0)
    d = np.column_stack([np.interp(tq, t, xy[:, k]) - np.interp(tq, truth.t, truth.xyz[:, k])
                         for k in (0, 1)])
    p = cov[np.clip(np.searchsorted(t, tq), 0, len(t) - 1)]
    v = np.column_stack([np.interp(tq + 1.0, truth.t, truth.xyz[:, k])
                         - np.interp(tq - 1.0, truth.t, truth.xyz[:, k]) for k in (0, 1)])
    moving = (np.hypot(v[:, 0], v[:, 1]) > 0.4).astype(float)
    h = np.arctan2(v[:, 1], v[:, 0])
    u = np.column_stack([np.cos(h), np.sin(h)])
    w = np.column_stack([-np.sin(h), np.cos(h)])
    ea, ec = np.einsum("ki,ki->k", u, d), np.einsum("ki,ki->k", w, d)
    pa, pc = np.einsum("ki,kij,kj->k", u, p, u), np.einsum("ki,kij,kj->k", w, p, w)
    nees = np.einsum("ki,kij,kj->k", d, np.linalg.inv(p), d)
    j = np.clip(np.searchsorted(t, tq), 0, len(t) - 1)
    dh = wrap_angle(tr.heading_rad[j] - np.interp(tq, truth.t, np.unwrap(truth.heading_rad)))
    terms = np.column_stack([nees, np.ones_like(nees), moving * ea ** 2 / pa,
                             moving * ec ** 2 / pc, moving, moving * ea ** 2, moving * ec ** 2,
                             moving * pa, moving * pc, moving * dh ** 2 / tr.var_heading[j]])
    tags = sess.tags.t if sess.tags is not None else np.zeros(0)
    k = np.searchsorted(tags, tq, side="right")
    since = np.where(k > 0, tq - tags[np.maximum(k - 1, 0)], np.inf)
    return terms, since, np.hypot(d[:, 0], d[:, 1])


def run_seed(seed: int, config: TrackerConfig, acc: dict[str, np.ndarray]
             ) -> tuple[float, float]:
    """Adds the seed's terms to ``acc``; its rescuers' p90 error (m) and mean NEES."""
    mission = inderst_hybrid_mission(seed, MissionOptions(range_sigma_fraction=0.02))
    res = MissionTracker(mission.agents, params=MissionParams(cooperate=False),
                         kinds=mission.kinds, config=config).run()
    errs, nees = [], []
    for name, agent in res.agents.items():
        if mission.kinds[name] != "rescuer":
            continue
        tr = agent.trajectory
        terms, since, err = rescuer_terms(mission, name, tr)
        errs.append(err)
        nees.append(terms[:, 0])
        labels = np.array([bin_label(float(s)) for s in since])
        for lab in ("all", *sorted(set(labels))):
            rows = terms if lab == "all" else terms[labels == lab]
            acc.setdefault(lab, np.zeros(len(COLUMNS)))
            acc[lab] += rows.sum(axis=0)
    return (float(np.percentile(np.concatenate(errs), 90)),
            float(np.mean(np.concatenate(nees))))


def table(acc: dict[str, np.ndarray]) -> str:
    """Markdown table of the pooled split."""
    lines = ["| since tag read | NEES (2 dof) | share | along NEES (1 dof) | across NEES (1 dof) "
             "| along: mse / claimed variance, m^2 | across: mse / claimed variance, m^2 "
             "| heading NEES (1 dof) |",
             "|---|---|---|---|---|---|---|---|"]
    total = acc["all"][1]
    for lab in sorted(acc, key=lambda s: (s != "all", float(s.split("-")[0].strip(">= s")
                                                              .split()[0]) if s != "all" else 0)):
        a = dict(zip(COLUMNS, acc[lab], strict=True))
        m = max(a["moving"], 1.0)
        lines.append(f"| {lab} | {a['nees'] / a['n']:.2f} | {a['n'] / total:.2f} | "
                     f"{a['along_nees'] / m:.2f} | {a['cross_nees'] / m:.2f} | "
                     f"{a['along_mse'] / m:.2f} / {a['along_var'] / m:.2f} | "
                     f"{a['cross_mse'] / m:.2f} / {a['cross_var'] / m:.2f} | "
                     f"{a['heading_nees'] / m:.2f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--cfg", default="{}", help="JSON tables merged into the preset's")
    args = ap.parse_args()
    cfg = preset("rescue-mission").model_dump()
    for section, values in json.loads(args.cfg).items():
        cfg[section].update(values)
    config = TrackerConfig.model_validate(cfg)
    acc: dict[str, np.ndarray] = {}
    p90, nees = [], []
    for seed in parse_seeds(args.seeds):
        a, b = run_seed(seed, config, acc)
        p90.append(a)
        nees.append(b)
        print(f"seed {seed}: rescuer p90 {a:.2f} m, NEES {b:.2f}", flush=True)
    print(table(acc))
    p, n = np.array(p90), np.array(nees)
    print(f"rescuer p90 (mean / p90 / worst over seeds) {p.mean():.2f} / "
          f"{np.percentile(p, 90):.2f} / {p.max():.2f} m; NEES {n.mean():.2f} / "
          f"{np.percentile(n, 90):.2f} / {n.max():.2f}")


if __name__ == "__main__":
    main()
