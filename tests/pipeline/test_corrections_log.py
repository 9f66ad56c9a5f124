"""The tracker's record of its corrections (hrtls.pipeline.corrections)."""

from __future__ import annotations

import numpy as np
import pytest

from hrtls.data import Landmark, Session
from hrtls.pipeline import Tracker
from hrtls.pipeline.chunks import split_session
from hrtls.pipeline.corrections import Corrections
from hrtls.pipeline.schedule import RANGE, TAGS
from hrtls.sim.mission import MissionOptions, inderst_hybrid_mission


@pytest.fixture(scope="module")
def rescuer() -> Session:
    """A rescuer of a short hybrid mission with the nodes as known landmarks (ranges apply)."""
    m = inderst_hybrid_mission(1, MissionOptions(walk_s=90.0, n_nodes=12))
    s = m.agents["R1"]
    nodes = {n: Landmark(id=n, kind="node", position=(float(p[0]), float(p[1]), 0.0))
             for n, p in m.node_truth_m.items()}
    return s.with_parts(truth=None, checkpoints=None, landmarks={**s.landmarks, **nodes})


def _all(parts: list[Corrections]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([getattr(c, k) for c in parts])
            for k in ("t", "kind", "source", "mean0_m", "cov0_m2", "mean1_m", "cov1_m2")}


def test_corrections_are_the_jumps_of_the_rows_and_survive_a_restore(rescuer: Session) -> None:
    tr = Tracker()
    res = tr.run(rescuer)
    c = tr.corrections_since(0)
    assert c.next_index == len(c)
    kinds = set(c.kind.tolist())
    assert TAGS in kinds and RANGE in kinds              # the Python path and the compiled loop
    # each moved the position; the row at its time holds the corrected state when no later
    # event shares that time
    assert np.all(np.any(c.mean1_m != c.mean0_m, axis=1))
    traj = res.trajectory
    k = np.searchsorted(traj.t, c.t)
    assert np.all(traj.t[k] == c.t)
    last = np.append(c.t[1:] != c.t[:-1], True)
    same = np.all(traj.xyz[k, :2] == c.mean1_m, axis=1)
    assert same[last].mean() > 0.9
    np.testing.assert_allclose(traj.cov_xy[k][same], c.cov1_m2[same])
    # a range update shrinks the covariance by rank one
    r = c.kind == RANGE
    lam = np.linalg.inv(c.cov1_m2[r]) - np.linalg.inv(c.cov0_m2[r])
    assert np.all(np.abs(np.linalg.det(lam)) < 1e-6 * np.einsum("nii->n", lam) ** 2)
    # chunked with a restore half-way: the same records, none twice
    tr2 = Tracker()
    tr2.start_session(rescuer)
    got: list[Corrections] = []
    nxt = 0
    parts = list(split_session(rescuer, 5.0))
    for j, part in enumerate(parts):
        tr2.update(part)
        got.append(tr2.corrections_since(nxt))
        nxt = got[-1].next_index
        if j == len(parts) // 2:
            tr2 = Tracker.restore(tr2.snapshot())
    tr2.finish()
    got.append(tr2.corrections_since(nxt))
    a, b = _all([c]), _all(got)
    for key in ("kind", "source"):
        np.testing.assert_array_equal(a[key], b[key])
    for key in ("t", "mean0_m", "cov0_m2", "mean1_m", "cov1_m2"):   # chunked: equal to 1e-9
        np.testing.assert_allclose(a[key], b[key], rtol=0, atol=1e-9)
