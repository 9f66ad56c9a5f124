"""The mission rescuers' own covariance without cooperation (issue 18): seeded regression."""

from __future__ import annotations

import numpy as np

from hrtls.mission.tracker import MissionParams, MissionTracker
from hrtls.pipeline import preset
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission


def test_rescuers_nees_without_cooperation_on_a_dev_seed() -> None:
    """Dev seed 1 (door tags, one robot, 2 % ranges), cooperation off, the ``rescue-mission``
    preset; the rescuers' NEES (2 dof) and error at 1 Hz over their walks against the truth,
    overall and 15-60 s after their latest tag read. Measured: NEES 1.86, 15-60 s after a
    read 2.08, p90 error 2.72 m; with the magnetic offset's error counted anew by every update
    (``offset_model = "independent"``, heading increment 0.02 rad) NEES 2.74, 15-60 s 3.45, p90
    3.32 m; with the earlier ``q_along = 0.04`` too NEES 5.01 and p90 3.97 m."""
    mission = inderst_hybrid_mission(1, MissionOptions(range_sigma_fraction=0.02))
    res = MissionTracker(mission.agents, params=MissionParams(cooperate=False),
                         kinds=mission.kinds, config=preset("rescue-mission")).run()
    errs, nees, late = [], [], []
    for name, agent in res.agents.items():
        if mission.kinds[name] != "rescuer":
            continue
        session = mission.simulations[name].session
        truth, tags = session.truth, session.tags
        assert truth is not None and tags is not None
        tr = agent.trajectory
        tq = np.arange(float(tr.t[0]), float(tr.t[-1]), 1.0)
        d = np.column_stack([np.interp(tq, tr.t, tr.xyz[:, k])
                             - np.interp(tq, truth.t, truth.xyz[:, k]) for k in (0, 1)])
        j = np.clip(np.searchsorted(tr.t, tq), 0, len(tr.t) - 1)
        errs.append(np.hypot(d[:, 0], d[:, 1]))
        nees.append(np.einsum("ki,kij,kj->k", d, np.linalg.inv(tr.cov_xy[j]), d))
        k = np.searchsorted(tags.t, tq, side="right")
        since = np.where(k > 0, tq - tags.t[np.maximum(k - 1, 0)], np.inf)
        late.append(nees[-1][(since >= 15.0) & (since < 60.0)])
    assert len(nees) == 3
    assert 1.0 <= float(np.mean(np.concatenate(nees))) <= 2.3
    assert len(np.concatenate(late)) > 100
    assert float(np.mean(np.concatenate(late))) <= 2.6
    assert float(np.percentile(np.concatenate(errs), 90)) <= 3.0
