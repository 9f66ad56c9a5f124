"""Landmarks updated during a mission hold from their time on (hrtls.pipeline.landmark_updates).

The oracles are sessions without updates: a tag destroyed at ``u`` tracks like the session
whose reads of that tag after ``u`` are removed; a tag moved at ``u`` tracks like the session
whose later reads name a new tag at the new position.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.data import Landmark, Session, TagDetections
from hrtls.errors import InputError
from hrtls.pipeline import Tracker, preset
from hrtls.pipeline.chunks import split_session
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import run_scenario

U_S = 100.0
"""Update time: between the reads of T5 at 43 s and at 179-180 s (seed 3, 150 m ring)."""


@pytest.fixture(scope="module")
def ring() -> Session:
    s = run_scenario("inderst_ring", 3, distance_m=150.0).session
    tags = s.tags
    assert tags is not None
    t5 = tags.t[tags.tag == "T5"]
    assert (t5 < U_S).any() and (t5 > U_S + 10.0).any()
    return s.with_parts(truth=None, checkpoints=None)


def _run(s: Session, versions: list[Landmark], *, chunk_s: float | None = None,
         restore_at_s: float | None = None) -> TrackResult:
    tr = Tracker(preset("default"))
    tr.start_session(s)
    tr.update_landmarks(versions)
    parts = [s] if chunk_s is None else list(split_session(s, chunk_s))
    for part in parts:
        tr.update(part)
        if restore_at_s is not None and part.time_span()[1] >= restore_at_s:
            tr = Tracker.restore(tr.snapshot())
            restore_at_s = None
    return tr.finish()


def _plain(s: Session) -> TrackResult:
    tr = Tracker(preset("default"))
    return tr.run(s)


def _assert_same(a: TrackResult, b: TrackResult, *, drop: np.ndarray | None = None) -> None:
    """Same rows (``drop``: rows of ``a`` left out of the comparison)."""
    ta, tb = a.trajectory, b.trajectory
    keep = np.ones(len(ta), dtype=bool) if drop is None else ~drop
    assert int(keep.sum()) == len(tb)
    np.testing.assert_allclose(ta.t[keep], tb.t, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.xyz[keep], tb.xyz, atol=1e-9, rtol=0)
    np.testing.assert_allclose(ta.cov_xy[keep], tb.cov_xy, atol=1e-9, rtol=0)


def _tags_renamed_after(s: Session, tag: str, new: str, t_from: float) -> TagDetections:
    g = s.tags
    assert g is not None
    ids = np.where((g.tag == tag) & (g.t >= t_from), new, g.tag)
    return TagDetections(g.t, ids)


def test_a_destroyed_tag_tracks_like_its_later_reads_removed(ring: Session) -> None:
    gone = ring.landmarks["T5"].model_copy(update={"updated": U_S, "status": "destroyed"})
    got = _run(ring, [gone])
    g = ring.tags
    assert g is not None
    keep = ~((g.tag == "T5") & (g.t >= U_S))
    oracle = _plain(ring.with_parts(tags=TagDetections(g.t[keep], g.tag[keep])))
    skips = [d for d in got.diagnostics if d.source == "T5" and d.t >= U_S]
    assert skips and all(d.reason == "landmark destroyed" for d in skips)
    # each skipped tag group still leaves its output row, the state unchanged
    tr = got.trajectory
    extra = np.isin(tr.t, [d.t for d in skips])
    assert extra.sum() == len(skips)
    prev = np.flatnonzero(extra) - 1
    np.testing.assert_array_equal(tr.xyz[extra], tr.xyz[prev])
    _assert_same(got, oracle, drop=extra)
    # and it did change the track: the reads after U_S corrected the plain run
    assert not np.allclose(_plain(ring).trajectory.xyz[-1], got.trajectory.xyz[-1])


def test_a_moved_tag_corrects_with_its_new_position_from_its_time_on(ring: Session) -> None:
    old = ring.landmarks["T5"]
    assert old.position is not None
    moved_xyz = (old.position[0] + 1.5, old.position[1] - 1.0, old.position[2])
    moved = old.model_copy(update={"updated": U_S, "position": moved_xyz,
                                   "hazard": "smoke reported"})
    got = _run(ring, [moved])
    renamed = ring.with_parts(
        tags=_tags_renamed_after(ring, "T5", "T5b", U_S),
        landmarks={**ring.landmarks,
                   "T5b": old.model_copy(update={"id": "T5b", "position": moved_xyz})})
    _assert_same(got, _plain(renamed))
    notes = " ".join(str(n) for n in got.report["notes"])
    assert "landmark 'T5' updated at 100.00 s (moved 1.80 m); hazard nearby: smoke reported" \
        in notes


def test_chunks_and_a_restore_across_the_update_give_the_offline_track(ring: Session) -> None:
    moved = ring.landmarks["T5"].model_copy(update={"updated": U_S,
                                                    "position": (41.0, 19.0, 2.2)})
    offline = _run(ring, [moved])
    _assert_same(offline, _run(ring, [moved], chunk_s=7.0))
    tr = offline.trajectory
    for chunk_s, restore_s in ((13.0, U_S - 20.0), (3.0, U_S + 5.0)):
        # a restored tracker reports the rows since its restore: the tail of the offline track
        got = _run(ring, [moved], chunk_s=chunk_s, restore_at_s=restore_s).trajectory
        assert 0 < len(got) < len(tr)
        np.testing.assert_allclose(got.xyz, tr.xyz[len(tr) - len(got):], atol=1e-9, rtol=0)
        np.testing.assert_allclose(got.cov_xy, tr.cov_xy[len(tr) - len(got):], atol=1e-9,
                                   rtol=0)


def test_updates_need_a_time_not_in_the_past(ring: Session) -> None:
    tr = Tracker(preset("default"))
    with pytest.raises(InputError, match="start"):
        tr.update_landmarks([ring.landmarks["T5"]])
    tr.start_session(ring)
    with pytest.raises(InputError, match="updated"):
        tr.update_landmarks([ring.landmarks["T5"]])   # no time
    first = next(split_session(ring, 30.0))
    tr.update(first)
    late = ring.landmarks["T5"].model_copy(update={"updated": 10.0})
    with pytest.raises(InputError, match="not before the data already tracked"):
        tr.update_landmarks([late])
    nan = ring.landmarks["T5"].model_copy(update={"updated": math.nan})
    with pytest.raises(InputError, match="updated"):
        tr.update_landmarks([nan])


def test_landmark_rejects_an_unknown_status() -> None:
    with pytest.raises(ValueError, match="status"):
        Landmark.model_validate({"id": "x", "position": [0, 0, 0], "status": "lost"})


def test_a_landmark_destroyed_from_the_start_corrects_nothing(ring: Session) -> None:
    g = ring.tags
    assert g is not None
    gone = ring.landmarks["T5"].model_copy(update={"status": "destroyed"})
    got = _plain(ring.with_parts(landmarks={**ring.landmarks, "T5": gone}))
    no_t5 = _plain(ring.with_parts(landmarks={k: v for k, v in ring.landmarks.items()
                                              if k != "T5"}))
    _assert_same(got, no_t5)


def test_a_cut_for_an_update_changes_nothing_else(ring: Session) -> None:
    """A new landmark nothing reads, added mid-chunk, leaves the track as it was, also with a
    magnetometer on its own (slower, offset) clock: the cut pieces are aligned first."""
    from hrtls.data import ImuStream, SensorSeries

    imu = ring.imu
    assert imu is not None and imu.mag is not None
    t_mag = imu.mag.t[::2] + 0.003
    mag = SensorSeries(t_mag, np.array([np.interp(t_mag, imu.mag.t, imu.mag.values[:, k])
                                        for k in range(3)]).T, "magnetometer")
    s = ring.with_parts(imu=ImuStream(imu.accel, imu.gyro, mag, check_units=False))
    new = Landmark(id="Z", kind="rfid", position=(0.0, 0.0, 0.0), updated=U_S + 0.0037)
    _assert_same(_run(s, [new]), _plain(s))
