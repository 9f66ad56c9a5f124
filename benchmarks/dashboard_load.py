"""Dashboard load: N live agents in chromium; frame time and memory measured in the browser.

A real ``hrtls serve`` on loopback (its own SQLite file) gets N agents; each streams wheel
odometry poses (a robot-like agent: the cheapest live tracker, so the service keeps up on a
small machine) through :class:`hrtls.service.client.AgentClient`, one batch per agent every
``--batch-s`` seconds, for ``--seconds``. The signed-in dashboard runs meanwhile; the page
measures the intervals between animation frames (requestAnimationFrame), the JS heap
(``performance.memory`` with --enable-precise-memory-info) and the DOM size. Printed, not
asserted::

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

MEASURE_JS = """(seconds) => new Promise((done) => {
    const frames = [];
    let last = performance.now();
    const end = last + seconds * 1000;
    const tick = (now) => {
        frames.push(now - last); last = now;
        if (now < end) requestAnimationFrame(tick);
        else done({frames, heap: performance.memory ? performance.memory.usedJSHeapSize : null,
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


def stream(server: str, tokens: list[str], *, t0: float, seconds: float, batch_s: float,
           stop: threading.Event, sent: list[int]) -> None:
    """Each agent walks a circle of its own; one batch of 5 poses per agent per batch_s."""
    clients = [AgentClient(server, tok, fmt="msgpack") for tok in tokens]
    n = len(clients)
    centres = np.column_stack([(np.arange(n) % 20) * 6.0, (np.arange(n) // 20) * 6.0])
    for i, c in enumerate(clients):
        c.checkin({"t": t0, "x": centres[i, 0] + 2 * np.cos(i), "y": centres[i, 1] + 2 * np.sin(i),
                   "z": 0.0, "heading": i + np.pi / 2, "sigma_xy_m": 0.3,
                   "sigma_heading_rad": 0.1})
    start = time.monotonic()
    k = 0
    while not stop.is_set() and time.monotonic() - start < seconds:
        t_batch = t0 + k * batch_s
        ts = t_batch + np.linspace(0, batch_s, 5, endpoint=False)
        for i, c in enumerate(clients):
            ang = 0.3 * (ts - t0) + i
            c.submit({"odometry": {"t": ts.tolist(),
                                   "x": (centres[i, 0] + 2 * np.cos(ang)).tolist(),
                                   "y": (centres[i, 1] + 2 * np.sin(ang)).tolist(),
                                   "heading_rad": (ang + np.pi / 2).tolist(),
                                   "sigma_m": [0.3] * len(ts)}})
            sent[0] += 1
        k += 1
        due = start + k * batch_s
        time.sleep(max(0.0, due - time.monotonic()))
    for c in clients:
        c.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, nargs="+", default=[10, 100, 300])
    ap.add_argument("--seconds", type=float, default=30.0, help="measured window per N")
    ap.add_argument("--batch-s", type=float, default=1.0)
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
                        "t0": float(m["now_t"]), "seconds": args.seconds + 40, "batch_s":
                        args.batch_s, "stop": stop, "sent": sent}, daemon=True)
                    feeder.start()
                    page = browser.new_page(viewport={"width": 1400, "height": 900})
                    login(page, service)
                    page.goto(f"{service.url}/?mission={mid}")
                    page.wait_for_selector("#app:not([hidden])")
                    deadline = time.monotonic() + 60
                    while time.monotonic() < deadline and page.evaluate(
                            "document.querySelectorAll('path.agent-dot').length") < 0.9 * n:
                        time.sleep(0.5)
                    r = page.evaluate(MEASURE_JS, args.seconds)
                    _, snap = service.api("GET", f"/missions/{mid}/snapshot")
                    stop.set()
                    feeder.join(timeout=30)
                    page.close()
                finally:
                    stop_service(service)
            f = np.asarray(r["frames"][1:])
            rows.append((n, r["dots"], len(snap["estimates"]), len(f), np.median(f),
                         np.percentile(f, 95), f.max(), (r["heap"] or 0) / 2**20, r["nodes"],
                         sent[0]))
        browser.close()
    print(f"dashboard load, {args.seconds:g} s measured per row, one batch per agent every "
          f"{args.batch_s:g} s (chromium {chromium_executable()}, this machine)")
    head = ("agents", "dots shown", "estimates", "frames", "frame p50 ms", "frame p95 ms",
            "frame max ms", "JS heap MiB", "DOM nodes", "batches sent")
    print(" | ".join(head))
    for r in rows:
        print(f"{r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]:.1f} | {r[5]:.1f} | {r[6]:.1f} | "
              f"{r[7]:.1f} | {r[8]} | {r[9]}")


if __name__ == "__main__":
    main()
