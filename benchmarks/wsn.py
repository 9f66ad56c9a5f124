"""Sensor-network benchmark: the thesis' studies and the 10,000-node timing.

Usage::

    python benchmarks/wsn.py                      # full: 1000 networks per study
    python benchmarks/wsn.py --networks 200 --noise-networks 100
    python benchmarks/wsn.py --timing-only

Tables: loose cooperation (Fig. 6.11: TLA / SELA / SELA + planner, way points), tight
cooperation with a robot (Fig. 6.13-6.17, per connectivity class), 2 % range noise (RMSE after
refinement as a fraction of rho). Timing: a 10,000-node unit-square network (mean degree about
15), disk graph by k-d tree and TLA / SELA propagation, single thread, after a warm-up run (the
compiled kernels are cached on disk, so the warm-up only loads them).
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from hrtls.wsn import experiment as ex
from hrtls.wsn.network import corner_seed_network
from hrtls.wsn.refine import RefineParams, refine_network
from hrtls.wsn.shadow_edge import shadow_edge_localize
from hrtls.wsn.trilateration import PropagationParams, trilaterate_network


def timing(n: int = 10_000, degree: float = 15.0, repeats: int = 5) -> None:
    rho = float(np.sqrt(degree / (np.pi * n)))
    rng = np.random.default_rng(0)
    small = corner_seed_network(np.random.default_rng(1), n_nodes=200, radius_m=0.15)
    shadow_edge_localize(small)  # warm-up (load compiled kernels)
    trilaterate_network(small)
    rows = []
    for r in range(repeats):
        t0 = time.perf_counter()
        net = corner_seed_network(np.random.default_rng(r), n_nodes=n, radius_m=rho)
        _ = net.adjacency
        t1 = time.perf_counter()
        tla = trilaterate_network(net)
        t2 = time.perf_counter()
        sela = shadow_edge_localize(net)
        t3 = time.perf_counter()
        err = np.linalg.norm(sela.estimate_m[sela.localized] - net.position_m[sela.localized],
                             axis=1).max() / rho
        rows.append((t1 - t0, t2 - t1, t3 - t2, tla.n_localized, sela.n_localized,
                     net.edges.shape[0], err))
    a = np.array(rows)
    med = np.median(a, axis=0)
    print(f"\n{n}-node network, rho = {rho:.4f} (mean degree {2 * med[5] / n:.1f}), "
          f"median of {repeats} runs, 1 thread")
    print(f"  build (deployment + k-d tree disk graph + CSR): {med[0]:.3f} s")
    print(f"  TLA propagation:  {med[1]:.3f} s  ({med[3]:.0f} nodes localized)")
    print(f"  SELA propagation: {med[2]:.3f} s  ({med[4]:.0f} nodes localized)")
    print(f"  build + SELA total: {med[0] + med[2]:.3f} s (target < 2 s); "
          f"max error {a[:, 6].max():.2e} rho")
    noisy = corner_seed_network(rng, n_nodes=n, radius_m=rho, range_noise_fraction=0.02)
    t0 = time.perf_counter()
    loc = shadow_edge_localize(noisy, params=PropagationParams.for_noise(0.02))
    t1 = time.perf_counter()
    ref = refine_network(noisy, loc, params=RefineParams(covariance=False))
    t2 = time.perf_counter()
    m = loc.localized & ~noisy.anchor
    e0 = np.sqrt(np.mean(np.sum((loc.estimate_m[m] - noisy.position_m[m]) ** 2, axis=1))) / rho
    e1 = np.sqrt(np.mean(np.sum((ref.estimate_m[m] - noisy.position_m[m]) ** 2, axis=1))) / rho
    print(f"  2 % noise: SELA {t1 - t0:.3f} s ({loc.n_localized} localized, rmse {e0:.3f} rho),"
          f" refinement {t2 - t1:.2f} s (rmse {e1:.3f} rho)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--networks", type=int, default=1000)
    ap.add_argument("--noise-networks", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timing-only", action="store_true")
    ap.add_argument("--engine", default="local", help="local | ray (same numbers either way)")
    ap.add_argument("--workers", type=int, default=None, help="networks at once (default: cores)")
    ap.add_argument("--ray-address", default=None)
    args = ap.parse_args()
    from hrtls.runner import make_engine

    engine = make_engine(args.engine, workers=args.workers, ray_address=args.ray_address)
    timing()
    if args.timing_only:
        return
    t = time.perf_counter()
    s = ex.loose_study(n_networks=args.networks, seed=args.seed, engine=engine)
    print(f"\nLoose cooperation (Fig. 6.11): {s.n_nodes} nodes, unit square, rho = "
          f"{s.radius_m:g}, seeds in a corner, {args.networks} networks "
          f"({time.perf_counter() - t:.1f} s)")
    print(ex.format_table(s.rows))
    print(f"way point kinds: {s.waypoint_kinds}")
    from hrtls.wsn.agents import RescuerParams
    from hrtls.wsn.planner import PlannerParams

    for name, prm in (("without the thesis' seed/vertex heuristic (candidates + arc search)",
                       PlannerParams(heuristic=False)),
                      ("heuristic without shared way points", PlannerParams(share_seeds=False))):
        t = time.perf_counter()
        s = ex.loose_study(n_networks=args.networks, seed=args.seed, planner=prm,
                          engine=engine)
        print(f"\nPlanner ablation: {name} ({time.perf_counter() - t:.1f} s)")
        print(ex.format_table(s.rows))

    t = time.perf_counter()
    k = max(1, args.networks // 5)
    drift = RescuerParams(step_length_m=0.02, heading_noise_rad=0.003,
                          step_length_noise_fraction=0.01, correct_every_steps=10)
    s = ex.loose_study(n_networks=k, seed=args.seed, rescuer=drift, engine=engine)
    print(f"\nLoose cooperation with a dead-reckoning rescuer (heading random walk 0.003 rad/step,"
          f" 1 % step length, 2 cm steps, range corrections every 10 steps), {k} networks "
          f"({time.perf_counter() - t:.1f} s)")
    print(ex.format_table(s.rows))
    for n_nodes, side in ((50, 1.0), (10, 0.5), (15, 1.0)):
        t = time.perf_counter()
        r = ex.tight_study(n_networks=args.networks, n_nodes=n_nodes, side_m=side,
                           seed=args.seed + 1, engine=engine)
        print(f"\nTight cooperation, robot (Fig. 6.13-6.17): {n_nodes} nodes in a {side:g} m "
              f"square, rho = {r.radius_m:g}, d_r = 2 rho, Delta = {r.delta_m:g} m, "
              f"{args.networks} networks ({time.perf_counter() - t:.1f} s)")
        print(ex.format_table(r.rows))
    t = time.perf_counter()
    z = ex.noise_study(n_networks=args.noise_networks, seed=args.seed + 2, engine=engine)
    print(f"\nRange noise {100 * z.noise_fraction:g} %: SELA (+ planner), then least-squares "
          f"refinement, {args.noise_networks} networks ({time.perf_counter() - t:.1f} s)")
    print(ex.format_table(z.rows))
    t = time.perf_counter()
    r = ex.tight_study(n_networks=args.noise_networks, range_noise_fraction=z.noise_fraction,
                       seed=args.seed + 3, engine=engine)
    print(f"\nTight cooperation with {100 * z.noise_fraction:g} % range noise, 50 nodes, "
          f"{args.noise_networks} networks ({time.perf_counter() - t:.1f} s)")
    print(ex.format_table(r.rows))


if __name__ == "__main__":
    main()
