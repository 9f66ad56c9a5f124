"""The service with its trackers on shard workers (Ray actors, issue 15, or local processes):
same rows as in-process, and a worker killed mid-stream loses nothing."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
from tests.service.conftest import start_live
from tests.service.streams import mission_for, office, offline_rows, start_pose, stored

from hrtls.service.client import AgentClient, session_batches
from hrtls.service.settings import Settings


def _ray_available() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


NEEDS_RAY = pytest.mark.skipif(not _ray_available() and os.environ.get("CI") != "true",
                               reason="Ray is not installed (pip install 'hrtls[ray]')")


def _wait_idle(host, timeout_s: float = 180.0) -> None:
    deadline = time.monotonic() + timeout_s
    time.sleep(0.1)
    while not host.idle():
        assert time.monotonic() < deadline, "tracker host did not finish"
        time.sleep(0.05)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize("engine", ["processes", pytest.param("ray", marks=NEEDS_RAY)])
def test_shard_killed_mid_stream_loses_nothing(tmp_path: Path, engine: str) -> None:
    from hrtls.runner.shards import ShardedRunner

    live = start_live(Settings(db=str(tmp_path / "shards.db"), engine=engine, ray_shards=2,
                               process_shards=2, snapshot_every_s=5.0))
    host = live.server.config.app.state.services.host
    runner = host.runner
    assert isinstance(runner, ShardedRunner) and runner.n_shards == 2
    try:
        session = office()
        with live.client(live.commander) as commander:
            mid, aid, token = mission_for(commander, session)
            batches = list(session_batches(session, chunk_s=0.5))
            half = len(batches) // 2
            with AgentClient(live.url, token, fmt="msgpack") as agent:
                agent.checkin(start_pose(session))
                for _, b in batches[:half]:
                    agent.submit(b)
                _wait_idle(host)
                pid = runner.kill_shard(runner.shard_of(aid))
                deadline = time.monotonic() + 30
                while _pid_alive(pid) and time.monotonic() < deadline:
                    time.sleep(0.05)
                assert not _pid_alive(pid), "the shard actor's process is still alive"
                for _, b in batches[half:]:
                    agent.submit(b)
                assert agent.outbox == {}
            _wait_idle(host)
            assert runner.recoveries == 1
            got = stored(commander, mid, aid)
    finally:
        live.stop()
        runner.shutdown()
    ref = offline_rows()
    n = len(got["t"])
    assert n > 100 and got["t"][-1] >= ref.t[-1] - 8.0, (n, got["t"][-1], ref.t[-1])
    np.testing.assert_array_equal(np.diff(got["t"]) > 0, True)  # no row twice
    np.testing.assert_allclose(got["t"], ref.t[:n], atol=1e-9)
    np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-9)
    np.testing.assert_allclose(got["cov"], ref.cov_xy[:n], atol=1e-9)


@NEEDS_RAY
def test_serve_refuses_bad_ray_options() -> None:
    from typer.testing import CliRunner

    from hrtls.cli.app import app

    r = CliRunner().invoke(app, ["serve", "--engine", "spark"])
    assert r.exit_code != 0 and "--engine" in r.output
    r = CliRunner().invoke(app, ["serve", "--engine", "ray", "--ray-shards", "0"])
    assert r.exit_code != 0 and "--ray-shards" in r.output
    r = CliRunner().invoke(app, ["serve", "--engine", "processes", "--process-shards", "0"])
    assert r.exit_code != 0 and "--process-shards" in r.output
