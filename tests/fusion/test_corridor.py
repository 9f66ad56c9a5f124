"""Seeded ring-corridor walk with RFID tags (the thesis' mission in small)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from hrtls.data.landmarks import Landmark
from hrtls.fusion.gating import is_spd
from hrtls.fusion.state import FilterState
from hrtls.fusion.step_prediction import StepPredictionParams, StepPredictor
from hrtls.fusion.tags import TagCorrector, TagParams, bearing_heading_correction

ALL_DIRS = (0.0, math.pi / 2, math.pi, -math.pi / 2)
CORNERS = [Landmark(id=f"c{i}", kind="rfid", position=(x, y, 2.2), accuracy_m=2.0,
                    bearings_rad=ALL_DIRS)
           for i, (x, y) in enumerate([(0, 0), (40, 0), (40, 20), (0, 20)])]
MIDDLE = [Landmark(id=f"m{i}", kind="rfid", position=(x, y, 2.2), accuracy_m=2.0,
                   bearings_rad=(0.0, math.pi) if y in (0, 20) else (math.pi / 2, -math.pi / 2))
          for i, (x, y) in enumerate([(20, 0), (40, 10), (20, 20), (0, 10)])]


def walk(seed: int, laps: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    corners = np.array([[0, 0], [40, 0], [40, 20], [0, 20], [0, 0]], float)
    pts, hd = [], []
    for _ in range(laps):
        for a, b in itertools.pairwise(corners):
            n = round(float(np.linalg.norm(b - a)) / 0.7)
            for k in range(1, n + 1):
                pts.append(a + (b - a) * k / n)
                hd.append(math.atan2(b[1] - a[1], b[0] - a[0]))
    truth = np.array(pts)
    length = np.linalg.norm(np.diff(np.vstack([[0.0, 0.0], truth]), axis=0), axis=1)
    heading = np.array(hd) + np.cumsum(rng.normal(0.002, 0.01, len(hd))) \
        + rng.normal(0, 0.03, len(hd))
    return truth, heading, length * (1 + rng.normal(0.03, 0.05, len(length)))


def track(truth: np.ndarray, heading: np.ndarray, length: np.ndarray, tags: list[Landmark],
          bearing: str | None, mode: str) -> np.ndarray:
    pred = StepPredictor(StepPredictionParams(heading_mode=mode))  # type: ignore[arg-type]
    corr = TagCorrector(TagParams(lobe_offset_m=0.0))
    s = FilterState.initial(sigma_xy_m=0.1, sigma_heading_rad=0.02)
    last: dict[str, int] = {}
    err = np.empty(len(truth))
    for j in range(len(truth)):
        s = pred.predict(s, t=float(j + 1), length_m=float(length[j]),
                         heading_rad=float(heading[j]))
        seen = [lm for lm in tags if np.linalg.norm(truth[j] - lm.xyz()[:2]) < 1.5
                and j - last.get(lm.id, -99) > 5]
        for lm in seen:
            last[lm.id] = j
        if seen:
            s = corr.update(s, t=float(j + 1), tags=seen).state
            if bearing is not None:
                s = bearing_heading_correction(s, seen[0].bearings_rad,
                                               mode=bearing).state  # type: ignore[arg-type]
        err[j] = np.linalg.norm(s.x[:2] - truth[j])
    assert is_spd(s.P)
    return err


def test_tags_and_bearings_bound_the_error() -> None:
    truth, heading, length = walk(0)
    dr = track(truth, heading, length, [], None, "input")
    tags = track(truth, heading, length, CORNERS + MIDDLE, None, "input")
    both = track(truth, heading, length, CORNERS + MIDDLE, "replace", "state")
    assert tags.mean() < 0.6 * dr.mean()
    assert both.max() < 0.25 * dr.max()
    assert both.max() < 5.0                      # room level
    assert both.mean() < tags.mean()
