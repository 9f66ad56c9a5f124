"""kill -9 mid-stream: restart, the client resends what was not acknowledged; nothing lost,
estimates equal to the uninterrupted run; a replayed agent exported and tracked offline."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
from sqlalchemy import func, select
from tests.service.streams import API, mission_for, office, offline_rows, start_pose, stored

from hrtls.io.session import write_session
from hrtls.service.client import AgentClient, session_batches
from hrtls.service.db import make_engine, session_factory
from hrtls.service.models import RawBatch
from hrtls.service.settings import Settings

HRTLS = [sys.executable, "-c", "from hrtls.cli.app import main; main()"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _serve(db: str, port: int) -> tuple[subprocess.Popen[str], str | None]:
    proc = subprocess.Popen([*HRTLS, "serve", "--db", db, "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    assert "dashboard" in proc.stdout.readline()
    token = None
    deadline = time.monotonic() + 120
    while True:
        try:
            httpx.get(f"http://127.0.0.1:{port}{API}/health", timeout=2)
            break
        except httpx.TransportError:
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.2)
    return proc, token


def _first_token(db: str) -> str:
    from hrtls.service.app import bootstrap

    secret = bootstrap(Settings(db=db), new_commander=True)
    assert secret is not None
    return secret


def _settle(c: httpx.Client, mid: int, aid: int, last_seq: int, timeout_s: float = 180) -> None:
    deadline = time.monotonic() + timeout_s
    previous = -1
    quiet_since = time.monotonic()
    while time.monotonic() < deadline:
        agent = c.get(f"{API}/missions/{mid}/agents/{aid}").json()
        n = len(c.get(f"{API}/missions/{mid}/estimates", params={"agent": aid}).json())
        if n != previous:
            previous, quiet_since = n, time.monotonic()
        if agent["status"]["acked_through"] == last_seq and not agent["status"]["missing"] \
                and time.monotonic() - quiet_since > 3.0:
            return
        time.sleep(0.3)
    raise AssertionError("estimates did not settle")


def test_kill_9_mid_stream_loses_nothing_and_estimates_equal(db_url: str) -> None:
    session = office()
    port = _free_port()
    commander_token = _first_token(db_url)
    proc, _ = _serve(db_url, port)
    url = f"http://127.0.0.1:{port}"
    batches = [b for _, b in session_batches(session, chunk_s=0.5)]
    kill_at = len(batches) // 2
    try:
        with httpx.Client(base_url=url, headers={"Authorization": f"Bearer {commander_token}"},
                          timeout=30) as c:
            mid, aid, token = mission_for(c, session)
        with AgentClient(url, token, timeout_s=5.0) as agent:
            agent.checkin(start_pose(session))
            for i, b in enumerate(batches):
                if i == kill_at:
                    os.kill(proc.pid, signal.SIGKILL)
                    proc.wait(timeout=30)
                if i == kill_at + 10:
                    assert len(agent.outbox) == 10, "batches sent while down stay buffered"
                    proc, _ = _serve(db_url, port)
                agent.submit(b)
            assert agent.flush() and agent.outbox == {}
            assert agent.stats.gaps >= 1
            # after the gap the newest batch went first, then the back-fill oldest first
            i_new = agent.stats.order.index(kill_at + 10)
            assert agent.stats.order[i_new + 1:i_new + 11] == list(range(kill_at, kill_at + 10))
        with httpx.Client(base_url=url, headers={"Authorization": f"Bearer {commander_token}"},
                          timeout=30) as c:
            _settle(c, mid, aid, len(batches) - 1)
            got = stored(c, mid, aid)
        engine = make_engine(Settings(db=db_url).db_url)
        try:
            with session_factory(engine)() as db:
                n_raw = db.scalar(select(func.count()).select_from(RawBatch)
                                  .where(RawBatch.agent_id == aid))
                seqs = sorted(db.scalars(select(RawBatch.seq).where(RawBatch.agent_id == aid)))
        finally:
            engine.dispose()
        assert n_raw == len(batches) and seqs == list(range(len(batches)))
        ref = offline_rows()
        n = len(got["t"])
        assert n > 100 and got["t"][-1] >= ref.t[-1] - 8.0
        assert np.all(np.diff(got["t"]) > 0), "no duplicated estimates"
        np.testing.assert_allclose(got["t"], ref.t[:n], atol=1e-9)
        np.testing.assert_allclose(got["xy"], ref.xyz[:n, :2], atol=1e-9)
        np.testing.assert_allclose(got["cov"], ref.cov_xy[:n], atol=1e-9)
    finally:
        proc.kill()
        proc.wait(timeout=30)


def test_agent_replay_cli_then_export_is_trackable(db_url: str, tmp_path: Path) -> None:
    session = office()
    rec = write_session(session.with_parts(truth=None), tmp_path / "rec")
    port = _free_port()
    commander_token = _first_token(db_url)
    proc, _ = _serve(db_url, port)
    url = f"http://127.0.0.1:{port}"
    try:
        with httpx.Client(base_url=url, headers={"Authorization": f"Bearer {commander_token}"},
                          timeout=30) as c:
            mid, aid, token = mission_for(c, session)
            out = subprocess.run([*HRTLS, "agent", "replay", str(rec), "--server", url,
                                  "--token", token, "--speed", "0"], capture_output=True,
                                 text=True, timeout=600)
            assert out.returncode == 0, out.stderr
            assert "unacknowledged: 0" in out.stdout
            n_batches = len(list(session_batches(session, chunk_s=0.5)))
            _settle(c, mid, aid, n_batches - 1)
            live_rows = stored(c, mid, aid)
    finally:
        proc.kill()
        proc.wait(timeout=30)
    out = subprocess.run([*HRTLS, "mission", "export", str(mid), "-o", str(tmp_path / "exp"),
                          "--db", db_url], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    folder = tmp_path / "exp" / f"agent-{aid}"
    assert (folder / "service_estimates.csv").is_file() and (tmp_path / "exp" /
                                                             "mission.json").is_file()
    out = subprocess.run([*HRTLS, "track", str(folder), "-o", str(tmp_path / "trk")],
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout + out.stderr
    import csv

    with open(next((tmp_path / "trk").rglob("trajectory.csv"))) as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["t"]) for r in rows])
    n = len(live_rows["t"])
    # the live run (mission time = session time + offset) equals offline tracking of the export
    offset = live_rows["t"][0] - t[0]
    np.testing.assert_allclose(live_rows["t"], t[:n] + offset, atol=1e-6)
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    np.testing.assert_allclose(live_rows["xy"], xy[:n], atol=1e-6)
