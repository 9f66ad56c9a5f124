"""Compile the live demo's kernels in a background process on a first run.

numba compiles while holding the interpreter lock, so a process compiles one kernel at a time.
On a first run (:func:`hrtls.jobs.warmup.first_run`) with a core to spare (``HRTLS_PRECOMPILE``
``auto``, the default; ``1``: always, ``0``: never), ``hrtls demo`` starts one worker process
per entry of :data:`PARTS`; it feeds the start of the demo's team to per-agent trackers as the
service's tracker host does (the same batches, decoded the same way, the same presets), which
compiles what the host calls, into numba's cache. The worker first runs the front-end kernels
(:data:`FRONT_END`) as Python, so it compiles the later stages while the demo compiles the
front end, then goes over the team again compiled (loading what the demo cached). Each process
loads what the other cached and waits for a kernel the other is compiling
(:func:`hrtls.kernels.cooperative`): no kernel is compiled twice. The worker writes nothing
but numba's cache and, when it ends, a marker; it stops when the demo exits. A core is spare
when the machine leaves it idle now (:func:`spare_cores`): on a busy machine the worker only
takes time from the demo (docs/real-data.md).

Run one part: ``python -m hrtls.jobs.precompile PART``.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import time
from pathlib import Path

FRONT_END = ("hrtls.calibration", "hrtls.attitude")
"""Modules whose kernels part 1 first runs as Python."""
PARTS = (FRONT_END,)
"""Per worker process: the kernel modules it first runs as Python."""
SPARE_PER_PART = 0.5
"""Idle cores (:func:`spare_cores`) wanted per worker."""
ENV_SWITCH = "HRTLS_PRECOMPILE"
"""``auto`` (unset): start the workers when cores are spare; ``1``: always; ``0``: never."""
IDLE_SAMPLE_S = 0.2
"""How long :func:`spare_cores` watches the machine's CPU counters, s."""
WAYPOINTS = 6
"""Each rescuer walks the first waypoints of the demo's route (a corridor and the stairs)."""


def marker() -> Path:
    """The file part 0 writes when it has compiled the demo's kernels for this install."""
    from hrtls.jobs.warmup import compiled_marker

    path = compiled_marker()
    return path.with_name(path.name.replace("compiled-", "demo-compiled-", 1))


def wanted() -> bool:
    """Whether the worker should run (asked for, a first run, a locked cache, a spare core).

    Asked for: :data:`ENV_SWITCH`; the cores are checked with ``auto`` only. numba compiles
    on one core; a worker can gain only on a core the machine does not already use.
    """
    from hrtls.jobs.warmup import first_run
    from hrtls.kernels import fcntl

    switch = os.environ.get(ENV_SWITCH, "auto")
    return (switch in ("1", "auto") and fcntl is not None and first_run()
            and not marker().exists()
            and (switch == "1" or spare_cores() >= SPARE_PER_PART * len(PARTS)))


def spare_cores() -> float:
    """Cores idle now, less the one this process will use (0 when it cannot tell).

    Read from the kernel's CPU counters (``/proc/stat``) over :data:`IDLE_SAMPLE_S`; the load
    average lags by a minute (an install that just ended still counts there).
    """
    first = _cpu_times()
    if first is None:
        return 0.0
    time.sleep(IDLE_SAMPLE_S)
    second = _cpu_times()
    if second is None or second[0] <= first[0]:
        return 0.0
    idle_share = (second[1] - first[1]) / (second[0] - first[0])
    return idle_share * (os.cpu_count() or 1) - 1.0


def _cpu_times() -> tuple[int, int] | None:
    """(all, idle + iowait) jiffies of every CPU since boot; None without ``/proc/stat``."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            fields = f.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    ticks = [int(v) for v in fields[1:]]
    return sum(ticks), ticks[3] + (ticks[4] if len(ticks) > 4 else 0)


def start() -> list[subprocess.Popen[bytes]]:
    """Start the workers when :func:`wanted`; they are stopped at this process's exit."""
    if not wanted():
        return []
    procs = [subprocess.Popen([sys.executable, "-m", "hrtls.jobs.precompile", str(part)],
                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, env=os.environ.copy())
             for part in range(len(PARTS))]
    atexit.register(stop, procs)
    return procs


def stop(procs: list[subprocess.Popen[bytes]]) -> None:
    """End the workers still running (their finished compiles stay cached)."""
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()


def run_part(part: int, *, seed: int = 0) -> None:
    """Track the start of the demo's team as the service does (part ``part``, module doc)."""
    import math
    import warnings

    from hrtls.kernels import interpret, jit_only, reset
    from hrtls.service.client import encode, session_batches
    from hrtls.service.host import decode_batch
    from hrtls.service.runner import AgentSpec, InProcessRunner
    from hrtls.sim.team import team_mission

    jit_only()  # numba's cache is what the demo loads
    mission = team_mission(seed, stop_s=0.0, waypoints=WAYPOINTS)
    landmarks = tuple(lm.model_dump(mode="json", exclude_none=True) for lm in mission.landmarks)
    passes = [PARTS[part], ()] if PARTS[part] else [()]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for interpreted in passes:
            if interpreted:
                interpret(interpreted)
            runner = InProcessRunner()
            for k, member in enumerate(mission.members):
                meta = member.session.meta.model_dump(mode="json")
                runner.open(AgentSpec(k, member.preset, meta, landmarks, kind=member.kind), None,
                            -math.inf)
                batches = session_batches(member.session.with_parts(truth=None), chunk_s=0.5,
                                          blocks=True)
                for seq, (_, batch) in enumerate(batches):
                    runner.feed(k, [decode_batch(*encode({**batch, "seq": seq}, "msgpack"))])
            reset()
            jit_only()


def _exit_with_parent(parent: int) -> None:
    """End this process soon after its parent (the demo) ends, however that ended."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="hrtls parent watch", daemon=True).start()


def main(argv: list[str]) -> int:
    """``python -m hrtls.jobs.precompile PART``: run one part; 0 when it completed."""
    from hrtls.jobs.warmup import configure_cache

    configure_cache()
    _exit_with_parent(os.getppid())
    part = int(argv[0]) if argv else 0
    run_part(part)
    if part == 0:
        path = marker()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("1\n", encoding="utf-8")
        except OSError:
            pass  # an unwritable home: the workers run again next time
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
