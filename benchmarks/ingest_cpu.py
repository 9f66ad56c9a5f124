"""CPU of the service's front end per ingest batch: rows against binary column blocks.

Per 0.5 s batch of a simulated office walk (100 Hz IMU with gyroscope and magnetometer, beacon
RSS, tags, ranges), what the service process does for a WebSocket batch: unpack the msgpack
frame, re-pack the batch for the raw log, check it into a :class:`~hrtls.service.batches.Batch`
and pickle it for a tracker process (``front end``); and what the tracker process does before
tracking: unpickle and build the tracker's chunk (``worker``). Microseconds per batch, the best
of ``--rounds`` interleaved rounds.

``--old-src DIR`` also loads ``DIR/hrtls/service/batches.py`` (e.g. ``/work/main/src``, the
code before column blocks) in this process and times it on the rows beside the new code, so the
ratios come from one run on one machine load.

    python benchmarks/ingest_cpu.py --old-src /work/main/src
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import pickle
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import msgpack

from hrtls.service import batches as new_batches
from hrtls.service.client import session_batches
from hrtls.sim.scenarios import run_scenario


def load_old(src: Path) -> ModuleType:
    """``src/hrtls/service/batches.py`` as a separate module (its imports: this tree's)."""
    path = src / "hrtls" / "service" / "batches.py"
    spec = importlib.util.spec_from_file_location("hrtls_old_batches", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"{path}: cannot load")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module   # pydantic resolves the annotations through it
    spec.loader.exec_module(module)
    return module


def frames(*, seed: int, duration_s: float, blocks: bool) -> list[bytes]:
    """The WebSocket frames of a simulated walk's batches."""
    s = run_scenario("office_random_walk", seed=seed, duration_s=duration_s).session
    out = []
    for seq, (_, b) in enumerate(session_batches(s, chunk_s=0.5, t_offset_s=1000.0,
                                                 blocks=blocks)):
        out.append(msgpack.packb({"type": "batch", "batch": {**b, "seq": seq}}))
    return out


def front_end(mod: ModuleType, frame: bytes) -> Any:
    """The service process's work on one WebSocket batch; the pickle sent to a shard."""
    value = msgpack.unpackb(frame, raw=False)["batch"]
    msgpack.packb(value)
    batch = mod.parse_batch(value)
    batch.time_span()
    return pickle.dumps(batch, protocol=pickle.HIGHEST_PROTOCOL)


def worker(mod: ModuleType, data: bytes, meta: Any) -> None:
    """The tracker process's work before tracking."""
    mod.to_chunk(pickle.loads(data), meta, {})


def per_batch_us(fn: Any, items: list[Any]) -> float:
    """CPU time of ``fn`` over ``items``, microseconds per item."""
    t0 = time.process_time()
    for item in items:
        fn(item)
    return 1e6 * (time.process_time() - t0) / len(items)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=100, help="simulated walk (100: the load test's)")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--old-src", type=Path, default=None,
                    help="source tree of the code to compare (its batches.py)")
    args = ap.parse_args()
    from hrtls.data.session import SessionMeta

    meta = SessionMeta()
    cases: dict[str, tuple[ModuleType, list[bytes]]] = {
        "new, rows": (new_batches, frames(seed=args.seed, duration_s=args.duration_s,
                                          blocks=False)),
        "new, blocks": (new_batches, frames(seed=args.seed, duration_s=args.duration_s,
                                            blocks=True))}
    if args.old_src is not None:
        cases = {"old, rows": (load_old(args.old_src), cases["new, rows"][1]), **cases}
    best: dict[str, list[float]] = {k: [float("inf")] * 2 for k in cases}
    for _ in range(args.rounds):
        for name, (mod, items) in cases.items():
            pickles = [front_end(mod, f) for f in items]
            fe = per_batch_us(lambda f, m=mod: front_end(m, f), items)
            wk = per_batch_us(lambda d, m=mod: worker(m, d, meta), pickles)
            best[name] = [min(best[name][0], fe), min(best[name][1], wk)]
    n = len(cases["new, rows"][1])
    print(f"{n} batches of 0.5 s (seed {args.seed}), best of {args.rounds} rounds, "
          f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print("| code, format | frame bytes | front end us/batch | worker us/batch |")
    print("|---|---|---|---|")
    for name, (_, items) in cases.items():
        size = sum(map(len, items)) / len(items)
        print(f"| {name} | {size:.0f} | {best[name][0]:.1f} | {best[name][1]:.1f} |")
    ref = "old, rows" if "old, rows" in cases else "new, rows"
    for name in cases:
        if name != ref:
            print(f"front end {ref} / {name}: {best[ref][0] / best[name][0]:.2f}x; "
                  f"worker: {best[ref][1] / best[name][1]:.2f}x")


if __name__ == "__main__":
    main()
