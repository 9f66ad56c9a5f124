"""Attitude benchmark: speed and accuracy of hrtls's filters next to VQF, imufusion and ahrs.

Run from the repository root::

    python benchmarks/attitude.py            # full table (a few minutes)
    python benchmarks/attitude.py --quick    # shorter data, no ahrs on long runs
    python benchmarks/attitude.py --speed-only --methods quat-ekf,vqf   # speed column only
    python benchmarks/attitude.py --quick --engine local --workers 2  # data sets on 2 cores

Variants: ``euler-ekf eq5`` integrates the angles with Colombo eq. 5 itself, ``quat-ekf 4st``
is the thesis' 4-state EKF (gyro bias only learnt at rest). ``euler-ekf dyn0`` switches off
the variance of the body's acceleration added to the accelerometer noise
(``dyn_acc_corr_s=0``: Colombo's constant ``Q_g``); ``quat-ekf dyn.1`` switches it on for
the quaternion EKF (off by default there); ``quat-ekf restvar`` shrinks its gyro-bias
variances at rest (``bias_var_at_rest=True``, off by default).

Speed: samples per second on 1 M samples after a warm-up, CPU time of this process (other jobs
on the machine share the cores; CPU time is less disturbed than wall time), best of 3.
Accuracy: inclination (roll/pitch combined) and heading RMS in degrees against the reference,
split as BROAD does (error ``q_est * conj(q_ref)``; heading = rotation about the vertical; a
constant heading offset removed; only ``movement`` samples; NaN references skipped).

Data: (1) ``hrtls.sim`` office walk (waist phone, magnetic anomalies), (2) the compact walking
simulator ``benchmarks/_attitude_sim.py`` with magnetic anomaly patches and a large gyro bias
(seeds 1-3),
(3) the BROAD trials in ``../shared/data/broad`` (skipped when absent), (4) with
``--fast-motion dev|held-out|all``, the simulated fast hand-held motions of
``benchmarks/_attitude_fast_sim.py`` (fast translation, fast rotation, both; 286 Hz; seeds 1-3
for development, 101-110 held out), printed in their own tables, one row per unit and the
mean / median / worst over seeds per kind; ``--fast-only`` skips (1)-(3)::

    python benchmarks/attitude.py --fast-motion all --fast-only \
        --methods inertial-lp,vqf,vqf-6d,quat-ekf,complementary

``vqf`` is VQF's 9-D output, ``vqf-6d`` its 6-D output (heading from the gyroscope only). The
data sets run through ``--engine`` (``benchmarks/_engine.py``); the speed runs stay in this
process, one at a time.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _attitude_fast_sim import DEV_SEEDS, HELD_OUT_SEEDS, KINDS, simulate_fast_motion
from _attitude_sim import simulate_walk
from _engine import Batch, add_engine_options
from hrtls.attitude import make_filter, orientation_errors
from hrtls.frames import (
    GRAVITY_M_S2,
    quat_conjugate,
    quat_from_rotation,
    quat_rotate,
    quat_to_rotation,
)

ROOT = Path(__file__).resolve().parents[1]
BROAD = ROOT.parent / "shared" / "data" / "broad"

Runner = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float], np.ndarray]


# ------------------------------------------------------------------------------ methods
def ours(name: str, **params: object) -> Runner:
    def run(t, acc, gyr, mag, rate):
        flt = make_filter(name)
        if params:
            flt = make_filter(name, type(flt.params)(**params))
        return flt.update(t, acc, gyr, mag).q
    return run


def vqf_runner(t, acc, gyr, mag, rate):
    from vqf import VQF

    v = VQF(1.0 / rate)
    out = v.updateBatch(np.ascontiguousarray(gyr), np.ascontiguousarray(acc),
                        np.ascontiguousarray(mag))
    return out["quat9D"]


def vqf6d_runner(t, acc, gyr, mag, rate):
    from vqf import VQF

    v = VQF(1.0 / rate)
    return v.updateBatch(np.ascontiguousarray(gyr), np.ascontiguousarray(acc))["quat6D"]


def imufusion_runner(t, acc, gyr, mag, rate):
    import imufusion

    ahrs = imufusion.Ahrs()
    s = imufusion.AhrsSettings()
    s.convention = imufusion.CONVENTION_ENU
    s.gain = 0.5
    s.gyroscope_range = 2000.0
    s.acceleration_rejection = 10.0
    s.magnetic_rejection = 10.0
    s.rejection_timeout = int(5 * rate)
    s.sample_rate = float(rate)
    ahrs.set_settings(s)
    g_deg = np.rad2deg(gyr)
    a_g = acc / GRAVITY_M_S2
    out = np.empty((len(t), 4))
    for i in range(len(t)):
        ahrs.update(g_deg[i], a_g[i], mag[i])
        out[i] = ahrs.get_quaternion()
    return out


def ahrs_runner(kind: str) -> Runner:
    def run(t, acc, gyr, mag, rate):
        from ahrs.filters import EKF, Madgwick

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if kind == "ekf":
                # frame="ENU" diverged on these data; NED with the measured dip works
                k = min(len(acc), 100)
                dip = np.rad2deg(np.arcsin(np.clip(-np.sum(acc[:k] * mag[:k], axis=1) / (
                    np.linalg.norm(acc[:k], axis=1) * np.linalg.norm(mag[:k], axis=1)),
                    -1.0, 1.0))).mean()
                return EKF(gyr=gyr, acc=acc, mag=mag, frequency=rate, frame="NED",
                           magnetic_ref=-float(dip)).Q
            return Madgwick(gyr=gyr, acc=acc, mag=mag, frequency=rate).Q
    return run


def available() -> tuple[dict[str, Runner], list[str]]:
    """The methods, and notes on the optional ones that are not installed."""
    methods: dict[str, Runner] = {
        "euler-ekf": ours("euler-ekf"),
        "euler-ekf eq5": ours("euler-ekf", exact_propagation=False),
        "quat-ekf": ours("quat-ekf"),
        "quat-ekf 4st": ours("quat-ekf", bias_in_state=False),
        "euler-ekf dyn0": ours("euler-ekf", dyn_acc_corr_s=0.0),
        "quat-ekf dyn.1": ours("quat-ekf", dyn_acc_corr_s=0.1),
        "quat-ekf restvar": ours("quat-ekf", bias_var_at_rest=True),
        "complementary": ours("complementary"),
        "inertial-lp": ours("inertial-lp"),
    }
    notes = []
    for label, module, runner in (("vqf", "vqf", vqf_runner),
                                  ("vqf-6d", "vqf", vqf6d_runner),
                                  ("imufusion", "imufusion", imufusion_runner),
                                  ("ahrs-ekf", "ahrs", ahrs_runner("ekf")),
                                  ("ahrs-madgwick", "ahrs", ahrs_runner("madgwick"))):
        try:
            __import__(module)
        except ImportError:
            notes.append(f"note: {module} is not installed; {label} skipped "
                         "(pip install -e .[bench])")
            continue
        methods[label] = runner
    return methods, notes


def as_q_nb(q: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """Scalar-first q that maps sensor vectors to the earth frame (conjugate if needed)."""
    q = np.asarray(q, dtype=np.float64)
    up = np.median(quat_rotate(q, acc)[:, 2])
    up_c = np.median(quat_rotate(quat_conjugate(q), acc)[:, 2])
    return q if up >= up_c else quat_conjugate(q)


# ------------------------------------------------------------------------------ data
def dataset_sim_office(duration_s: float) -> tuple:
    from scipy.spatial.transform import Slerp

    from hrtls.sim.scenarios import run_scenario

    res = run_scenario("office_random_walk", 0, duration_s=duration_s)
    t, acc, gyr, mag = res.session.imu.aligned()
    ideal = res.imu.ideal
    slerp = Slerp(ideal.t, quat_to_rotation(ideal.q_nd))
    q_ref = quat_from_rotation(slerp(np.clip(t, ideal.t[0], ideal.t[-1])))
    rate = 1.0 / float(np.median(np.diff(t)))
    return t, acc, gyr, mag, q_ref, np.ones(len(t), dtype=bool), rate


def dataset_sim_walk(duration_s: float, seed: int) -> tuple:
    s = simulate_walk(duration_s=duration_s, seed=seed)
    return s.t, s.acc, s.gyr, s.mag, s.q_true, s.movement, 100.0


def dataset_fast(kind: str, seed: int) -> tuple:
    s = simulate_fast_motion(kind, seed=seed)
    return s.t, s.acc, s.gyr, s.mag, s.q_true, s.movement, s.rate_hz


def dataset_broad(path: Path) -> tuple:
    import h5py

    with h5py.File(path, "r") as f:
        acc = np.asarray(f["imu_acc"][()], dtype=np.float64)
        gyr = np.asarray(f["imu_gyr"][()], dtype=np.float64)
        mag = np.asarray(f["imu_mag"][()], dtype=np.float64)
        q_ref = np.asarray(f["opt_quat"][()], dtype=np.float64)
        movement = np.asarray(f["movement"][()], dtype=bool)
        rate = float(f.attrs["sampling_rate"])
    t = np.arange(len(acc)) / rate
    return t, acc, gyr, mag, q_ref, movement, rate


@dataclass(frozen=True)
class DatasetItem:
    """One data set (``kind`` sim-office, sim-walk, fast-<kind> or broad) and its methods."""

    name: str
    kind: str
    methods: tuple[str, ...]
    quick: bool
    duration_s: float = 0.0
    seed: int = 0
    path: Path | None = None


def load(item: DatasetItem) -> tuple:
    """``(t, acc, gyr, mag, q_ref, movement, rate)`` of the data set."""
    if item.kind == "sim-office":
        return dataset_sim_office(item.duration_s)
    if item.kind == "sim-walk":
        return dataset_sim_walk(item.duration_s, item.seed)
    if item.kind.startswith("fast-"):
        return dataset_fast(item.kind.removeprefix("fast-"), item.seed)
    assert item.path is not None
    return dataset_broad(item.path)


def accuracy(item: DatasetItem) -> tuple[int, dict[str, tuple[float, float]]]:
    """Samples and inclination / heading RMS (deg) per method on one data set."""
    runners, _ = available()
    t, acc, gyr, mag, q_ref, mask, rate = load(item)
    out: dict[str, tuple[float, float]] = {}
    for label in item.methods:
        if label.startswith("ahrs") and item.quick and len(t) > 50_000:
            continue
        q = as_q_nb(runners[label](t, acc, gyr, mag, rate), acc)
        err = orientation_errors(q, q_ref, mask)
        out[label] = (float(np.rad2deg(err.inclination_rms_rad)),
                      float(np.rad2deg(err.heading_rms_rad)))
    return len(t), out


# ------------------------------------------------------------------------------ speed
def speed(runner: Runner, n: int) -> float:
    rng = np.random.default_rng(0)
    rate = 100.0
    t = np.arange(n) / rate
    phase = 2 * np.pi * 0.3 * t[:, None] + np.array([0.0, 1.0, 2.0])
    gyr = 0.5 * np.sin(phase) + rng.normal(size=(n, 3)) * 0.01
    acc = np.array([0.0, 0.0, GRAVITY_M_S2]) + rng.normal(size=(n, 3)) * 0.5
    mag = np.array([0.0, 20.0, -40.0]) + rng.normal(size=(n, 3)) * 1.0
    runner(t[:1000], acc[:1000], gyr[:1000], mag[:1000], rate)  # warm-up / compile
    best = np.inf
    for _ in range(3):
        t0 = time.process_time()
        runner(t, acc, gyr, mag, rate)
        best = min(best, time.process_time() - t0)
    return n / best


def fast_items(which: str, labels: tuple[str, ...], quick: bool) -> list[DatasetItem]:
    """The fast-motion units of ``--fast-motion`` (every kind for each seed of the set)."""
    seeds = {"none": (), "dev": DEV_SEEDS, "held-out": HELD_OUT_SEEDS,
             "all": DEV_SEEDS + HELD_OUT_SEEDS}[which]
    return [DatasetItem(f"fast-{kind}-{seed}", f"fast-{kind}", labels, quick, seed=seed)
            for kind in KINDS for seed in seeds]


def print_fast(names: list[str], results: dict[str, dict[str, tuple[float, float]]],
               methods: list[str]) -> None:
    """Per-unit and per-kind tables of the fast-motion units (development / held-out seeds)."""
    print()
    print("fast-motion units: inclination / heading RMS in degrees")
    header = f"{'unit':22s} | " + " | ".join(f"{m:>13s}" for m in methods)
    print(header)
    print("-" * len(header))
    for n in names:
        cells = [f"{results[m][n][0]:5.2f} / {results[m][n][1]:5.2f}" if n in results[m]
                 else f"{'-':>13s}" for m in methods]
        print(f"{n:22s} | " + " | ".join(cells))
    print()
    print("fast-motion units over seeds: inclination / heading RMS in degrees, "
          "mean | median | worst")
    for set_name, seeds in (("dev", DEV_SEEDS), ("held-out", HELD_OUT_SEEDS)):
        for kind in (*KINDS, "all"):
            kinds = KINDS if kind == "all" else (kind,)
            units = [f"fast-{k}-{s}" for k in kinds for s in seeds]
            if not all(u in names for u in units):
                continue
            print(f"{set_name} seeds {seeds[0]}-{seeds[-1]}, {kind}")
            for m in methods:
                r = np.array([results[m][u] for u in units if u in results[m]])
                if len(r) == 0:
                    continue
                stats = (r.mean(axis=0), np.median(r, axis=0), r.max(axis=0))
                print(f"  {m:14s} | " + " | ".join(f"{a:5.2f} / {b:5.2f}" for a, b in stats))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter data and speed runs")
    ap.add_argument("--methods", default="", help="comma-separated subset")
    ap.add_argument("--speed-only", action="store_true", help="only the speed column")
    ap.add_argument("--speed-samples", type=int, default=0,
                    help="samples of the speed runs (default 1 M, --quick 200 k)")
    ap.add_argument("--fast-motion", choices=("none", "dev", "held-out", "all"), default="none",
                    help="add the simulated fast-motion units: development seeds "
                         f"{DEV_SEEDS[0]}-{DEV_SEEDS[-1]}, held-out seeds "
                         f"{HELD_OUT_SEEDS[0]}-{HELD_OUT_SEEDS[-1]}, or both")
    ap.add_argument("--fast-only", action="store_true",
                    help="only the fast-motion units (no office walk, walks or BROAD)")
    add_engine_options(ap)
    args = ap.parse_args()
    batch = Batch.of(args)
    methods, notes = available()
    for note in notes:
        print(note)
    if args.methods:
        methods = {k: v for k, v in methods.items() if k in args.methods.split(",")}
    n_fast = 200_000 if args.quick else 1_000_000
    n_slow = 20_000 if args.quick else 100_000
    if args.speed_samples > 0:
        n_fast = args.speed_samples
        n_slow = max(1, args.speed_samples // 10)
    labels = tuple(methods)
    datasets = [DatasetItem("sim-office", "sim-office", labels, args.quick,
                            duration_s=120.0 if args.quick else 600.0)]
    for seed in (1, 2, 3):
        datasets.append(DatasetItem(f"sim-walk{seed}", "sim-walk", labels, args.quick,
                                    duration_s=120.0 if args.quick else 300.0, seed=seed))
    if args.speed_only or args.fast_only:
        datasets = []
    elif BROAD.is_dir():
        for p in sorted(BROAD.glob("*.hdf5")):
            datasets.append(DatasetItem("broad-" + p.stem.split("_")[0], "broad", labels,
                                        args.quick, path=p))
    else:
        print(f"note: {BROAD} not found; BROAD trials skipped")
    if not args.speed_only:
        datasets += fast_items(args.fast_motion, labels, args.quick)

    results: dict[str, dict[str, tuple[float, float]]] = {m: {} for m in methods}
    rates: dict[str, float] = {}
    for label, runner in methods.items():
        slow = label.startswith("ahrs")
        rates[label] = speed(runner, n_slow if slow else n_fast)
        print(f"speed {label}: {rates[label] / 1e6:.3f} M samples/s", flush=True)
    names = []
    fast_names = []
    for item, (n_samples, per_method) in batch.map(accuracy, datasets,
                                                   label=lambda it: it.name):
        (fast_names if item.kind.startswith("fast-") else names).append(item.name)
        for label, value in per_method.items():
            results[label][item.name] = value
        print(f"done {item.name} ({n_samples} samples)", flush=True)

    header = f"{'method':14s} {'M samples/s':>11s} | " + " | ".join(
        f"{n:>13s}" for n in names)
    print()
    print("inclination / heading RMS in degrees" if names else "speed (CPU time, best of 3)")
    print(header)
    print("-" * len(header))
    for label in methods:
        cells = []
        for n in names:
            if n in results[label]:
                inc, hd = results[label][n]
                cells.append(f"{inc:5.2f} / {hd:5.2f}")
            else:
                cells.append(f"{'-':>13s}")
        print(f"{label:14s} {rates[label] / 1e6:11.3f} | " + " | ".join(cells))
    broad = [n for n in names if n.startswith("broad-")]
    if broad:
        print()
        print(f"BROAD trials ({len(broad)}): inclination / heading RMS in degrees over trials")
        print(f"{'method':14s} | {'mean':>13s} | {'median':>13s} | {'worst':>13s}")
        for label in methods:
            r = np.array([results[label][n] for n in broad if n in results[label]])
            if len(r) == 0:
                continue
            stats = (r.mean(axis=0), np.median(r, axis=0), r.max(axis=0))
            print(f"{label:14s} | " + " | ".join(f"{a:5.2f} / {b:5.2f}" for a, b in stats))
    if fast_names:
        print_fast(fast_names, results, list(methods))
    batch.finish()


if __name__ == "__main__":
    main()
