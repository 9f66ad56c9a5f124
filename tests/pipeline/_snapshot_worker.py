"""Runs in a fresh (spawned) process: restore a tracker from bytes and feed it the rest."""

from __future__ import annotations

import itertools
import warnings
from functools import cache
from typing import Any

import numpy as np

from hrtls.data import Session
from hrtls.pipeline import Tracker
from hrtls.pipeline.chunks import aligned_imu, session_window
from hrtls.sim.scenarios import run_scenario


@cache
def office_session() -> Session:
    """The session of the pipeline tests' ``office`` fixture, IMU aligned as a device sends."""
    s = run_scenario("office_random_walk", 3, duration_s=120.0).session
    return s.with_parts(imu=aligned_imu(s.imu)) if s.imu is not None else s


def chunks(session: Session, edges: list[float]) -> list[Session]:
    """The non-empty windows between consecutive ``edges``."""
    out = []
    for a, b in itertools.pairwise(edges):
        part = session_window(session, a, b)
        if part is not None:
            out.append(part)
    return out


def rows(tracker: Tracker, t_after: float = -np.inf) -> dict[str, Any]:
    e = tracker.estimates_since(t_after)
    return {"t": e.t, "xyz": e.xyz, "heading": e.heading_rad, "cov": e.cov_xy,
            "since": e.since_correction_s, "floor": e.floor}


def continue_from(data: bytes, edges: list[float], first: int) -> dict[str, Any]:
    """Restore, feed the chunks from index ``first``, finish; rows and report counters."""
    warnings.simplefilter("ignore")
    tracker = Tracker.restore(data)
    for part in chunks(office_session(), edges)[first:]:
        tracker.update(part)
    res = tracker.finish()
    live = rows(tracker)
    return {"live": live, "t": res.trajectory.t, "xyz": res.trajectory.xyz,
            "cov": res.trajectory.cov_xy, "heading": res.trajectory.heading_rad,
            "corrections": res.report["corrections"],
            "yaw_pseudo": res.report["yaw_pseudo_measurements"],
            "scale": res.report["step_length_scale"]}
