"""Floor detection probability: the share of time (and of checkpoints) on the right floor.

ISO/IEC 18305 scores the floor as the share of test points whose estimated floor is the true
one; its test points are on floors. Floors are ``round((z - ground_z) / floor_height)`` for
both the estimate and the truth; the continuous truth is sampled on a uniform grid of
``grid_s`` over the time both cover. ``time_share_correct`` counts every grid time (on a
landing half-way up, the true floor is a coin toss); ``time_share_correct_on_floors`` only
those where the truth is within ``on_floor_m`` of a floor's level (the ISO reading).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hrtls.data import Checkpoints, GroundTruth, Trajectory
from hrtls.fusion.floors import floor_index


def _changes(floors: np.ndarray) -> int:
    return int(np.count_nonzero(np.diff(floors))) if len(floors) > 1 else 0


def floor_detection(estimate: Trajectory, truth: GroundTruth | None,
                    checkpoints: Checkpoints | None, *, floor_height_m: float,
                    ground_z_m: float = 0.0, grid_s: float = 0.5, on_floor_m: float = 0.3
                    ) -> dict[str, Any] | None:
    """Floor scores of ``estimate``; None when there is no truth to compare with.

    Keys: ``floor_height_m``; with continuous truth ``time_share_correct``,
    ``time_share_correct_on_floors``, ``floors_true``,
    ``changes_true`` and ``changes_estimated`` (on the grid); with checkpoints
    ``checkpoints_correct`` and ``checkpoints``.
    """
    if len(estimate) == 0 or (truth is None and checkpoints is None):
        return None
    out: dict[str, Any] = {"floor_height_m": float(floor_height_m)}
    t0, t1 = float(estimate.t[0]), float(estimate.t[-1])
    if truth is not None and len(truth.t) > 1:
        lo, hi = max(t0, float(truth.t[0])), min(t1, float(truth.t[-1]))
        if hi > lo:
            grid = np.arange(lo, hi, grid_s)
            z_true = np.interp(grid, truth.t, truth.xyz[:, 2])
            z_est = estimate.position_at(grid)[:, 2]
            f_true = floor_index(z_true, floor_height_m, ground_z_m=ground_z_m)
            f_est = floor_index(z_est, floor_height_m, ground_z_m=ground_z_m)
            level = ground_z_m + f_true * floor_height_m
            on_floor = np.abs(z_true - level) <= on_floor_m
            right = f_true == f_est
            out.update(time_share_correct=float(np.mean(right)),
                       time_share_correct_on_floors=float(np.mean(right[on_floor]))
                       if np.any(on_floor) else None,
                       floors_true=sorted({int(f) for f in f_true}),
                       changes_true=_changes(f_true), changes_estimated=_changes(f_est))
    if checkpoints is not None and len(checkpoints.t):
        inside = (checkpoints.t >= t0) & (checkpoints.t <= t1)
        if np.any(inside):
            f_true = floor_index(checkpoints.xyz[inside, 2], floor_height_m,
                                 ground_z_m=ground_z_m)
            f_est = floor_index(estimate.position_at(checkpoints.t[inside])[:, 2],
                                floor_height_m, ground_z_m=ground_z_m)
            out.update(checkpoints_correct=float(np.mean(f_true == f_est)),
                       checkpoints=int(np.count_nonzero(inside)))
    return out
