"""The live (chunked) run equals the offline run; outputs are sane."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Session
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.chunks import split_session
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult


def track_in_parts(cfg: TrackerConfig, session: Session, *, chunk_s: float,
                   restore_after: int | None = None) -> TrackResult:
    """``session`` fed in ``chunk_s`` parts; after part ``restore_after`` (if given) the tracker
    goes on from its snapshot."""
    tr = Tracker(cfg)
    tr.start_session(session)
    for i, part in enumerate(split_session(session, chunk_s)):
        if i == restore_after:
            tr = Tracker.restore(tr.snapshot())
        tr.update(part)
    return tr.finish()


def chunked_run(name: str, sim: SimulationResult, chunk_s: float) -> TrackResult:
    return track_in_parts(preset(name), sim.session, chunk_s=chunk_s)


def assert_same(offline: TrackResult, live: TrackResult) -> None:
    a, b = offline.trajectory, live.trajectory
    assert len(a) == len(b)
    np.testing.assert_allclose(a.t, b.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(a.xyz, b.xyz, atol=1e-9, rtol=0)
    np.testing.assert_allclose(a.cov_xy, b.cov_xy, atol=1e-9, rtol=0)
    assert offline.report["corrections"] == live.report["corrections"]


def test_chunked_equals_offline_without_imu(office: SimulationResult) -> None:
    """Infrastructure only: no upstream stage, the event loop alone decides (exact)."""
    sim = SimulationResult(**{**{f: getattr(office, f) for f in office.__dataclass_fields__},
                              "session": office.session.with_parts(imu=None, orientation=None,
                                                                   pressure=None)})
    offline = Tracker(preset("default")).run(sim.session)
    s = sim.session
    tr = Tracker(preset("default"))
    tr.start(s.meta, s.landmarks, has_imu=False, has_gyro=False, has_mag=False,
             has_orientation=False, rate_hz=0.0, t0=s.time_span()[0])
    for part in split_session(s, 5.0):
        tr.update(part)
    assert_same(offline, tr.finish())


@pytest.mark.parametrize("name", ["default", "colombo2014", "inderst-range", "basso2017"])
def test_chunked_equals_offline(office: SimulationResult, name: str) -> None:
    offline = Tracker(preset(name)).run(office.session)
    live = chunked_run(name, office, 5.0)
    sa, sb = offline.steps, live.steps
    same_steps = len(sa) == len(sb) and bool(
        np.allclose(sa.t_end, sb.t_end, atol=1e-9)
        and np.allclose(np.cos(sa.heading_rad), np.cos(sb.heading_rad), atol=1e-9, equal_nan=True)
        and np.allclose(sa.length_m, sb.length_m, atol=1e-9))
    assert same_steps, "the gait/attitude stages give other steps in 5 s chunks than offline"
    assert_same(offline, live)


@pytest.mark.parametrize("name", ["default", "colombo2014", "tarrio2011", "inderst-rfid"])
def test_covariances_symmetric_psd(office: SimulationResult, name: str) -> None:
    res = Tracker(preset(name)).run(office.session)
    tr = res.trajectory
    assert np.all(np.isfinite(tr.xyz)) and np.all(np.isfinite(tr.cov_xy))
    np.testing.assert_allclose(tr.cov_xy, np.transpose(tr.cov_xy, (0, 2, 1)), atol=1e-12)
    eig = np.linalg.eigvalsh(tr.cov_xy)
    assert eig.min() > -1e-9
    assert np.all(tr.var_heading >= 0)
    assert np.all(np.diff(tr.t) > 0)
