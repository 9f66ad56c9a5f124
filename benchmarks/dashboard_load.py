"""Dashboard load: N live, tracked agents in chromium; frame time, update latency and memory.

A real ``hrtls serve`` on loopback (its own SQLite file) gets N robot agents that stream wheel
odometry poses through :class:`hrtls.service.client.AgentClient` (the cheapest live tracker, so
the service keeps up on a small machine). Each agent first sends a backlog batch of
``BACKLOG_S`` seconds (the service started a tracker without IMU after 30 s of data when the
tables in docs/dashboard.md were measured; a robot's now starts on its first poses) and then one
batch every ``--batch-s`` seconds. Once at least 90 % of the agents are drawn, the
signed-in dashboard is measured for ``--seconds``: the intervals between animation frames
(requestAnimationFrame), the time of each render, the update latency (wall clock when a delta
reaches the page minus the time the service computed the estimate, ``received_t``), the
JS heap (``performance.memory`` with --enable-precise-memory-info) and the DOM size. Printed,
not asserted::

    python benchmarks/dashboard_load.py --agents 300 --seconds 30
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "web"))

from conftest import chromium_executable, login, start_service, stop_service
from hrtls.service.client import AgentClient

BACKLOG_S = 31.0

MEASURE_JS = """(seconds) => new Promise((done) => {
    const board = window.hrtlsDashboard;
    const frames = [], renders = [], latency = [];
    const render = board.render.bind(board), applyDelta = board.applyDelta.bind(board);
    board.render = () => { const t0 = performance.now(); render();
                           renders.push(performance.now() - t0); };
    board.applyDelta = (d) => {
        const now = Date.now() / 1000 - board.mission.t0Unix;  // same machine, same clock
        for (const e of d.estimates) latency.push(1000 * (now - e.received_t));
        applyDelta(d);
    };
    let last = performance.now();
    const end = last + seconds * 1000;
    const tick = (now) => {
        frames.push(now - last); last = now;
        if (now < end) { requestAnimationFrame(tick); return; }
        board.render = render; board.applyDelta = applyDelta;
        done({frames, renders, latency,
              heap: performance.memory ? performance.memory.usedJSHeapSize : null,
              nodes: document.getElementsByTagName('*').length,
              dots: document.querySelectorAll('path.agent-dot').length});
    };
    requestAnimationFrame(tick);
})"""


def create_agents(service, n: int) -> tuple[int, list[str]]:
    status, mission = service.api("POST", "/missions", {
        "name": f"load {n}", "floors": [{"index": 0, "name": "Ground floor", "height_m": 0.0}]})
    assert status == 201, mission
    tokens = []
    for k in range(n):
        status, out = service.api("POST", f"/missions/{mission['id']}/agents",
                                  {"name": f"A{k:03d}", "kind": "robot"})
        assert status == 201, out
        tokens.append(out["token"])
    return int(mission["id"]), tokens


def _poses(i: int, ts: np.ndarray, t0: float, centre: np.ndarray) -> dict[str, list[float]]:
    ang = 0.3 * (ts - t0) + i
    return {"t": ts.tolist(), "x": (centre[0] + 2 * np.cos(ang)).tolist(),
            "y": (centre[1] + 2 * np.sin(ang)).tolist(),
            "heading_rad": (ang + np.pi / 2).tolist(), "sigma_m": [0.3] * len(ts)}


def stream(server: str, tokens: list[str], *, t0: float, seconds: float, batch_s: float,
           stop: threading.Event, sent: list[int]) -> None:
    """Each agent drives a circle of its own: a backlog batch, then 5 poses every batch_s."""
    clients = [AgentClient(server, tok, fmt="msgpack") for tok in tokens]
    n = len(clients)
    centres = np.column_stack([(np.arange(n) % 20) * 6.0, (np.arange(n) // 20) * 6.0])
    t_start = t0 - BACKLOG_S
    for i, c in enumerate(clients):
        c.checkin({"t": t_start, "x": centres[i, 0] + 2 * np.cos(i),
                   "y": centres[i, 1] + 2 * np.sin(i), "z": 0.0, "heading": i + np.pi / 2,
                   "sigma_xy_m": 0.3, "sigma_heading_rad": 0.1})
        c.submit({"odometry": _poses(i, np.arange(t_start, t0, 0.2), t_start, centres[i])})
        sent[0] += 1
    start = time.monotonic()
    k = 0
    while not stop.is_set() and time.monotonic() - start < seconds:
        t_batch = t0 + k * batch_s
        ts = t_batch + np.linspace(0, batch_s, 5, endpoint=False)
        for i, c in enumerate(clients):
            c.submit({"odometry": _poses(i, ts, t_start, centres[i])})
            sent[0] += 1
        k += 1
        due = start + k * batch_s
        time.sleep(max(0.0, due - time.monotonic()))
    for c in clients:
        c.close()


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, nargs="+", default=[10, 100, 300])
    ap.add_argument("--seconds", type=float, default=30.0, help="measured window per N")
    ap.add_argument("--batch-s", type=float, default=1.0)
    ap.add_argument("--wait-s", type=float, default=240.0,
                    help="longest wait for 90 %% of the agents to be drawn")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    rows = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium_executable(), args=[
            "--no-sandbox", "--disable-gpu", "--enable-precise-memory-info"])
        for n in args.agents:
            with tempfile.TemporaryDirectory() as tmp:
                service = start_service(Path(tmp))
                try:
                    mid, tokens = create_agents(service, n)
                    _, m = service.api("GET", f"/missions/{mid}")
                    stop, sent = threading.Event(), [0]
                    feeder = threading.Thread(target=stream, args=(service.url, tokens), kwargs={
                        "t0": float(m["now_t"]), "seconds": args.seconds + args.wait_s + 10,
                        "batch_s": args.batch_s, "stop": stop, "sent": sent}, daemon=True)
                    feeder.start()
                    page = browser.new_page(viewport={"width": 1400, "height": 900})
                    login(page, service)
                    page.goto(f"{service.url}/?mission={mid}")
                    page.wait_for_selector("#app:not([hidden])")
                    started = time.monotonic()
                    drawn = 0
                    while time.monotonic() - started < args.wait_s:
                        drawn = page.evaluate("document.querySelectorAll('path.agent-dot').length")
                        if drawn >= 0.9 * n:
                            break
                        time.sleep(1.0)
                    waited = time.monotonic() - started
                    if drawn < 0.9 * n:
                        print(f"{n} agents: only {drawn} drawn after {waited:.0f} s "
                              "(the service is behind); measured anyway", file=sys.stderr)
                    r = page.evaluate(MEASURE_JS, args.seconds)
                    _, snap = service.api("GET", f"/missions/{mid}/snapshot")
                    stop.set()
                    feeder.join(timeout=30)
                    page.close()
                finally:
                    stop_service(service)
            f = r["frames"][1:]
            rows.append((n, r["dots"], len(snap["estimates"]), waited, _pct(f, 50), _pct(f, 95),
                         max(f), _pct(r["renders"], 50), _pct(r["renders"], 95),
                         _pct(r["latency"], 50), _pct(r["latency"], 95),
                         max(r["latency"], default=float("nan")), len(r["latency"]),
                         sum(v > 1000.0 for v in r["latency"]),
                         (r["heap"] or 0) / 2**20, r["nodes"], sent[0]))
        browser.close()
    print(f"dashboard load, {args.seconds:g} s measured per row, one batch per agent every "
          f"{args.batch_s:g} s (chromium {chromium_executable()}, this machine)")
    head = ("agents", "dots shown", "estimates", "wait s", "frame p50 ms", "frame p95 ms",
            "frame max ms", "render p50 ms", "render p95 ms", "update p50 ms", "update p95 ms",
            "update max ms", "updates", "updates > 1 s", "JS heap MiB", "DOM nodes",
            "batches sent")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.0f} | {r[4]:.1f} | {r[5]:.1f} | {r[6]:.1f} "
              f"| {r[7]:.1f} | {r[8]:.1f} | {r[9]:.0f} | {r[10]:.0f} | {r[11]:.0f} | {r[12]} "
              f"| {r[13]} | {r[14]:.1f} | {r[15]} | {r[16]} |")


if __name__ == "__main__":
    main()
