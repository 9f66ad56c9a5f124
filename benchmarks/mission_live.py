"""The networked mission live through the service vs offline: node positions, agent tracks.

For each seed a service runs on loopback (a fresh SQLite file; ``--pg URL`` for PostgreSQL),
``inderst_hybrid_mission`` is streamed to it as ``hrtls mission simulate`` does (as fast as the
service acknowledges) and closed, and then the service's mission estimator (fed
batch by batch from the raw log, windows as they complete) is compared with
:meth:`MissionTracker.run` on the same stored data fed at once (``offline_tracker``).
``vs_simulated_sessions``: the same against :meth:`MissionTracker.run` on the simulator's
sessions themselves (their own times and metadata, not what the service received).
Seed 1 has a robot; seed 2 runs the per-agent trackers in worker processes (``engine =
processes``; the mission estimator is in the service process either way).

    python benchmarks/mission_live.py --seeds 0,1,2 [--walk-s 300]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from hrtls.mission.tracker import MissionResult, MissionTracker
from hrtls.pipeline import preset
from hrtls.service.client import AgentClient
from hrtls.service.mission_runner import MissionRunner, offline_tracker
from hrtls.service.network_sim import (
    RESCUER_PRESET,
    create_network_mission,
    network_team,
    stream_network,
)
from hrtls.service.settings import Settings


def result_diff(live: MissionResult, offline: MissionResult, *, shift_s: float = 0.0
                ) -> dict[str, Any]:
    """Largest differences: node positions (m), node covariances (m^2), agent positions (m).

    ``shift_s``: the live times are the offline ones plus this (agent rows are matched by
    count and their times to 1e-6 s, else exactly).
    """
    nodes = sorted(n for n, e in offline.nodes.items() if e.localized)
    same = nodes == sorted(n for n, e in live.nodes.items() if e.localized)
    d_node = max((float(np.max(np.abs(live.nodes[n].position_m - offline.nodes[n].position_m)))
                  for n in nodes), default=0.0)
    d_cov = max((float(np.max(np.abs(live.nodes[n].covariance_m2
                                     - offline.nodes[n].covariance_m2))) for n in nodes),
                default=0.0)
    d_agent = 0.0
    rows = 0
    for k, r in offline.agents.items():
        a, b = r.trajectory, live.agents[k].trajectory
        same_t = np.array_equal(a.t, b.t) if shift_s == 0.0 else \
            len(a.t) == len(b.t) and bool(np.allclose(a.t + shift_s, b.t, rtol=0, atol=1e-6))
        if len(a.t) != len(b.t) or not same_t:
            d_agent = math.inf
            continue
        rows += len(a.t)
        d_agent = max(d_agent, float(np.max(np.abs(a.xyz - b.xyz))))
    hist = all(np.array_equal(h.position_m, live.node_history[n].position_m)
               for n, h in offline.node_history.items()) and \
        set(offline.node_history) == set(live.node_history)
    return {"localized": len(nodes), "nodes": len(offline.nodes), "same_localized": same,
            "node_m": d_node, "node_cov_m2": d_cov, "agent_m": d_agent, "agent_rows": rows,
            "same_history": hist}


def wait_done(runner: MissionRunner, mission_id: int, timeout_s: float) -> MissionTracker:
    """The live estimator once it consumed every batch and processed every window."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        lm = runner.missions.get(mission_id)
        if lm is not None and runner.caught_up(mission_id):
            with lm.lock:
                tr = lm.tracker
                t_data = max(b.t_last for b in tr.buffers.values())
                if tr.t0 is not None and tr.horizon_s > t_data:
                    return tr
        time.sleep(0.2)
    raise TimeoutError(f"mission {mission_id}: estimator not done in {timeout_s} s")


def live_vs_offline(url: str, commander_token: str, runner: MissionRunner, settings: Settings,
                    *, seed: int, options: dict[str, Any], params: dict[str, Any],
                    timeout_s: float = 900.0) -> dict[str, Any]:
    """Stream one seed, wait, compare (see the module doc)."""
    from hrtls.service.db import make_engine, session_factory

    mission, members = network_team("inderst_hybrid_mission", seed=seed, options=options)
    t = time.perf_counter()
    with AgentClient(url, commander_token) as commander:
        mid, agents = create_network_mission(commander, "inderst_hybrid_mission", mission,
                                             members, params=params)
        clients = stream_network(url, commander, mid, agents, speed=math.inf,
                                 network=mission.network_ranges)
        commander.request("PATCH", f"/missions/{mid}", json={"status": "closed"})
    for c in clients:
        c.close()
    tr = wait_done(runner, mid, timeout_s)
    seconds = time.perf_counter() - t
    live = tr.result()
    engine = make_engine(settings.db_url)
    try:
        offline = offline_tracker(session_factory(engine), mid).run()
    finally:
        engine.dispose()
    late = runner.missions[mid].late_samples
    sim_tracker = MissionTracker(
        {k: m.session for k, m in zip(tr.names, members, strict=True)},
        config=preset(RESCUER_PRESET),
        kinds={k: m.kind for k, m in zip(tr.names, members, strict=True)})
    sim_tracker.feed_network(mission.network_ranges)
    sim = sim_tracker.run()
    shift = tr.t0 - min(m.session.time_span()[0] for m in members) if tr.t0 is not None else 0.0
    vs_sim = result_diff(live, _renamed(sim, tr.names), shift_s=shift)
    return {"seed": seed, "mission": mid, "late_samples": late, "stream_s": seconds,
            **result_diff(live, offline),
            "vs_simulated_sessions": {k: vs_sim.get(k) for k in ("same_localized", "node_m",
                                                                 "agent_m")}}


def _renamed(res: MissionResult, names: list[str]) -> MissionResult:
    """``res`` with its agents named as the service's (same order)."""
    agents = dict(zip(names, res.agents.values(), strict=True))
    return MissionResult(agents, res.nodes, res.node_history, res.contributors, res.readings,
                         res.closures)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--walk-s", type=float, default=300.0)
    ap.add_argument("--pg", default=None, help="PostgreSQL URL instead of SQLite files")
    ap.add_argument("--node-ranges", action="store_true",
                    help="the nodes range each other (POST .../network/ranges)")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the tests' server
    from tests.service.conftest import _reset_postgres, start_live

    print(f"load {Path('/proc/loadavg').read_text().split()[:3]}")
    for seed in (int(s) for s in args.seeds.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            db = args.pg or str(Path(tmp) / "service.db")
            if args.pg:
                _reset_postgres(args.pg)
            live = start_live(Settings(db=db, engine="processes" if seed == 2 else "local",
                                       process_shards=2))
            try:
                runner = live.server.config.app.state.services.missions
                out = live_vs_offline(
                    live.url, live.commander, runner, live.settings, seed=seed,
                    options={"walk_s": args.walk_s, "n_robots": 1 if seed == 1 else 0,
                             "node_ranges": args.node_ranges},
                    params={})
            finally:
                live.stop()
        print(out)


if __name__ == "__main__":
    main()
