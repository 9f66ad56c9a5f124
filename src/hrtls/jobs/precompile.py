"""Compile the live demo's kernels in a background process on a first run.

numba compiles while holding the interpreter lock, so a process compiles one kernel at a time.
Asked for (``HRTLS_PRECOMPILE=1``, or ``auto``: with a core to spare), a first run
(:func:`hrtls.jobs.warmup.first_run`) of ``hrtls demo`` starts one worker process per entry
of :data:`PARTS`; it tracks the start of a simulated team
mission offline, which compiles what the live mission tracker and the robot's filter call, into
numba's cache. The worker first runs the front-end kernels (:data:`FRONT_END`) as Python, so
it compiles the later stages while the demo compiles the front end, then goes over the mission
again compiled (loading what the demo cached). Each process loads what the other cached and
waits for a kernel the other is compiling (:func:`hrtls.kernels.cooperative`): no kernel is
compiled twice. The worker writes nothing but numba's cache and, when it ends, a marker; it
stops when the demo exits. On the shared 2-core machine at load 3-6 the worker made every
agent's first estimate later (docs/real-data.md), so it is off unless asked for.

Run one part: ``python -m hrtls.jobs.precompile PART``.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
from pathlib import Path

FRONT_END = ("hrtls.calibration", "hrtls.attitude")
"""Modules whose kernels part 1 first runs as Python."""
PARTS = (FRONT_END,)
"""Per worker process: the kernel modules it first runs as Python."""
SPARE_PER_PART = 0.5
"""Idle cores (:func:`spare_cores`) wanted per worker."""
ENV_SWITCH = "HRTLS_PRECOMPILE"
"""``1``: start the worker; ``auto``: when a core is spare; unset or ``0``: no worker (on the
shared 2-core machine it slowed the demo down, module doc)."""
WAYPOINTS = 6
"""Each rescuer walks the first waypoints of the demo's route (a corridor and the stairs)."""


def marker() -> Path:
    """The file part 0 writes when it has compiled the demo's kernels for this install."""
    from hrtls.jobs.warmup import compiled_marker

    path = compiled_marker()
    return path.with_name(path.name.replace("compiled-", "demo-compiled-", 1))


def wanted() -> bool:
    """Whether the worker should run (asked for, a first run, a locked cache, a spare core).

    Asked for: :data:`ENV_SWITCH`; the core is checked with ``auto`` only. numba compiles on
    one core; a worker can gain only on a core the machine does not already use (by the
    one-minute load average).
    """
    from hrtls.jobs.warmup import first_run
    from hrtls.kernels import fcntl

    switch = os.environ.get(ENV_SWITCH, "0")
    return (switch in ("1", "auto") and fcntl is not None and first_run()
            and not marker().exists()
            and (switch == "1" or spare_cores() >= SPARE_PER_PART * len(PARTS)))


def spare_cores() -> float:
    """Cores the machine leaves idle: the count less the one-minute load, less this process."""
    try:
        load = os.getloadavg()[0]
    except OSError:  # no load average (Windows): count the machine as busy
        return 0.0
    return (os.cpu_count() or 1) - 1.0 - load


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
    """Track the start of the demo's team mission (part ``part``, module doc)."""
    import warnings

    from hrtls.kernels import interpret, jit_only, reset
    from hrtls.mission.tracker import MissionParams, MissionTracker
    from hrtls.pipeline import preset
    from hrtls.sim.team import team_mission

    jit_only()  # numba's cache is what the demo loads
    mission = team_mission(seed, stop_s=0.0, waypoints=WAYPOINTS)
    passes = [PARTS[part], ()] if PARTS[part] else [()]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for interpreted in passes:
            if interpreted:
                interpret(interpreted)
            tracker = MissionTracker({m.name: m.session for m in mission.members},
                                     config=preset("default"),
                                     kinds={m.name: m.kind for m in mission.members},
                                     params=MissionParams())
            tracker.advance()
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
