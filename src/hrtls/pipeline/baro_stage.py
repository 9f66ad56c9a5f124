"""The tracker's barometric stage: heights, floors and flat-stairs relabelling, live.

Pressure samples are queued as chunks bring them and run through
:func:`hrtls.fusion.baro_floors.baro_floors_update` up to the schedule's horizon, where every
step that ended before is known (the walking flags of the pressure-step removal need them);
the rest at :meth:`BaroStage.finish`. A row at time t takes the height of the last processed
pressure sample at or before t (causal), placed on the start pose's height:
``z = z_pose + z_baro(t) - floor_height * floor(t_pose)``. A row or step labelled stairs while
the barometer climbed less than ``flat_m`` over the ``flat_window_s`` before it becomes
walking (with no height change for a step). Without pressure samples nothing is changed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hrtls.data import Activity, StepEvents, Trajectory
from hrtls.fusion.baro_floors import (
    BaroFloorParams,
    BaroFloorState,
    baro_floors_update,
    stairs_rates,
    walking_flags,
)

_STAIRS = (int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS))


@dataclass(frozen=True, slots=True)
class BaroStageParams:
    """When the barometer says flat: less than ``flat_m`` over the last ``flat_window_s``."""

    flat_m: float = 0.25
    flat_window_s: float = 3.0


class BaroStage:
    """Queue, causal floor filter and its outputs (time, floor, height) for one track."""

    STATE = ("filter", "queue_t", "queue_p", "step_ends", "step_starts", "step_dz", "out_t",
             "out_floor", "out_z", "anchor_floor", "changes")
    """Attributes a snapshot holds."""

    def __init__(self, *, floor_height_m: float, t_pose: float, z_pose_m: float,
                 params: BaroStageParams | None = None) -> None:
        self.floor_params = BaroFloorParams(floor_height_m=floor_height_m)
        self.params = params or BaroStageParams()
        self.t_pose = t_pose
        self.z_pose_m = z_pose_m
        self.filter: BaroFloorState | None = None
        self.queue_t = np.zeros(0)
        self.queue_p = np.zeros(0)
        self.step_ends = np.zeros(0)
        self.step_starts = np.zeros(0)
        self.step_dz = np.zeros(0)
        self.out_t = np.zeros(0)
        self.out_floor = np.zeros(0, dtype=np.int64)
        self.out_z = np.zeros(0)
        self.anchor_floor: int | None = None
        self.changes = 0

    @property
    def active(self) -> bool:
        """Pressure samples have been processed."""
        return len(self.out_t) > 0

    # ------------------------------------------------------------------ input
    def add_pressure(self, t: np.ndarray, pressure_pa: np.ndarray) -> None:
        """Queue a chunk's pressure samples (in time order across chunks)."""
        if len(t):
            self.queue_t = np.concatenate([self.queue_t, np.asarray(t, dtype=np.float64)])
            self.queue_p = np.concatenate([self.queue_p,
                                           np.asarray(pressure_pa, dtype=np.float64)])

    def add_steps(self, t_end: np.ndarray, t_start: np.ndarray | None = None,
                  dz_m: np.ndarray | None = None) -> None:
        """Detected steps' end times (the walking flags).

        With their start times and height changes too: the step model's climb rate on stairs
        (None: no climb).
        """
        if len(t_end):
            n = len(t_end)
            self.step_ends = np.concatenate([self.step_ends, np.asarray(t_end, np.float64)])
            self.step_starts = np.concatenate([self.step_starts, np.asarray(
                t_end if t_start is None else t_start, np.float64)])
            self.step_dz = np.concatenate([self.step_dz, np.zeros(n) if dz_m is None
                                           else np.asarray(dz_m, np.float64)])

    def _trim_steps(self, t_s: float) -> None:
        keep = self.step_ends >= t_s - 2.5
        self.step_ends = self.step_ends[keep]
        self.step_starts = self.step_starts[keep]
        self.step_dz = self.step_dz[keep]

    def advance(self, horizon_s: float) -> None:
        """Process the queued samples up to ``horizon_s``."""
        # pressure samples still to come are after the queue's first or after the horizon
        t_next = min(float(self.queue_t[0]), horizon_s) if len(self.queue_t) else horizon_s
        if len(self.step_ends) and math.isfinite(t_next):
            self._trim_steps(t_next)
        n = int(np.searchsorted(self.queue_t, horizon_s, side="right"))
        if n == 0:
            return
        t, p = self.queue_t[:n], self.queue_p[:n]
        self.queue_t, self.queue_p = self.queue_t[n:], self.queue_p[n:]
        prev_floor = int(self.out_floor[-1]) if len(self.out_floor) else None
        self.filter, out = baro_floors_update(
            self.filter, t, p, walking_flags(t, self.step_ends), params=self.floor_params,
            stairs_m_s=stairs_rates(t, self.step_starts, self.step_ends, self.step_dz))
        self._trim_steps(float(t[-1]))
        self.changes += out.changes + int(prev_floor is not None
                                          and prev_floor != int(out.floor[0]))
        if self.anchor_floor is None and t[-1] > self.t_pose:
            before = np.flatnonzero(t <= self.t_pose)
            self.anchor_floor = (int(out.floor[before[-1]]) if len(before)
                                 else prev_floor if prev_floor is not None else 0)
        self.out_t = np.concatenate([self.out_t, t])
        self.out_floor = np.concatenate([self.out_floor, out.floor])
        self.out_z = np.concatenate([self.out_z, out.z_m])

    def finish(self) -> None:
        """Process everything queued."""
        self.advance(np.inf)

    # ------------------------------------------------------------------ output
    def height_at(self, t: np.ndarray) -> np.ndarray:
        """Height of rows at ``t`` on the start pose's height (last sample at or before)."""
        idx = np.clip(np.searchsorted(self.out_t, t, side="right") - 1, 0, None)
        anchor = 0 if self.anchor_floor is None else self.anchor_floor
        return np.asarray(self.z_pose_m + self.out_z[idx]
                          - self.floor_params.floor_height_m * anchor)

    def flat(self, t: np.ndarray) -> np.ndarray:
        """True where the barometer climbed less than ``flat_m`` over the window before."""
        w = self.params.flat_window_s
        return np.asarray(np.abs(self.height_at(t) - self.height_at(t - w)) < self.params.flat_m)

    def rows(self, t: np.ndarray, xyz: np.ndarray, activity: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """Rows' positions with the barometer's height, and their relabelled activity."""
        if not self.active or not len(t):
            return xyz, activity
        out = xyz.copy()
        out[:, 2] = self.height_at(t)
        act = np.asarray(activity).copy()
        act[np.isin(act, _STAIRS) & self.flat(t)] = int(Activity.WALKING)
        return out, act

    def trajectory(self, tr: Trajectory) -> tuple[Trajectory, int]:
        """``tr`` with the barometer's heights; and how many rows became walking."""
        if not self.active or not len(tr):
            return tr, 0
        xyz, act = self.rows(tr.t, tr.xyz, tr.activity)
        relabelled = int(np.count_nonzero(act != tr.activity))
        return Trajectory(tr.t, xyz, tr.heading_rad, tr.cov_xy, tr.var_heading, act), relabelled

    def steps(self, steps: StepEvents) -> tuple[StepEvents, int]:
        """Stairs steps during which the barometer was flat become walking with no dz."""
        if not self.active or not len(steps):
            return steps, 0
        flat = np.isin(steps.activity, _STAIRS) & self.flat(steps.t_end)
        n = int(np.count_nonzero(flat))
        if not n:
            return steps, 0
        activity = steps.activity.copy()
        activity[flat] = int(Activity.WALKING)
        return StepEvents(steps.t_start, steps.t_end, steps.length_m, steps.heading_rad,
                          np.where(flat, 0.0, steps.dz_m), activity, steps.frequency_hz,
                          steps.acc_max, steps.acc_min), n

    def report(self, *, rows_relabelled: int, steps_relabelled: int) -> dict[str, Any]:
        """``report["floors"]``."""
        fh = self.floor_params.floor_height_m
        if not self.active:
            return {"source": "step model", "floor_height_m": fh}
        return {"source": "barometer", "causal": True, "floor_height_m": fh,
                "floor_changes": self.changes,
                "pressure_steps_absorbed": 0 if self.filter is None
                else int(self.filter.scalars[5]),
                "stairs_steps_relabelled_walking": steps_relabelled,
                "stairs_rows_relabelled_walking": rows_relabelled}

    # ------------------------------------------------------------------ snapshot
    def state(self) -> dict[str, Any]:
        """What a snapshot holds (the outputs only as far back as the flat window reaches)."""
        out = {k: getattr(self, k) for k in self.STATE}
        if len(self.out_t):
            keep = self.out_t >= self.out_t[-1] - self.params.flat_window_s - 1.0
            keep[-1] = True
            for k in ("out_t", "out_floor", "out_z"):
                out[k] = out[k][keep]
        return out

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`state`.

        A state without the steps' starts and height changes (from before they were kept)
        takes its steps as steps of no climb.
        """
        for k in self.STATE:
            if k in ("step_starts", "step_dz") and k not in state:
                setattr(self, k, np.array(state["step_ends"], dtype=np.float64)
                        if k == "step_starts" else np.zeros(len(state["step_ends"])))
            else:
                setattr(self, k, state[k])
