"""The per-floor track plot: panels, shared fitted axes, start/end, labels apart."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hrtls.data import Checkpoints, GroundTruth, Trajectory
from hrtls.evaluate.floor_plots import plot_track_by_floor, spread_labels, track_figure


def _two_floor_track() -> tuple[Trajectory, GroundTruth, Checkpoints]:
    t = np.arange(0.0, 100.0, 0.5)
    x = np.where(t < 50.0, t * 0.5, 25.0 - (t - 50.0) * 0.5)
    y = np.where(t < 50.0, 0.0, 5.0)
    z = np.where(t < 50.0, 0.0, 3.0)
    xyz = np.column_stack([x, y, z])
    cps = Checkpoints(np.array([10.0, 20.0, 20.5, 80.0]), xyz[[20, 40, 41, 160]] + 0.3,
                      np.array(["A", "B", "C", "D"]))
    return Trajectory.build(t=t, xyz=xyz), GroundTruth(t, xyz), cps


def test_one_panel_per_floor_with_the_same_fitted_axes(tmp_path: Path) -> None:
    est, truth, cps = _two_floor_track()
    fig = track_figure(est, truth, floor_height_m=3.0, checkpoints=cps, title="t")
    assert [ax.get_title() for ax in fig.axes] == ["t: floor 1", "t: floor 0"]
    limits = {(ax.get_xlim(), ax.get_ylim()) for ax in fig.axes}
    assert len(limits) == 1
    (x0, x1), (y0, y1) = limits.pop()
    assert x0 < est.xyz[:, 0].min() and x1 > est.xyz[:, 0].max()
    assert y0 < est.xyz[:, 1].min() and y1 > est.xyz[:, 1].max()
    legends = [[t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes]
    assert "end" in legends[0] and "start" not in legends[0]
    assert "start" in legends[1] and "checkpoints (error drawn)" in legends[1]
    texts = [t.get_text() for t in fig.axes[1].texts]
    assert texts == ["A 0.4 m", "B 0.4 m", "C 0.4 m"]
    png = plot_track_by_floor(tmp_path / "track.png", est, truth, floor_height_m=3.0,
                              checkpoints=cps)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_single_floor_is_a_single_panel() -> None:
    est, _, _ = _two_floor_track()
    flat = Trajectory.build(t=est.t, xyz=est.xyz * [1.0, 1.0, 0.0])
    fig = track_figure(flat, None, floor_height_m=3.0, title="flat")
    assert [ax.get_title() for ax in fig.axes] == ["flat"]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=12))
def test_labels_are_spread_apart(points: list[tuple[float, float]]) -> None:
    labels = spread_labels(np.array(points), min_distance=0.5)
    assert labels.shape == (len(points), 2)
    d = np.hypot(*(labels[:, None, :] - labels[None, :, :]).transpose(2, 0, 1))
    d[np.diag_indices(len(points))] = np.inf
    # up to 12 labels always fit on the rings around a point
    assert d.min() >= 0.5 - 1e-9
