"""Snapshot / restore: a tracker continued in a new process gives the uninterrupted result."""

from __future__ import annotations

import multiprocessing
import warnings
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from hrtls.errors import FormatError
from hrtls.pipeline import PRESETS, Tracker, preset
from hrtls.pipeline.snapshot import MAGIC

from ._snapshot_worker import chunks, continue_from, office_session, rows


@pytest.fixture(scope="module")
def pool() -> Iterator[ProcessPoolExecutor]:
    with ProcessPoolExecutor(max_workers=1,
                             mp_context=multiprocessing.get_context("spawn")) as ex:
        yield ex


def _dedupe(t: np.ndarray) -> np.ndarray:
    keep = np.ones(len(t), dtype=bool)
    keep[:-1] = t[1:] > t[:-1]
    return keep


@pytest.mark.slow
@pytest.mark.parametrize("name", PRESETS)
@settings(max_examples=3, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate],
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(sizes=st.lists(st.floats(0.3, 25.0), min_size=1, max_size=12),
       cut=st.floats(0.0, 1.0))
def test_restored_in_a_new_process_continues_exactly(pool: ProcessPoolExecutor, name: str,
                                                     sizes: list[float], cut: float) -> None:
    warnings.simplefilter("ignore")
    s = office_session()
    t0, t1 = s.time_span()
    edges = [t0]
    while edges[-1] <= t1:
        edges.append(edges[-1] + sizes[(len(edges) - 1) % len(sizes)])
    parts = chunks(s, edges)
    k = int(cut * len(parts))
    whole = Tracker(preset(name))
    whole.start_session(s)
    for part in parts:
        whole.update(part)
    ref = whole.finish()
    first = Tracker(preset(name))
    first.start_session(s)
    for part in parts[:k]:
        first.update(part)
    before = rows(first)
    data = first.snapshot()
    assert data.startswith(MAGIC)
    out = pool.submit(continue_from, data, edges, k).result()
    # rows read before the snapshot + rows after the restore = the uninterrupted trajectory
    t = np.concatenate([before["t"], out["live"]["t"]])
    xyz = np.concatenate([before["xyz"], out["live"]["xyz"]])
    keep = _dedupe(t)
    tr = ref.trajectory
    assert keep.sum() == len(tr)
    np.testing.assert_allclose(t[keep], tr.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(xyz[keep], tr.xyz, atol=1e-9, rtol=0)
    cov = np.concatenate([before["cov"], out["live"]["cov"]])
    np.testing.assert_allclose(cov[keep], tr.cov_xy, atol=1e-9, rtol=0)
    # finish() of the restored tracker: the rows since the restore
    n_after = len(out["t"])
    np.testing.assert_allclose(out["xyz"], tr.xyz[len(tr) - n_after:], atol=1e-9, rtol=0)
    assert out["corrections"] == ref.report["corrections"]
    assert out["yaw_pseudo"] == ref.report["yaw_pseudo_measurements"]
    assert out["scale"] == ref.report["step_length_scale"]


def test_estimates_since_reads_the_rows_so_far() -> None:
    warnings.simplefilter("ignore")
    s = office_session()
    t0, t1 = s.time_span()
    tr = Tracker(preset("default"))
    tr.start_session(s)
    parts = chunks(s, list(np.arange(t0, t1 + 10.0, 10.0)))
    seen = []
    last = -np.inf
    for part in parts:
        tr.update(part)
        e = tr.estimates_since(last)
        if len(e):
            assert np.all(e.t > last)
            seen.append(e)
            last = float(e.t[-2]) if len(e) > 1 else last  # the last row may still change
    res = tr.finish()
    e = tr.estimates_since()
    np.testing.assert_array_equal(e.t, res.trajectory.t)
    np.testing.assert_array_equal(e.xyz, res.trajectory.xyz)
    assert np.all(e.since_correction_s >= 0)
    assert np.isinf(e.since_correction_s[0]) and np.any(np.isfinite(e.since_correction_s))
    assert np.all(e.floor == np.rint(e.xyz[:, 2] / s.meta.floor_height_m))


def test_restore_refuses_foreign_bytes() -> None:
    with pytest.raises(FormatError, match="header"):
        Tracker.restore(b"not a snapshot")
    good = Tracker(preset("default"))
    good.start_session(office_session())
    data = good.snapshot()
    with pytest.raises(FormatError, match="version"):
        Tracker.restore(MAGIC + bytes([99]) + data[len(MAGIC) + 1:])
    with pytest.raises(FormatError, match="corrupt"):
        Tracker.restore(data[:len(MAGIC) + 1] + b"garbage")
