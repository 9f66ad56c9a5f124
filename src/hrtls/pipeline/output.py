"""The tracker's output rows: accumulated in blocks, read whole or since a time.

One row per processed event (the filter state after it); several events at one time keep the
last row. :class:`Estimates` is what :meth:`hrtls.pipeline.Tracker.estimates_since` returns
to a live reader.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.data import Trajectory
from hrtls.fusion.state import IH, FilterState

FloatArray = np.ndarray


@dataclass(frozen=True, slots=True, eq=False)
class Estimates:
    """Trajectory rows produced so far (ENU, m; heading rad, CCW from east).

    Attributes
    ----------
    t: row times, s (increasing). xyz: (N, 3) position, m. heading_rad: (N,).
    cov_xy: (N, 2, 2) horizontal covariance, m^2. var_heading: (N,) rad^2.
    activity: (N,) :class:`~hrtls.data.Activity` codes.
    since_correction_s: (N,) time since the last accepted correction (fix, tag, RSS, range)
    at or before the row, s (inf before the first).
    floor: (N,) floor index ``round(z / floor_height_m)``.
    """

    t: FloatArray
    xyz: FloatArray
    heading_rad: FloatArray
    cov_xy: FloatArray
    var_heading: FloatArray
    activity: np.ndarray
    since_correction_s: FloatArray
    floor: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


class TrackRows:
    """Accumulated output rows, in blocks; ``hidden`` leading rows are not reported.

    After a restore the last row before the snapshot is kept (hidden) so that a later row at
    the same time still replaces it, as in the uninterrupted run.
    """

    def __init__(self) -> None:
        self.t: list[np.ndarray] = []
        self.x: list[np.ndarray] = []
        self.cov: list[np.ndarray] = []
        self.var_h: list[np.ndarray] = []
        self.activity: list[np.ndarray] = []
        self.hidden = 0

    def add(self, state: FilterState, activity: int) -> None:
        """One row: the state's position, heading and covariance."""
        self.add_block(np.array([state.t]), state.x[None, :], state.P[None, :2, :2],
                       np.array([state.P[IH, IH]]), np.array([activity]))

    def add_block(self, t: np.ndarray, x: np.ndarray, cov_xy: np.ndarray, var_h: np.ndarray,
                  activity: np.ndarray) -> None:
        """Rows of a kernel run (states ``x`` (N, 4), covariances (N, 2, 2))."""
        if len(t):
            self.t.append(t)
            self.x.append(x)
            self.cov.append(cov_xy)
            self.var_h.append(var_h)
            self.activity.append(np.asarray(activity, dtype=np.int64))

    def last_time(self) -> float | None:
        """Time of the latest row (None before any)."""
        return float(self.t[-1][-1]) if self.t and len(self.t[-1]) else None

    def _compact(self) -> None:
        if len(self.t) > 1:
            self.t = [np.concatenate(self.t)]
            self.x = [np.concatenate(self.x)]
            self.cov = [np.concatenate(self.cov)]
            self.var_h = [np.concatenate(self.var_h)]
            self.activity = [np.concatenate(self.activity)]

    def _kept(self) -> np.ndarray:
        """Mask of the reported rows: the last of each time, hidden rows dropped."""
        t = self.t[0]
        keep = np.ones(len(t), dtype=bool)
        keep[:-1] = t[1:] > t[:-1]
        keep[:self.hidden] = False
        return keep

    def trajectory(self) -> Trajectory:
        """Every reported row."""
        if not self.t:
            return Trajectory.build(t=np.zeros(0), xyz=np.zeros((0, 3)))
        self._compact()
        keep = self._kept()
        x = self.x[0][keep]
        return Trajectory.build(t=self.t[0][keep], xyz=x[:, :3], heading_rad=x[:, IH],
                                cov_xy=self.cov[0][keep], var_heading=self.var_h[0][keep],
                                activity=self.activity[0][keep])

    def since(self, t_after: float, correction_t: FloatArray, floor_height_m: float
              ) -> Estimates:
        """Reported rows with time > ``t_after``; ``correction_t``: accepted corrections."""
        if not self.t:
            z = np.zeros(0)
            return Estimates(z, np.zeros((0, 3)), z, np.zeros((0, 2, 2)), z,
                             np.zeros(0, dtype=np.int64), z, np.zeros(0, dtype=np.int64))
        self._compact()
        t_all = self.t[0]
        i0 = int(np.searchsorted(t_all, t_after, side="right"))
        keep = self._kept()[i0:]
        t = t_all[i0:][keep]
        x = self.x[0][i0:][keep]
        k = np.searchsorted(correction_t, t, side="right")
        last = (np.where(k > 0, correction_t[np.maximum(k - 1, 0)], -np.inf)
                if len(correction_t) else np.full(len(t), -np.inf))
        return Estimates(t, x[:, :3].copy(), x[:, IH].copy(), self.cov[0][i0:][keep],
                         self.var_h[0][i0:][keep], self.activity[0][i0:][keep], t - last,
                         np.rint(x[:, 2] / floor_height_m).astype(np.int64))
