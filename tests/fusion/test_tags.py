from __future__ import annotations

import math

import numpy as np
import pytest

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import TagDetections
from hrtls.fusion.gating import is_spd
from hrtls.fusion.state import FilterState
from hrtls.fusion.tags import (
    TagCorrector,
    TagParams,
    bearing_heading_correction,
    group_detections,
    lobe_centre,
)


def tag(tid: str, x: float, y: float, orient: float | None = None, acc: float | None = 2.0,
        bearings: tuple[float, ...] = ()) -> Landmark:
    return Landmark(id=tid, kind="rfid", position=(x, y, 2.2), lobe_orientation_rad=orient,
                    accuracy_m=acc, bearings_rad=bearings)


def state_at(x: float, y: float, sigma: float = 3.0) -> FilterState:
    p = np.diag([sigma**2, sigma**2, 0.01, 0.04])
    p[0, 3] = p[3, 0] = 0.3 * sigma * 0.2
    return FilterState(5.0, np.array([x, y, 0.0, 0.0]), p)


def test_lobe_centre() -> None:
    np.testing.assert_allclose(lobe_centre(tag("a", 1.0, 2.0, math.pi / 2), 1.4), [1.0, 3.4])
    np.testing.assert_allclose(lobe_centre(tag("a", 1.0, 2.0), 1.4), [1.0, 2.0])


def test_strategy_1_reset_outside() -> None:
    s = state_at(10.0, 0.0)
    up = TagCorrector().update(s, t=5.0, tags=[tag("a", 0.0, 0.0, 0.0)])
    assert up.strategy == 1
    np.testing.assert_allclose(up.state.x[:2], [1.4, 0.0])          # eq. 4.26: p = T
    np.testing.assert_allclose(up.state.P[:2, :2], np.eye(2) * 1.0)  # (0.5 * 2 m)^2
    assert up.state.P[0, 3] == 0.0
    assert up.correction_m == pytest.approx(8.6)
    assert up.diagnostics[0].accepted and up.diagnostics[0].reason == "strategy 1"


def test_strategy_2_inside_bounds_covariance() -> None:
    s = state_at(1.0, 0.5)
    up = TagCorrector().update(s, t=5.0, tags=[tag("a", 0.0, 0.0, 0.0)])
    assert up.strategy == 2
    np.testing.assert_allclose(up.state.x, s.x)                      # eq. 4.27: kept
    np.testing.assert_allclose(up.state.P[:2, :2], np.eye(2))         # bounded to R_i
    small = state_at(1.0, 0.5, sigma=0.3)
    up2 = TagCorrector().update(small, t=5.0, tags=[tag("a", 0.0, 0.0, 0.0)])
    np.testing.assert_allclose(up2.state.P, small.P)                  # already better


def test_strategy_3_multi_outside() -> None:
    s = state_at(20.0, 20.0)
    tags = [tag("a", 0.0, 0.0), tag("b", 2.0, 0.0)]
    up = TagCorrector().update(s, t=5.0, tags=tags)
    assert up.strategy == 3
    np.testing.assert_allclose(up.state.x[:2], [1.0, 0.0])            # eq. 4.28: T_bar
    p = up.state.P[:2, :2]
    # spread of the centres along x (1 m^2) plus the fused lobes (1/2 m^2 per axis)
    np.testing.assert_allclose(p, np.diag([1.5, 0.5]))
    assert is_spd(up.state.P)


def test_strategy_4_moves_toward_centre_and_shrinks() -> None:
    s = state_at(0.5, 1.0)
    tags = [tag("a", 0.0, 0.0), tag("b", 2.0, 0.0)]
    up = TagCorrector().update(s, t=5.0, tags=tags)
    assert up.strategy == 4
    t_bar = np.array([1.0, 0.0])
    before = np.linalg.norm(s.x[:2] - t_bar)
    after = np.linalg.norm(up.state.x[:2] - t_bar)
    assert after < before
    # moved along delta = T_bar - p by the fraction 1 / (1 + delta^T C^-1 delta)
    c = np.diag([1.5, 0.5])
    delta = t_bar - s.x[:2]
    frac = 1.0 / (1.0 + delta @ np.linalg.solve(c, delta))
    np.testing.assert_allclose(up.state.x[:2], s.x[:2] + frac * delta)
    assert np.trace(up.state.P[:2, :2]) < np.trace(s.P[:2, :2])
    assert is_spd(up.state.P)


def test_kalman_strategy_and_rejection() -> None:
    s = state_at(3.0, 0.0)
    up = TagCorrector(TagParams(strategy="kalman")).update(s, t=5.0, tags=[tag("a", 0.0, 0.0)])
    assert up.strategy == 0 and up.diagnostics[0].accepted
    assert 0.0 < up.state.x[0] < 3.0
    assert up.state.heading != 0.0                                      # via the cross term
    far = TagCorrector(TagParams(max_correction_m=20.0)).update(state_at(100.0, 0.0), t=5.0,
                                                                tags=[tag("a", 0.0, 0.0)])
    assert far.diagnostics[0].status == "rejected"


def test_group_detections() -> None:
    det = TagDetections(np.array([0.0, 0.1, 0.2, 3.0]), np.array(["a", "b", "a", "c"]))
    groups = group_detections(det, 0.5)
    assert groups == [(0.2, ["a", "b"]), (3.0, ["c"])]


def test_bearing_correction_eq_4_21_4_22() -> None:
    s = state_at(0.0, 0.0).evolve(x=np.array([0.0, 0.0, 0.0, 0.3]))
    bearings = (0.0, math.pi)
    hc = bearing_heading_correction(s, bearings, deadband_rad=0.05, gate_rad=0.5)
    assert hc.diagnostics.accepted
    assert hc.state.heading == pytest.approx(0.0)                       # nearest bearing
    assert hc.correction_rad == pytest.approx(-0.3)
    assert hc.state.P[0, 3] == 0.0
    near = s.evolve(x=np.array([0.0, 0.0, 0.0, math.pi - 0.02]))
    assert bearing_heading_correction(near, bearings).diagnostics.status == "skipped"
    turning = s.evolve(x=np.array([0.0, 0.0, 0.0, 1.2]))
    assert bearing_heading_correction(turning, bearings).diagnostics.status == "rejected"
    k = bearing_heading_correction(s, bearings, mode="kalman", sigma_rad=0.2)
    assert k.diagnostics.accepted and 0.0 < k.state.heading < 0.3
    wrap = s.evolve(x=np.array([0.0, 0.0, 0.0, -3.0]))
    w = bearing_heading_correction(wrap, bearings)
    assert w.state.heading == pytest.approx(math.pi)
    assert w.correction_rad == pytest.approx(math.pi + 3.0 - 2 * math.pi)


def test_repeated_reads_are_skipped_and_memory_roundtrips() -> None:
    import json

    from hrtls.fusion.tags import TagMemory

    corr = TagCorrector(TagParams(repeat_interval_s=2.0))
    a = tag("a", 0.0, 0.0)
    up = corr.update(state_at(10.0, 0.0), t=5.0, tags=[a])
    assert up.strategy == 1 and up.memory.last_used == {"a": 5.0}
    moved = up.state.evolve(x=np.array([1.5, 0.0, 0.0, 0.0]), t=6.0)
    again = corr.update(moved, t=6.0, tags=[a], memory=up.memory)
    assert again.diagnostics[0].status == "skipped" and again.strategy == -1
    np.testing.assert_array_equal(again.state.x, moved.x)
    mem = TagMemory.from_dict(json.loads(json.dumps(again.memory.to_dict())))
    later = corr.update(moved.evolve(t=8.0), t=8.0, tags=[a], memory=mem)
    assert later.strategy == 2


def test_strategy_4_keeps_covariance_when_already_tighter() -> None:
    s = state_at(0.5, 1.0, sigma=0.2)
    up = TagCorrector().update(s, t=5.0, tags=[tag("a", 0.0, 0.0), tag("b", 2.0, 0.0)])
    assert up.strategy == 4
    np.testing.assert_allclose(up.state.P[:2, :2], s.P[:2, :2])      # eq. 4.30 first branch


def test_update_ids_skips_unknown() -> None:
    lms = {"a": tag("a", 0.0, 0.0)}
    up = TagCorrector().update_ids(state_at(10.0, 0.0), t=5.0, ids=["zz", "a"], landmarks=lms)
    assert [d.status for d in up.diagnostics] == ["skipped", "accepted"]
    assert up.strategy == 1
    none = TagCorrector().update_ids(state_at(10.0, 0.0), t=5.0, ids=["zz"], landmarks=lms)
    assert none.strategy == -1 and none.diagnostics[0].source == "zz"
