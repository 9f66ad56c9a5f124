"""CPU of the service's two trackings of a networked mission's rescuers, side by side.

The service tracks each agent in its host (``hrtls.service.host``: the published agent
estimates) and, for a mission with a sensor network, again inside the mission estimator
(``hrtls.service.mission_runner``: the node estimates). This times, in one process and
interleaved rounds, the per-agent causal trackers of the rescuers (the host's work) and
:meth:`MissionTracker.run` (the estimator's work: the same agents' trackers, cooperating, plus
the nodes). Process CPU seconds, best of ``--rounds``; robots are left out of the per-agent
side (the host tracks rescuers only through ``Tracker``). The host's trackers are fed
in batches of ``--host-chunk-s``.

    python benchmarks/mission_double_cost.py MISSION_FOLDER [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import time

from hrtls.data import Session
from hrtls.io.mission import read_mission
from hrtls.jobs.mission import estimator_sessions
from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline import Tracker, TrackerConfig
from hrtls.pipeline.chunks import split_session


def _host(session: Session, config: TrackerConfig, chunk_s: float) -> None:
    """One agent as the host tracks it: causal updates, one a batch of ``chunk_s``."""
    tr = Tracker(config)
    tr.start_session(session)
    for chunk in split_session(session, chunk_s):
        tr.update(chunk)
    tr.finish()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mission")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--host-chunk-s", type=float, default=MissionParams().chunk_s,
                    help="batch length the host's trackers are fed, s (default: the "
                         "estimator's window)")
    a = ap.parse_args()
    folder = read_mission(a.mission)
    sessions = estimator_sessions(folder)
    kinds = {name: ag.kind for name, ag in folder.agents.items()}
    config = TrackerConfig()
    per_agent, mission = [], []
    for _ in range(a.rounds):
        t = time.process_time()
        for name, s in sessions.items():
            if kinds[name] == "rescuer":
                _host(s, config, a.host_chunk_s)
        per_agent.append(time.process_time() - t)
        t = time.process_time()
        MissionTracker(sessions, config=config, kinds=kinds,
                       landmark_updates=folder.landmark_updates).run()
        mission.append(time.process_time() - t)
    print(f"load average (1/5/15 min): {os.getloadavg()}")
    print(f"agents: {kinds}; host batches of {a.host_chunk_s} s")
    print(f"per-agent trackers (host): best {min(per_agent):.2f} s CPU, all {per_agent}")
    print(f"mission estimator:         best {min(mission):.2f} s CPU, all {mission}")
    print(f"host share of the total:   {min(per_agent) / (min(per_agent) + min(mission)):.0%}")


if __name__ == "__main__":
    main()
