"""Load test of ``hrtls serve`` on loopback: N agents streaming 100 Hz IMU plus infrastructure.

Each agent replays a simulated office walk (beacon RSS, RFID tags, radio ranges) in real time
as 0.5 s msgpack batches over HTTP. A dashboard WebSocket watches the mission. Per N the table
gives:

* sensor-to-WebSocket latency: wall time from the sensing of a batch's newest sample to the
  delta that reports it processed (the agent's ``status.last_data_t``), p50/p99/max;
* estimate lag: wall time from an estimate's own time to its delta (includes the step
  detection of the tracker: a step is known when it ends);
* lost (sent - acknowledged), duplicated (stored twice: the raw log's unique seq), 429 retries;
* IMU samples per second stored, server memory per agent (RSS growth / N);
* the machine's 1-minute load average at the end of the level (the machine is shared: a
  load above its core count means the figures of that level are inflated by other jobs);
* the server process's CPU time over the level's wall time, % of one core (less sensitive
  to other jobs than the latencies).

N is *sustained* when p99 latency <= 1 s with zero loss and duplicates. Bounded: each N runs
``--duration-s`` (default 60 s; the issue's figure is 300 s) and the whole run stops adding N
after ``--time-limit-s``. Only loopback is used.

    python benchmarks/serve_load.py --agents 5,10,20,40 --duration-s 60
    python benchmarks/serve_load.py --agents 5,10,20,40 --duration-s 60 --engine ray

The issue's Ray target compares the two: the Ray runner should sustain >= 90 % of the agents
of the in-process runner on the same machine.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import msgpack
import numpy as np
import websockets

from hrtls.service.client import session_batches
from hrtls.sim.scenarios import run_scenario

API = "/api/v1"
HRTLS = [sys.executable, "-c", "from hrtls.cli.app import main; main()"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def cpu_s(pid: int) -> float:
    """User + system CPU time of process ``pid``, s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def start_server(db: str, port: int, engine: str, ray_shards: int, log: Path | None
                 ) -> tuple[subprocess.Popen[str], str]:
    env = {**os.environ}
    runner = ["--engine", engine] + (["--ray-shards", str(ray_shards)] if engine == "ray" else [])
    proc = subprocess.Popen([*HRTLS, "serve", "--db", db, "--port", str(port),
                             "--rate-per-agent", "20", "--queue-batches", "256", *runner],
                            stdout=subprocess.PIPE, text=True,
                            stderr=subprocess.DEVNULL if log is None else log.open("a"),
                            env=env)
    assert proc.stdout is not None
    proc.stdout.readline()
    token = proc.stdout.readline().rsplit(" ", 1)[-1].strip()
    for _ in range(600):
        try:
            httpx.get(f"http://127.0.0.1:{port}{API}/health", timeout=2)
            return proc, token
        except httpx.TransportError:
            time.sleep(0.1)
    raise RuntimeError("server did not start")


def prepare(duration_s: float, n_distinct: int) -> list[tuple[dict, list[tuple[float, dict]]]]:
    out = []
    for seed in range(n_distinct):
        s = run_scenario("office_random_walk", seed=100 + seed,
                         duration_s=duration_s).session
        meta = s.meta
        batches = [(t_end, b) for t_end, b in session_batches(s, chunk_s=0.5)
                   if t_end <= duration_s]
        out.append(({"placement": meta.placement, "user": {"height_m": meta.user.height_m,
                                                           "step_model": meta.user.step_model},
                     "mounting_q_bd": list(meta.mounting_q_bd or (1.0, 0.0, 0.0, 0.0)),
                     "start_pose": meta.start_pose.model_dump() if meta.start_pose else None,
                     "landmarks": [lm.model_dump(mode="json", exclude_none=True)
                                   for lm in s.landmarks.values()],
                     "channel": meta.channel.model_dump() if meta.channel else None},
                    batches))
    return out


async def run_level(url: str, token: str, n: int, streams: list, duration_s: float) -> dict:
    h = {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(base_url=url, headers=h, timeout=60,
                                 limits=httpx.Limits(max_connections=200)) as c:
        meta0 = streams[0][0]
        m = (await c.post(f"{API}/missions", json={"name": f"load {n}",
                                                   "channel": meta0["channel"]})).json()
        mid, t0_unix = m["id"], m["t0_unix"]
        for lm in meta0["landmarks"]:
            await c.post(f"{API}/missions/{mid}/landmarks", json=lm)
        agents = []
        for i in range(n):
            meta, _ = streams[i % len(streams)]
            r = (await c.post(f"{API}/missions/{mid}/agents", json={
                "name": f"A{i}", "placement": meta["placement"], "user": meta["user"],
                "mounting_q_bd": meta["mounting_q_bd"]})).json()
            agents.append((r["agent"]["id"], r["token"], i % len(streams)))
    start_wall = time.time() + 2.0
    t_start = start_wall - t0_unix      # mission time at which every session starts
    lat: list[float] = []
    lag: list[float] = []
    counts = {"sent": 0, "acked": 0, "dup": 0, "r429": 0, "samples": 0}
    stop = asyncio.Event()

    async def dashboard() -> None:
        async with websockets.connect(url.replace("http", "ws") + f"{API}/missions/{mid}/ws",
                                      additional_headers=h, max_size=2**24) as ws:
            while not stop.is_set():
                try:
                    raw = await asyncio.wait_for(ws.recv(), timeout=1.0)
                except TimeoutError:
                    continue
                now = time.time()
                msg = json.loads(raw)
                if msg.get("type") != "delta":
                    continue
                for a in msg["agents"]:
                    t_data = a["status"]["last_data_t"]
                    if t_data is not None and now > start_wall + 8.0:
                        lat.append(now - (t0_unix + t_data))
                for e in msg["estimates"]:
                    if now > start_wall + 8.0:
                        lag.append(now - (t0_unix + e["t"]))

    async def agent(aid: int, tok: str, k: int) -> None:
        meta, batches = streams[k]
        async with httpx.AsyncClient(base_url=url, timeout=60,
                                     headers={"Authorization": f"Bearer {tok}"}) as ac:
            pose = dict(meta["start_pose"])
            pose["t"] = t_start
            await ac.post(f"{API}/missions/{mid}/agents/{aid}/checkin", json=pose)
            for seq, (t_end, b) in enumerate(batches):
                due = start_wall + t_end
                delay = due - time.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                b2 = {**b, "seq": seq}
                for part in ("imu", "rss", "tags", "ranges", "fixes", "baro"):
                    if part in b2 and b2[part] is not None:
                        b2[part] = {**b2[part], "t": [x + t_start for x in b2[part]["t"]]}
                body = msgpack.packb(b2)
                while True:
                    counts["sent"] += 1
                    r = await ac.post(f"{API}/ingest", content=body,
                                      headers={"Content-Type": "application/msgpack"})
                    if r.status_code == 429:
                        counts["r429"] += 1
                        await asyncio.sleep(float(r.headers.get("retry-after", "1")))
                        continue
                    r.raise_for_status()
                    counts["acked"] += 1
                    if r.json()["status"] == "duplicate":
                        counts["dup"] += 1
                    counts["samples"] += len(b.get("imu", {}).get("t", []))
                    break

    dash = asyncio.create_task(dashboard())
    t_run = time.time()
    await asyncio.gather(*(agent(aid, tok, k) for aid, tok, k in agents))
    await asyncio.sleep(2.0)
    stop.set()
    await dash
    wall = time.time() - t_run
    expected = sum(len(streams[k][1]) for _, _, k in agents)
    return {"mission": mid, "lat": np.array(lat), "lag": np.array(lag), "wall_s": wall,
            "expected": expected, **counts}


def p(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if len(a) else float("nan")


WARM_UP_S = 15.0


def warm_up(tmp: Path, streams: list, args: argparse.Namespace) -> float:
    """A short unreported level: the server compiles its kernels into the cache the measured
    servers load them from (a cold cache made the first level tens of seconds late); s."""
    start = time.time()
    short = [(meta, [(t, b) for t, b in batches if t <= WARM_UP_S]) for meta, batches in streams]
    port = free_port()
    proc, token = start_server(str(tmp / "warm-up.db"), port, args.engine, args.ray_shards,
                               args.server_log)
    try:
        asyncio.run(run_level(f"http://127.0.0.1:{port}", token, 2, short, WARM_UP_S))
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=60)
    return time.time() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agents", default="5,10,20,40")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--time-limit-s", type=float, default=1200.0)
    ap.add_argument("--distinct", type=int, default=4, help="distinct simulated walks")
    ap.add_argument("--engine", choices=("local", "ray"), default="local",
                    help="where the server's trackers run (ray: shard actors, local Ray)")
    ap.add_argument("--ray-shards", type=int, default=2, help="shard actors with --engine ray")
    ap.add_argument("--server-log", type=Path, default=None, help="append the server's stderr here")
    args = ap.parse_args()
    levels = [int(x) for x in args.agents.split(",")]
    streams = prepare(args.duration_s + 5.0, args.distinct)
    began = time.time()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        print(f"warm-up level: {warm_up(Path(tmp), streams, args):.0f} s", flush=True)
        for n in levels:
            if time.time() - began > args.time_limit_s:
                print(f"time limit reached before N={n}")
                break
            port = free_port()
            proc, token = start_server(str(Path(tmp) / f"load{n}.db"), port, args.engine,
                                       args.ray_shards, args.server_log)
            try:
                rss0, cpu0 = rss_kib(proc.pid), cpu_s(proc.pid)
                try:
                    res = asyncio.run(run_level(f"http://127.0.0.1:{port}", token, n, streams,
                                                args.duration_s))
                except (httpx.HTTPError, OSError, TimeoutError) as exc:
                    print(f"| {n} | failed: {type(exc).__name__} (server overloaded) |",
                          flush=True)
                    break
                rss1, cpu1 = rss_kib(proc.pid), cpu_s(proc.pid)
            finally:
                proc.terminate()  # SIGTERM: the server also shuts its Ray runtime down
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=60)
            db = __import__("sqlite3").connect(str(Path(tmp) / f"load{n}.db"))
            stored = db.execute("SELECT count(*), count(DISTINCT agent_id || '-' || seq) "
                                "FROM raw_batches").fetchone()
            db.close()
            lat, lag = res["lat"], res["lag"]
            lost = res["expected"] - res["acked"] + res["dup"]
            dup = stored[0] - stored[1]
            ok = bool(len(lat)) and p(lat, 99) <= 1.0 and lost == 0 and dup == 0 \
                and stored[0] == res["expected"]
            rows.append((n, p(lat, 50), p(lat, 99), float(lat.max()) if len(lat) else 0.0,
                         p(lag, 50), p(lag, 99), lost, dup, res["r429"],
                         res["samples"] / args.duration_s, (rss1 - rss0) / n / 1024.0, ok,
                         os.getloadavg()[0], 100.0 * (cpu1 - cpu0) / res["wall_s"]))
            r = rows[-1]
            print(f"| {r[0]} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.2f} | {r[5]:.2f} | "
                  f"{r[6]} | {r[7]} | {r[8]} | {r[9]:.0f} | {r[10]:.1f} | "
                  f"{'yes' if r[11] else 'no'} | {r[12]:.1f} | {r[13]:.0f} |  "
                  f"({res['wall_s']:.0f} s)", flush=True)
    print()
    if args.engine == "ray":
        print("(MiB/agent is the server process only; with Ray the trackers live in the actors)")
    print("| agents | latency p50 s | p99 s | max s | estimate lag p50 s | p99 s | lost | dup |"
          " 429 retries | IMU samples/s | MiB/agent | sustained | load 1 min | server CPU % |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.2f} | {r[5]:.2f} | "
              f"{r[6]} | {r[7]} | {r[8]} | {r[9]:.0f} | {r[10]:.1f} | "
              f"{'yes' if r[11] else 'no'} | {r[12]:.1f} | {r[13]:.0f} |")
    best = max((r[0] for r in rows if r[11]), default=0)
    print(f"\nengine {args.engine}"
          + (f" ({args.ray_shards} shard actors)" if args.engine == "ray" else "")
          + f": largest sustained N: {best} (duration {args.duration_s:.0f} s per level, "
          f"{os.cpu_count()} CPUs, shared)")


if __name__ == "__main__":
    main()
