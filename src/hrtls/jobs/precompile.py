"""Compile the live demo's kernels in a background process on a first run.

numba compiles while holding the interpreter lock, so a process compiles one kernel at a time.
On a first run (:func:`hrtls.jobs.warmup.first_run`) with a core to spare (``HRTLS_PRECOMPILE``
``auto``, the default; ``1``: always, ``0``: never), ``hrtls demo`` starts a worker process: it
feeds the start of the demo's team to per-agent trackers as the service's tracker host does
(the same batches, decoded the same way, the same presets), so it compiles exactly the host's
builds, into numba's cache, in the order a rescuer's data needs them (front end, gait, then the
position filter). The demo's own first compiles are the position filter's: a robot's tracker
starts on its first odometry poses, a rescuer's only after ``RATE_SAMPLES`` IMU samples
(:mod:`hrtls.pipeline.live`). The two processes thus compile different kernels at the same
time; each loads what the other cached and waits for a kernel the other is compiling
(:func:`hrtls.kernels.cooperative`): no kernel is compiled twice. The worker writes nothing but
numba's cache and, when it ends, a marker; it stops when the demo exits. A core is spare when
the machine leaves it idle now (:func:`spare_cores`): on a busy machine the worker only takes
time from the demo (docs/real-data.md).

Run it alone: ``python -m hrtls.jobs.precompile``.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import time
from pathlib import Path

SPARE_CORES = 0.5
"""Idle cores (:func:`spare_cores`) the worker wants."""
ENV_SWITCH = "HRTLS_PRECOMPILE"
"""``auto`` (unset): start the worker when a core is spare; ``1``: always; ``0``: never."""
IDLE_SAMPLE_S = 0.2
"""How long :func:`spare_cores` watches the machine's CPU counters, s."""
WAYPOINTS = 6
"""Each rescuer walks the first waypoints of the demo's route (a corridor and the stairs)."""


def marker() -> Path:
    """The file the worker writes when it has compiled the demo's kernels for this install."""
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
            and (switch == "1" or spare_cores() >= SPARE_CORES))


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


def start() -> subprocess.Popen[bytes] | None:
    """Start the worker when :func:`wanted` (stopped at this process's exit); None without."""
    if not wanted():
        return None
    proc = subprocess.Popen([sys.executable, "-m", "hrtls.jobs.precompile"],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=os.environ.copy())
    atexit.register(stop, proc)
    return proc


def stop(proc: subprocess.Popen[bytes]) -> None:
    """End the worker if still running (its finished compiles stay cached)."""
    if proc.poll() is None:
        proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()


def run(*, seed: int = 0) -> None:
    """Track the start of the demo's team as the service's tracker host does (module doc)."""
    import math
    import warnings

    from hrtls.kernels import jit_only
    from hrtls.service.client import encode, session_batches
    from hrtls.service.host import decode_batch
    from hrtls.service.runner import AgentSpec, InProcessRunner
    from hrtls.sim.team import team_mission

    jit_only()  # numba's cache is what the demo loads
    mission = team_mission(seed, stop_s=0.0, waypoints=WAYPOINTS)
    landmarks = tuple(lm.model_dump(mode="json", exclude_none=True) for lm in mission.landmarks)
    runner = InProcessRunner()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k, member in enumerate(mission.members):
            meta = member.session.meta.model_dump(mode="json")
            runner.open(AgentSpec(k, member.preset, meta, landmarks, kind=member.kind), None,
                        -math.inf)
            batches = session_batches(member.session.with_parts(truth=None), chunk_s=0.5,
                                      blocks=True)
            for seq, (_, batch) in enumerate(batches):
                runner.feed(k, [decode_batch(*encode({**batch, "seq": seq}, "msgpack"))])


def _exit_with_parent(parent: int) -> None:
    """End this process soon after its parent (the demo) ends, however that ended."""
    import threading
    import time

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="hrtls parent watch", daemon=True).start()


def main() -> int:
    """``python -m hrtls.jobs.precompile``: compile, then write the marker; 0 when done."""
    from hrtls.jobs.warmup import configure_cache

    configure_cache()
    _exit_with_parent(os.getppid())
    run()
    path = marker()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("1\n", encoding="utf-8")
    except OSError:
        pass  # an unwritable home: the worker runs again next time
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
