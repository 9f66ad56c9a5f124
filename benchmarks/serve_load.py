"""Load test of ``hrtls serve`` on loopback: N agents streaming 100 Hz IMU plus infrastructure.

Each agent replays a simulated office walk (beacon RSS, RFID tags, radio ranges) in real time
as 0.5 s msgpack batches over its ingest WebSocket, waiting for each ack; the numeric columns
go as binary column blocks (``--format blocks``, what ``hrtls.service.client`` sends) or as
lists (``--format rows``, the older format). The load generator
is cheap per message (frames encoded before the start, ``--agents-per-process`` agents per
process) so that the table measures the service, not the client; a dashboard WebSocket watches
the mission. Per N the table gives:

* sensor-to-WebSocket latency: wall time from the sensing of a batch's newest sample to the
  first delta that reports it processed (the agent's ``status.last_data_t``; a later delta
  repeating the same time, e.g. when the agent goes silent after its stream, is not counted
  again), p50/p99/max;
* estimate lag: wall time from an estimate's own time to its delta (includes the step
  detection of the tracker: a step is known when it ends);
* lost (sent - acknowledged), duplicated (stored twice: the raw log's unique seq), 429 retries;
* IMU samples per second stored, server memory per agent (RSS growth / N);
* the machine's 1-minute load average at the end of the level (the machine is shared: a
  load above its core count means the figures of that level are inflated by other jobs);
* the server's CPU time (its process and descendants: tracker processes, Ray) over the
  level's wall time, % of one core (less sensitive to other jobs than the latencies), and the
  load generator's (all its processes) beside it.

N is *sustained* when p99 latency <= 1 s with zero loss and duplicates. Bounded: each N runs
``--duration-s`` (default 60 s; the issue's figure is 300 s) and the whole run stops adding N
after ``--time-limit-s``. Only loopback is used.

    python benchmarks/serve_load.py --agents 5,10,20,40 --duration-s 60
    python benchmarks/serve_load.py --agents 5,10,20,40 --duration-s 60 --engine ray
    python benchmarks/serve_load.py --agents 100,200,300 --duration-s 60 --engine processes

The issue's figure (300 agents at 100 Hz for 5 minutes, trackers in two worker processes;
run it on a quiet machine, about 25 minutes with the warm-up and the set-up of the agents)::

    python benchmarks/serve_load.py --agents 300 --duration-s 300 --engine processes \
        --process-shards 2 --time-limit-s 3600

and the same with ``--format rows`` for the list format.

The issue's Ray target compares the two: the Ray runner should sustain >= 90 % of the agents
of the in-process runner on the same machine.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
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

from hrtls.service.batches import PARTS, numeric_fields
from hrtls.service.client import session_batches
from hrtls.service.columns import block
from hrtls.sim.scenarios import run_scenario

API = "/api/v1"
HRTLS = [sys.executable, "-c", "from hrtls.cli.app import main; main()"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def tree(pid: int) -> list[int]:
    """``pid`` and its descendants (the server's tracker processes, Ray's processes)."""
    out = [pid]
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids = (task / "children").read_text().split()
        except OSError:
            continue
        for kid in kids:
            out += tree(int(kid))
    return out


def rss_kib(pid: int) -> int:
    """Resident memory of ``pid`` and its descendants, KiB."""
    total = 0
    for p in tree(pid):
        try:
            lines = Path(f"/proc/{p}/status").read_text().splitlines()
        except OSError:
            continue
        total += sum(int(line.split()[1]) for line in lines if line.startswith("VmRSS:"))
    return total


def cpu_s(pid: int) -> float:
    """User + system CPU time of process ``pid`` and its descendants, s."""
    total = 0
    for p in tree(pid):
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])
    return total / os.sysconf("SC_CLK_TCK")


def start_server(db: str, port: int, args: argparse.Namespace
                 ) -> tuple[subprocess.Popen[str], str]:
    env = {**os.environ}
    log: Path | None = args.server_log
    shards = {"ray": ["--ray-shards", str(args.ray_shards)],
              "processes": ["--process-shards", str(args.process_shards)]}
    runner = ["--engine", args.engine, *shards.get(args.engine, [])]
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


SETUP_CONCURRENCY = 8
"""Agents created and checked in at once while a level is set up (not measured)."""


def _as_blocks(part: str, cols: dict) -> dict:
    numeric = numeric_fields(part)
    return {k: block(np.asarray(v, dtype=np.float64)) if k in numeric and v is not None else v
            for k, v in cols.items()}


def _frames(batches: list[tuple[float, dict]], t_start: float,
            fmt: str) -> list[tuple[float, bytes, int]]:
    """``(t_end, msgpack frame, IMU samples)`` of each batch, times shifted by ``t_start``."""
    out = []
    for seq, (t_end, b) in enumerate(batches):
        b2 = {**b, "seq": seq}
        for part in PARTS:
            if part in b2 and b2[part] is not None:
                b2[part] = {**b2[part], "t": [x + t_start for x in b2[part]["t"]]}
                if fmt == "blocks":
                    b2[part] = _as_blocks(part, b2[part])
        out.append((t_end, msgpack.packb({"type": "batch", "batch": b2}),
                    len(b.get("imu", {}).get("t", []))))
    return out


async def _stream_agents(ws_url: str, agents: list[tuple[int, str, int]], streams: list,
                         start_wall: float, t_start: float, fmt: str) -> dict[str, float]:
    """Stream every agent's batches over its ingest WebSocket, each when its last sample is
    due; resend after 429. The counts and this process's CPU time."""
    counts = {"sent": 0.0, "acked": 0.0, "dup": 0.0, "r429": 0.0, "samples": 0.0}
    frames = {k: _frames(streams[k][1], t_start, fmt) for k in {k for _, _, k in agents}}

    async def agent(tok: str, k: int) -> None:
        async with websockets.connect(f"{ws_url}{API}/ingest/ws", max_size=2**24,
                                      compression=None,
                                      additional_headers={"Authorization": f"Bearer {tok}"}
                                      ) as ws:
            for t_end, frame, n_imu in frames[k]:
                delay = start_wall + t_end - time.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                while True:
                    counts["sent"] += 1
                    await ws.send(frame)
                    while True:   # skip orders and anything else that is not our answer
                        reply = json.loads(await ws.recv())
                        if reply.get("type") in ("ack", "error"):
                            break
                    if reply["type"] == "error" and reply.get("status") == 429:
                        counts["r429"] += 1
                        await asyncio.sleep(float(reply.get("retry_after_s", 1.0)))
                        continue
                    if reply["type"] == "error":
                        raise RuntimeError(f"batch refused: {reply}")
                    counts["acked"] += 1
                    counts["dup"] += reply["status"] == "duplicate"
                    counts["samples"] += n_imu
                    break

    await asyncio.gather(*(agent(tok, k) for _, tok, k in agents))
    counts["cpu_s"] = time.process_time()
    return counts


def _agent_process(ws_url: str, agents: list[tuple[int, str, int]], streams: list,
                   start_wall: float, t_start: float, fmt: str, out: mp.Queue) -> None:
    try:
        out.put(asyncio.run(_stream_agents(ws_url, agents, streams, start_wall, t_start,
                                           fmt)))
    except Exception as exc:   # reported by the parent
        out.put({"error": f"{type(exc).__name__}: {exc}"})


async def run_level(url: str, token: str, n: int, streams: list, duration_s: float,
                    per_process: int, fmt: str) -> dict:
    h = {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(base_url=url, headers=h, timeout=60) as c:
        meta0 = streams[0][0]
        m = (await c.post(f"{API}/missions", json={"name": f"load {n}",
                                                   "channel": meta0["channel"]})).json()
        mid, t0_unix = m["id"], m["t0_unix"]
        for lm in meta0["landmarks"]:
            (await c.post(f"{API}/missions/{mid}/landmarks", json=lm)).raise_for_status()
        gate = asyncio.Semaphore(SETUP_CONCURRENCY)

        async def create(i: int) -> tuple[int, str, int]:
            meta, _ = streams[i % len(streams)]
            async with gate:
                r = await c.post(f"{API}/missions/{mid}/agents", json={
                    "name": f"A{i}", "placement": meta["placement"], "user": meta["user"],
                    "mounting_q_bd": meta["mounting_q_bd"]})
            r.raise_for_status()
            return r.json()["agent"]["id"], r.json()["token"], i % len(streams)

        agents = list(await asyncio.gather(*(create(i) for i in range(n))))
        start_wall = time.time() + 3.0 + 0.02 * n
        t_start = start_wall - t0_unix      # mission time at which every session starts

        async def checkin(aid: int, k: int) -> None:
            pose = {**streams[k][0]["start_pose"], "t": t_start}
            async with gate:
                r = await c.post(f"{API}/missions/{mid}/agents/{aid}/checkin", json=pose)
            r.raise_for_status()

        await asyncio.gather(*(checkin(aid, k) for aid, _, k in agents))
    lat: list[float] = []
    lat_at: list[float] = []   # when each latency was seen, s after the start
    lag: list[float] = []
    reported: dict[int, float] = {}   # agent id -> newest data time a delta reported
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
                if msg.get("type") != "delta" or now <= start_wall + 8.0:
                    continue
                for a in msg["agents"]:
                    t_data = a["status"]["last_data_t"]
                    # the first delta that reports new data; later deltas (a status change,
                    # the agent gone silent after its stream ended) repeat an old time
                    if t_data is not None and t_data != reported.get(a["id"]):
                        reported[a["id"]] = t_data
                        lat.append(now - (t0_unix + t_data))
                        lat_at.append(now - start_wall)
                lag.extend(now - (t0_unix + e["t"]) for e in msg["estimates"])

    ctx = mp.get_context("fork")
    out: mp.Queue = ctx.Queue()
    shards = [agents[i:i + per_process] for i in range(0, n, per_process)]
    procs = [ctx.Process(target=_agent_process, daemon=True,
                         args=(url.replace("http", "ws"), shard, streams, start_wall, t_start,
                               fmt, out)) for shard in shards]
    cpu0 = time.process_time()
    dash = asyncio.create_task(dashboard())
    t_run = time.time()
    for proc in procs:
        proc.start()
    loop = asyncio.get_running_loop()
    results = [await loop.run_in_executor(None, out.get, True, duration_s + 120.0)
               for _ in procs]
    for proc in procs:
        proc.join(timeout=10)
    await asyncio.sleep(2.0)
    stop.set()
    await dash
    wall = time.time() - t_run
    errors = [r["error"] for r in results if "error" in r]
    if errors:
        raise RuntimeError("; ".join(errors))
    counts = {k: int(sum(r[k] for r in results)) for k in ("sent", "acked", "dup", "r429",
                                                            "samples")}
    client_cpu_s = sum(r["cpu_s"] for r in results) + time.process_time() - cpu0
    expected = sum(len(streams[k][1]) for _, _, k in agents)
    return {"mission": mid, "lat": np.array(lat), "lat_at": np.array(lat_at),
            "lag": np.array(lag), "wall_s": wall,
            "expected": expected, "client_cpu_pct": 100.0 * client_cpu_s / wall, **counts}


def p(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if len(a) else float("nan")


WARM_UP_S = 15.0


def warm_up(tmp: Path, streams: list, args: argparse.Namespace) -> float:
    """A short unreported level: the server compiles its kernels into the cache the measured
    servers load them from (a cold cache made the first level tens of seconds late); s."""
    start = time.time()
    short = [(meta, [(t, b) for t, b in batches if t <= WARM_UP_S]) for meta, batches in streams]
    port = free_port()
    proc, token = start_server(str(tmp / "warm-up.db"), port, args)
    try:
        asyncio.run(run_level(f"http://127.0.0.1:{port}", token, 2, short, WARM_UP_S,
                              args.agents_per_process, args.format))
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=60)
    return time.time() - start


WINDOW_S = 5.0


def _windows(lat: np.ndarray, at: np.ndarray) -> str:
    """The largest latency in each ``WINDOW_S`` of the level (where the slow deltas were)."""
    if not len(lat):
        return "-"
    k = (at // WINDOW_S).astype(int)
    return " ".join(f"{lat[k == i].max():.1f}" if np.any(k == i) else "-"
                    for i in range(k.min(), k.max() + 1))


def _row(r: tuple) -> str:
    return (f"| {r[0]} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.2f} | {r[5]:.2f} | "
            f"{r[6]} | {r[7]} | {r[8]} | {r[9]:.0f} | {r[10]:.1f} | "
            f"{'yes' if r[11] else 'no'} | {r[12]:.1f} | {r[13]:.0f} | {r[14]:.0f} |")


ISSUE_RUN = """the issue's figure (300 agents at 100 Hz for 5 minutes, trackers in two worker
processes; on a quiet machine, about 25 minutes with the warm-up and the agents' set-up):

  python benchmarks/serve_load.py --agents 300 --duration-s 300 --engine processes \\
      --process-shards 2 --time-limit-s 3600

and the same with --format rows for the list format."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=ISSUE_RUN,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--agents", default="5,10,20,40")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--time-limit-s", type=float, default=1200.0)
    ap.add_argument("--distinct", type=int, default=4, help="distinct simulated walks")
    ap.add_argument("--engine", choices=("local", "processes", "ray"), default="local",
                    help="where the server's trackers run (processes: local worker processes, "
                         "ray: shard actors, local Ray)")
    ap.add_argument("--process-shards", type=int, default=2,
                    help="worker processes with --engine processes")
    ap.add_argument("--ray-shards", type=int, default=2, help="shard actors with --engine ray")
    ap.add_argument("--agents-per-process", type=int, default=50,
                    help="agents one load-generator process streams")
    ap.add_argument("--format", choices=("blocks", "rows"), default="blocks",
                    help="numeric columns as binary column blocks (what the Python client "
                         "sends) or as lists (the older format)")
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
            proc, token = start_server(str(Path(tmp) / f"load{n}.db"), port, args)
            try:
                rss0, cpu0 = rss_kib(proc.pid), cpu_s(proc.pid)
                try:
                    res = asyncio.run(run_level(f"http://127.0.0.1:{port}", token, n, streams,
                                                args.duration_s, args.agents_per_process,
                                                args.format))
                except (httpx.HTTPError, OSError, TimeoutError, RuntimeError) as exc:
                    print(f"| {n} | failed: {type(exc).__name__}: {exc} |",
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
                         os.getloadavg()[0], 100.0 * (cpu1 - cpu0) / res["wall_s"],
                         res["client_cpu_pct"]))
            print(_row(rows[-1]) + f"  ({res['wall_s']:.0f} s; latency max per "
                  f"{WINDOW_S:.0f} s: {_windows(res['lat'], res['lat_at'])})", flush=True)
    print()
    print("(server CPU % and MiB/agent: the server process and its descendants, i.e. its "
          "tracker processes; % of one core)")
    print("| agents | latency p50 s | p99 s | max s | estimate lag p50 s | p99 s | lost | dup |"
          " 429 retries | IMU samples/s | MiB/agent | sustained | load 1 min | server CPU % |"
          " client CPU % |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(_row(r))
    best = max((r[0] for r in rows if r[11]), default=0)
    print(f"\nformat {args.format}, engine {args.engine}"
          + (f" ({args.ray_shards} shard actors)" if args.engine == "ray" else "")
          + (f" ({args.process_shards} processes)" if args.engine == "processes" else "")
          + f": largest sustained N: {best} (duration {args.duration_s:.0f} s per level, "
          f"{os.cpu_count()} CPUs, shared)")


if __name__ == "__main__":
    main()
