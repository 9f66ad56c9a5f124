"""Cold start: one build per kernel on the demo's path, compiles locked across processes, the
background worker's switches (``hrtls.jobs.precompile``)."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import hrtls.kernels as K
from hrtls.jobs import precompile, warmup
from hrtls.service.batches import ImuPart
from hrtls.service.columns import block, numeric

# the live mission tracker on the demo's (shortened) team mission, then the Python callers of
# the kernels that the tracker's compiled code also calls: each kernel must keep one build
_SCRIPT = textwrap.dedent("""
    import json, warnings
    import numpy as np
    warnings.simplefilter("ignore")
    import hrtls.kernels as K
    from hrtls.fusion.floors import floor_level_update
    from hrtls.fusion.gating import kalman_update
    from hrtls.mission.tracker import MissionParams, MissionTracker
    from hrtls.pipeline import preset
    from hrtls.fusion.state import FilterState
    from hrtls.sim.team import team_mission
    K.jit_only()
    m = team_mission(0, stop_s=0.0, waypoints=6)
    tr = MissionTracker({a.name: a.session for a in m.members}, config=preset("default"),
                        kinds={a.name: a.kind for a in m.members}, params=MissionParams())
    tr.advance()
    x, p = np.zeros(4), np.eye(4)
    kalman_update(x, p, np.eye(2, 4), np.eye(2), np.ones(2), gate_probability=0.99)
    floor_level_update(FilterState(t=0.0, x=x, P=p), 3.0)
    print(json.dumps({k: len(v._dispatcher.signatures) for k, v in K.REGISTRY.items()
                      if v._dispatcher is not None}))
""")
ONE_BUILD = ("hrtls.attitude._inertial_lowpass_kernel:inertial_lowpass_kernel",
             "hrtls.fusion.gating:joseph_kernel", "hrtls.fusion.gating:scalar_update",
             "hrtls.gait.peak_steps:peak_step_kernel",
             "hrtls.gait.motion_detector:running_std_kernel", "hrtls.gait.vertical:level_kernel")
"""Kernels that had several builds in a live demo (read-only columns, literal arguments)."""


def test_decoded_columns_are_writable() -> None:
    a = np.arange(6.0).reshape(3, 2)
    decoded = numeric(block(a), "imu.acc", width=2)
    assert decoded.flags.writeable and decoded.flags.c_contiguous
    np.testing.assert_array_equal(decoded, a)
    part = ImuPart(t=np.arange(3.0), acc=np.ones((3, 3)), gyr=None, mag=None)
    again = pickle.loads(pickle.dumps(part))
    assert again.t.flags.writeable and again.acc.flags.writeable
    np.testing.assert_array_equal(again.acc, part.acc)


@pytest.mark.slow
def test_demo_path_compiles_one_build_per_kernel(tmp_path: Path) -> None:
    # an empty cache: a build loaded from the cache types none of the kernels it calls
    env = {**os.environ, "HRTLS_AOT": "0", "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", _SCRIPT], env=env, capture_output=True,
                         text=True, check=True)
    builds = json.loads(out.stdout.strip().splitlines()[-1])
    for key in ONE_BUILD:
        assert builds.get(key) == 1, (key, builds.get(key))
    several = {k: n for k, n in builds.items() if n > 1}
    assert not several


def test_compile_lock_is_beside_the_index(tmp_path: Path) -> None:
    if K.fcntl is None:
        pytest.skip("no fcntl")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "HRTLS_AOT": "0"}
    code = ("from hrtls.fusion.gating import wrap_rad; import math; "
            "print(wrap_rad(3 * math.pi))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)
    assert abs(float(out.stdout) - np.pi) < 1e-12
    locks = list(tmp_path.rglob("*wrap_rad*.nbi.lock"))
    assert len(locks) == 1 and locks[0].with_suffix("").exists()  # the index beside it


def test_compile_log_has_a_line_per_compile(tmp_path: Path) -> None:
    if K.fcntl is None:
        pytest.skip("no fcntl")
    log = tmp_path / "compiles.jsonl"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "HRTLS_AOT": "0",
           K.COMPILE_LOG: str(log)}
    code = ("from hrtls.fusion.floors import floor_level_update; "
            "from hrtls.fusion.state import FilterState; import numpy as np; "
            "floor_level_update(FilterState(t=0.0, x=np.zeros(4), P=np.eye(4)), 3.0)")
    for _ in range(2):   # compiled, then loaded from the cache
        subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True)
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    first = [r for r in lines if r["pid"] == lines[0]["pid"]]
    second = [r for r in lines if r["pid"] != lines[0]["pid"]]
    # every kernel compiled once (a kernel typed again inside another finds its build)
    assert {r["kernel"] for r in first} == {r["kernel"] for r in first if r["compiled"]}
    assert len({r["kernel"] for r in first if r["compiled"]}) == sum(r["compiled"]
                                                                    for r in first)
    assert second and not any(r["compiled"] for r in second)
    nested = [r for r in first if r["depth"] > 0 and r["compiled"]]
    assert nested   # the kernels a kernel calls are compiled inside its compile
    for r in first:
        assert 0.0 <= r["self_cpu_s"] <= r["cpu_s"] + 1e-9 and r["wall_s"] >= 0.0
        assert ":" in r["kernel"] and r["sig"].startswith("(")
    top = [r for r in first if r["depth"] == 0]
    assert sum(r["cpu_s"] for r in top) == pytest.approx(sum(r["self_cpu_s"] for r in first))


def test_worker_switches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(precompile, "spare_cores", lambda: 1.0)
    monkeypatch.delenv(precompile.ENV_SWITCH, raising=False)
    assert precompile.wanted()  # auto: a core is spare
    monkeypatch.setenv(precompile.ENV_SWITCH, "auto")
    assert precompile.wanted()
    monkeypatch.setattr(precompile, "spare_cores", lambda: 0.2)  # a busy machine
    assert not precompile.wanted()
    monkeypatch.setenv(precompile.ENV_SWITCH, "1")
    assert precompile.wanted()  # asked for, whatever the load
    monkeypatch.setenv(precompile.ENV_SWITCH, "0")
    assert not precompile.wanted()
    monkeypatch.setenv(precompile.ENV_SWITCH, "1")
    precompile.marker().parent.mkdir(parents=True, exist_ok=True)
    precompile.marker().write_text("1\n")
    assert not precompile.wanted()  # the worker completed once
    precompile.marker().unlink()
    warmup.mark_compiled()
    assert not precompile.wanted()  # `hrtls warmup` (or a track) compiled everything
    assert precompile.marker().parent == warmup.compiled_marker().parent


def test_spare_cores_from_cpu_counters(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(precompile, "IDLE_SAMPLE_S", 0.0)
    monkeypatch.setattr(precompile.os, "cpu_count", lambda: 4)
    counters = iter([(1000, 400), (1400, 700)])  # 300 of 400 jiffies idle: 3 of 4 cores
    monkeypatch.setattr(precompile, "_cpu_times", lambda: next(counters))
    assert precompile.spare_cores() == pytest.approx(2.0)  # less the demo's own core
    counters = iter([(1000, 400), (1400, 400)])  # every core busy
    assert precompile.spare_cores() == pytest.approx(-1.0)
    monkeypatch.setattr(precompile, "_cpu_times", lambda: None)  # no /proc/stat
    assert precompile.spare_cores() == 0.0


def test_cpu_counters_of_this_machine() -> None:
    times = precompile._cpu_times()
    if times is None:
        pytest.skip("no /proc/stat")
    total, idle = times
    assert 0 <= idle <= total
    assert -1.0 <= precompile.spare_cores() <= (os.cpu_count() or 1) - 1.0 + 1e-9


