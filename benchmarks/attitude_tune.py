"""Leave-one-trial-out choice of the ``inertial-lp`` parameters (issue 13's tuning discipline).

Units: the BROAD trials in ``../shared/data/broad`` and the simulated walks of
``benchmarks/attitude.py`` (seeds 1-3, 300 s). A parameter set's score on a unit is
``(inc / inc_vqf + head / head_vqf) / 2`` (``--score mean``) or, the issue's target read as
"both no worse than VQF", ``max(inc / inc_vqf, head / head_vqf)`` (``--score worse``, the
default) (RMS in degrees as in ``benchmarks/attitude.py``,
VQF 9-D with its defaults on the same data as the yardstick). For every unit the grid point
with the best mean score over the *other* units is chosen and scored on the held-out unit;
the grid point best over all units is printed as a candidate for the defaults. Prints per-unit
held-out figures, their mean / median / worst, and the chosen sets::

    python benchmarks/attitude_tune.py            # the full grid (a few minutes)
    python benchmarks/attitude_tune.py --quick    # a smaller grid

The units run through ``--engine`` (``benchmarks/_engine.py``): each scores VQF and the whole
grid on its own data.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _engine import Batch, add_engine_options
from attitude import BROAD, DatasetItem, as_q_nb, load, vqf_runner
from hrtls.attitude import make_filter, orientation_errors
from hrtls.attitude.inertial_lowpass import InertialLowpassParams

GRID: dict[str, list[float]] = {
    "tau_acc_s": [2.0, 3.0, 4.5],
    "tau_mag_s": [6.0, 9.0, 15.0],
    "mag_norm_gate_uT": [3.0, 5.0],
    "mag_dip_gate_rad": [float(np.deg2rad(10.0))],
    "bias_sigma_motion_rad_s": [float(np.deg2rad(d)) for d in (0.1, 0.2)],
}
QUICK: dict[str, list[float]] = {
    "tau_acc_s": [3.0, 6.0],
    "tau_mag_s": [9.0],
    "mag_norm_gate_uT": [5.0],
    "mag_dip_gate_rad": [float(np.deg2rad(10.0))],
    "bias_sigma_motion_rad_s": [float(np.deg2rad(0.1))],
}


def rms_deg(q: np.ndarray, acc: np.ndarray, q_ref: np.ndarray, mask: np.ndarray
            ) -> tuple[float, float]:
    err = orientation_errors(as_q_nb(q, acc), q_ref, mask)
    return float(np.rad2deg(err.inclination_rms_rad)), float(np.rad2deg(err.heading_rms_rad))


@dataclass(frozen=True)
class UnitItem:
    """One unit (its data set) and the grid points to score on it."""

    data: DatasetItem
    points: tuple[tuple[tuple[str, float], ...], ...]


def score_unit(item: UnitItem) -> tuple[tuple[float, float], np.ndarray]:
    """VQF's RMS and each grid point's ``(inc, head)`` RMS (deg) on one unit."""
    t, acc, gyr, mag, q_ref, mask, rate = load(item.data)
    vqf = rms_deg(vqf_runner(t, acc, gyr, mag, rate), acc, q_ref, mask)
    figures = np.empty((len(item.points), 2))
    for i, point in enumerate(item.points):
        params = InertialLowpassParams(**dict(point))  # type: ignore[arg-type]
        q = make_filter("inertial-lp", params).update(t, acc, gyr, mag).q
        figures[i] = rms_deg(q, acc, q_ref, mask)
    return vqf, figures


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a two-point grid")
    ap.add_argument("--score", choices=("worse", "mean"), default="worse",
                    help="per-unit score: the worse of the two ratios to VQF, or their mean")
    add_engine_options(ap)
    args = ap.parse_args()
    batch = Batch.of(args)
    grid = QUICK if args.quick else GRID
    units: list[DatasetItem] = []
    if BROAD.is_dir():
        for p in sorted(BROAD.glob("*.hdf5")):
            units.append(DatasetItem("broad-" + p.stem.split("_")[0], "broad", (), False,
                                     path=p))
    else:
        print(f"note: {BROAD} not found; simulated walks only")
    for seed in (1, 2, 3):
        units.append(DatasetItem(f"sim-walk{seed}", "sim-walk", (), False, duration_s=300.0,
                                 seed=seed))
    keys = list(grid)
    points = [dict(zip(keys, v, strict=True)) for v in itertools.product(*grid.values())]
    items = [UnitItem(u, tuple(tuple(p.items()) for p in points)) for u in units]
    scored = batch.map(score_unit, items, label=lambda it: it.data.name)
    names = [it.data.name for it, _ in scored]
    vqf = {it.data.name: v for it, (v, _) in scored}
    figures = np.stack([f for _, (_, f) in scored], axis=1)
    ref = np.array([vqf[u] for u in names])
    ratios = figures / ref[None, :, :]
    score = ratios.max(axis=2) if args.score == "worse" else ratios.mean(axis=2)

    def show(point: dict[str, float]) -> str:
        return ", ".join(f"{k}={np.rad2deg(v):.3g} deg" if k.endswith("rad")
                         or k.endswith("rad_s") else f"{k}={v:g}" for k, v in point.items())

    print(f"{len(points)} grid points, {len(names)} units")
    print(f"{'held-out unit':14s} {'inc':>6s} {'head':>6s} | {'vqf inc':>7s} {'vqf head':>8s}"
          " | chosen on the other units")
    held = np.empty((len(names), 2))
    for j, u in enumerate(names):
        others = [k for k in range(len(names)) if k != j]
        best = int(np.argmin(score[:, others].mean(axis=1)))
        held[j] = figures[best, j]
        print(f"{u:14s} {held[j, 0]:6.2f} {held[j, 1]:6.2f} | {ref[j, 0]:7.2f} {ref[j, 1]:8.2f}"
              f" | {show(points[best])}")
    for label, sel in (("BROAD", [k for k, u in enumerate(names) if u.startswith("broad")]),
                       ("sim walks", [k for k, u in enumerate(names) if u.startswith("sim")])):
        if not sel:
            continue
        h = held[sel]
        r = ref[sel]
        print(f"{label} held-out: inclination mean/median/worst {h[:, 0].mean():.2f} / "
              f"{np.median(h[:, 0]):.2f} / {h[:, 0].max():.2f} deg (VQF {r[:, 0].mean():.2f} / "
              f"{np.median(r[:, 0]):.2f} / {r[:, 0].max():.2f}); heading {h[:, 1].mean():.2f} / "
              f"{np.median(h[:, 1]):.2f} / {h[:, 1].max():.2f} deg (VQF {r[:, 1].mean():.2f} / "
              f"{np.median(r[:, 1]):.2f} / {r[:, 1].max():.2f}); worst inclination ratio to VQF "
              f"{(h[:, 0] / r[:, 0]).max():.2f}")
    best_all = int(np.argmin(score.mean(axis=1)))
    print(f"best over all units (candidate defaults): {show(points[best_all])}")
    print("its per-unit figures: " + ", ".join(
        f"{u} {figures[best_all, j, 0]:.2f}/{figures[best_all, j, 1]:.2f}"
        for j, u in enumerate(names)))
    batch.finish()


if __name__ == "__main__":
    main()
