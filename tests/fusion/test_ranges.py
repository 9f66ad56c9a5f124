from __future__ import annotations

import itertools

import numpy as np
import pytest

from hrtls.data.landmarks import Landmark
from hrtls.data.observations import RangeMeasurements
from hrtls.fusion.gating import is_spd, summarize
from hrtls.fusion.ranges import RangeParams, range_update, ranges_at, update_ranges
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor

NODES = {f"n{i}": Landmark(id=f"n{i}", kind="node", position=p)
         for i, p in enumerate([(0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (20.0, 15.0, 0.0),
                                (0.0, 15.0, 0.0)])}


def test_single_range_update_hand_computed() -> None:
    s = FilterState(0.0, np.array([3.0, 0.0, 0.0, 0.0]), np.diag([1.0, 1.0, 0.01, 0.01]))
    up = range_update(s, [0.0, 0.0, 0.0], 4.0, 1.0)
    # H = [1, 0, 0, 0]; S = 2; K = 1/2 -> x = 3.5
    assert up.diagnostics.accepted
    assert up.state.x[0] == pytest.approx(3.5)
    assert up.state.P[0, 0] == pytest.approx(0.5)
    assert up.state.P[1, 1] == pytest.approx(1.0)
    on_top = range_update(s.evolve(x=np.zeros(4)), [0.0, 0.0, 0.0], 1.0, 0.1)
    assert on_top.diagnostics.status == "rejected"
    outlier = range_update(s, [0.0, 0.0, 0.0], 3.0 + 20 * np.sqrt(2.0), 1.0)
    assert outlier.diagnostics.status == "rejected"


def test_range_ekf_converges_on_walk_around_four_nodes() -> None:
    rng = np.random.default_rng(7)
    # rectangle walk 5..15 x 4..11 with step heading error; ranges after every step
    corners = np.array([[5.0, 4.0], [15.0, 4.0], [15.0, 11.0], [5.0, 11.0], [5.0, 4.0]])
    pts, heads = [], []
    for a, b in itertools.pairwise(corners):
        n = int(np.linalg.norm(b - a) / 0.7)
        for k in range(1, n + 1):
            pts.append(a + (b - a) * k / n)
            heads.append(np.arctan2(*(b - a)[::-1]))
    truth = np.array(pts * 3)
    heading = np.array(heads * 3)
    steps = np.linalg.norm(np.diff(np.vstack([corners[:1], truth]), axis=0), axis=1)
    pred = StepPredictor(StepPredictionParams(sigma_heading_rad=0.1))
    s = FilterState.initial(xyz=(7.0, 2.0, 0.0), sigma_xy_m=3.0)     # 2.8 m off
    s_dr = s
    rows_t, rows_n, rows_r = [], [], []
    diags = []
    for j in range(truth.shape[0]):
        h = heading[j] + 0.08 + rng.normal(0, 0.05)                  # biased heading
        length = steps[j] * (1 + rng.normal(0, 0.05))
        s = pred.predict(s, t=float(j + 1), length_m=length, heading_rad=h)
        s_dr = pred.predict(s_dr, t=float(j + 1), length_m=length, heading_rad=h)
        for nid, lm in NODES.items():
            z = np.linalg.norm(truth[j] - lm.xyz()[:2]) + rng.normal(0, 0.3)
            rows_t.append(float(j + 1))
            rows_n.append(nid)
            rows_r.append(max(z, 0.0))
        meas = RangeMeasurements(np.array(rows_t[-4:]), np.array(rows_n[-4:]),
                                 np.array(rows_r[-4:]), np.full(4, 0.3))
        s, d = update_ranges(s, meas, np.arange(4), NODES)
        diags += d
        assert is_spd(s.P)
    err = np.linalg.norm(s.x[:2] - truth[-1])
    err_dr = np.linalg.norm(s_dr.x[:2] - truth[-1])
    assert err < 0.5
    assert err_dr > 3 * err
    assert summarize(diags)["range"]["accepted"] >= 0.95 * len(diags)


def test_unknown_node_skipped_and_window() -> None:
    meas = RangeMeasurements(np.array([1.0, 2.0, 3.0]), np.array(["n0", "zz", "n1"]),
                             np.array([5.0, 5.0, 17.0]), np.full(3, np.nan))
    np.testing.assert_array_equal(ranges_at(meas, 1.0, 3.0), [1, 2])
    s = FilterState.initial(xyz=(3.0, 3.0, 0.0))
    s2, d = update_ranges(s, meas, [0, 1, 2], NODES, params=RangeParams(default_sigma_m=1.0))
    assert [x.status for x in d] == ["accepted", "skipped", "accepted"]
    assert is_spd(s2.P)


def test_slant_range_3d() -> None:
    s = FilterState(0.0, np.array([3.0, 0.0, 4.0, 0.0]), np.diag([1.0, 1.0, 1.0, 0.01]))
    up = range_update(s, [0.0, 0.0, 0.0], 5.0, 0.1, params=RangeParams(use_3d=True))
    assert up.diagnostics.innovation[0] == pytest.approx(0.0)
    flat = range_update(s, [0.0, 0.0, 0.0], 5.0, 0.1)
    assert flat.diagnostics.innovation[0] == pytest.approx(2.0)
