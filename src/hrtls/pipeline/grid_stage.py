"""The tracker's stage for sessions with beacon RSS but no IMU: the grid filter.

With ``[prediction] no_imu = "grid"`` (the default) and at least three positioned anchors, the
RSS readings of each chunk go to :class:`~hrtls.fusion.rss_grid.RssGridFilter` (settings:
``[prediction.grid]``, path loss: the tracker's); its rows (one per scan: mean and covariance
of the position density, height of the start, heading not observed: the variance of a uniform
angle) are the track's rows, live and offline, instead of the random-walk Kalman filter's.
Readings are buffered until their scan window has closed, so chunks give the rows of one call.
An anchor landmark's extra field ``rss_offset_db`` (a site survey of that anchor's RSS over
the channel model, dB) is the grid's starting offset for it. With ``[prediction.radio_map]
survey`` (a CSV file of readings at known positions) the grid adds that survey's radio map to
the channel model (:mod:`hrtls.fusion.radio_map`).
The grid uses RSS only: once a fix, tag read or range arrives, the stage turns off (with a
note) and the Kalman filter's track, which uses them all, is the track.
With ``[offline] grid_smoother`` (:meth:`GridStage.keep_densities`, called by
:meth:`~hrtls.pipeline.tracker.Tracker.run` only: offline) the filtered densities are kept and,
at :meth:`GridStage.finish`, the rows are replaced by those of the forward-backward smoother
(:mod:`hrtls.fusion.rss_grid_smoother`). With ``[prediction.grid] smoother_lag_s`` L > 0 (live
too) each row is that of the fixed-lag smoother over the scans up to L s after it, out once a
scan more than L s later has been filtered (:class:`~hrtls.fusion.rss_grid_smoother.FixedLag`).
``no_imu = "random-walk"`` keeps the Kalman filter with
:class:`~hrtls.fusion.random_walk.RandomWalkParams`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hrtls.data import Activity, Landmark, Session
from hrtls.frames import UNIFORM_ANGLE_VAR_RAD2
from hrtls.fusion.path_loss import PathLossModel
from hrtls.fusion.radio_map import RadioMapParams, RadioSurvey, residual_map
from hrtls.fusion.rss_grid import (
    NO_RECORD,
    GridGeometry,
    GridParams,
    GridRows,
    GridState,
    RssGridFilter,
    causal_scans,
)
from hrtls.fusion.rss_grid_smoother import FixedLag, GridRecord, check_smoothable
from hrtls.fusion.shadowing import ShadowingMemory
from hrtls.pipeline.build import Notes, grid_anchors
from hrtls.pipeline.config import TrackerConfig, params_of
from hrtls.pipeline.output import TrackRows

RSS_OFFSET_KEY = "rss_offset_db"
"""Extra landmark field: the anchor's RSS over the channel model, dB (a site survey)."""


def survey_offsets(anchors: dict[str, Landmark], ids: list[str]) -> np.ndarray:
    """Each anchor's surveyed RSS offset over the channel, dB (extra field ``rss_offset_db``).

    Zero where the landmark does not carry one.
    """
    return np.array([float((anchors[a].model_extra or {}).get(RSS_OFFSET_KEY, 0.0))
                     for a in ids], dtype=np.float64)


class GridStage:
    """Buffered RSS readings, the grid filter's state and its rows.

    ``filter`` is None when the stage is off (an IMU, ``no_imu = "random-walk"``, RSS off, too
    few anchors, or other observations than RSS): it then ignores readings.
    """

    def __init__(self, anchors: dict[str, Landmark], *, model: PathLossModel,
                 params: GridParams, t0: float, z_m: float, notes: Notes,
                 survey: RadioSurvey | None = None,
                 map_params: RadioMapParams | None = None) -> None:
        """``survey``: readings at known positions for a radio map (``map_params``)."""
        self.ids = sorted(anchors)
        xy = np.array([anchors[a].xyz()[:2] for a in self.ids], dtype=np.float64)
        radio_map = None
        if self.ids and survey is not None:
            geometry = GridGeometry.around(xy, cell_m=params.cell_m, margin_m=params.margin_m,
                                           max_cells=params.max_cells)
            radio_map = residual_map(survey, anchor_ids=self.ids, anchors_xy=xy,
                                     geometry=geometry, model=model,
                                     params=map_params or RadioMapParams())
        self.filter = RssGridFilter(xy, model=model, params=params, radio_map=radio_map) \
            if self.ids else None
        self.params = params
        self.t0 = t0
        self.z_m = z_m
        self.notes = notes
        self.state = GridState(-math.inf, np.zeros((0, 0)), np.zeros(0)) if self.filter is None \
            else self.filter.start(survey_offsets(anchors, self.ids))
        self._buf_t = np.zeros(0)
        self._buf_a = np.zeros(0, dtype=np.int64)
        self._buf_r = np.zeros(0)
        self._buf_w = np.zeros(0)               # information fraction of each reading
        self._memory = ShadowingMemory()
        self.rows = TrackRows()
        self.record: GridRecord | None = None      # [offline] grid_smoother
        self.smoothed = False
        self.lag: FixedLag | None = None
        if self.filter is not None and params.smoother_lag_s > 0.0:
            check_smoothable(params, where="[prediction.grid] smoother_lag_s")
            self.lag = FixedLag.empty(self.filter.geometry, lag_s=params.smoother_lag_s)

    @classmethod
    def build(cls, config: TrackerConfig, landmarks: dict[str, Landmark], model: PathLossModel,
              *, has_imu: bool, t0: float, z_m: float, notes: Notes) -> GridStage:
        """The stage, on when the session has no IMU and the configuration asks for it.

        ``t0``: first sample time (scan windows start there), s; ``z_m``: height of the rows.
        """
        params = params_of(GridParams, config.prediction.grid)
        map_params = params_of(RadioMapParams, config.prediction.radio_map)
        anchors = grid_anchors(config, landmarks, has_imu=has_imu)
        survey = None
        if anchors and map_params.survey:
            from hrtls.io.survey import read_survey

            survey = read_survey(map_params.survey)
        stage = cls(anchors, model=model, params=params, t0=t0, z_m=z_m,
                    notes=notes, survey=survey, map_params=map_params)
        if stage.filter is not None:
            notes.add(f"no IMU: positions from beacon RSS alone by a grid filter over "
                      f"{len(anchors)} anchors ({stage.filter.geometry.cell_m:.2f} m cells), "
                      "starting from the first scan's likelihood; heading not observed" +
                      (f"; radio map of {len(survey.rss_dbm)} surveyed readings"
                       if survey is not None else ""))
        elif not has_imu:
            notes.add("no IMU: positions from the infrastructure alone, predicted by a random "
                      "walk between observations")
        return stage

    def add(self, chunk: Session, *, horizon: float) -> None:
        """Buffer the RSS of known anchors, run the scans whose window ended by ``horizon``.

        Other observations in ``chunk`` (fixes, tags, ranges) turn the stage off.
        """
        if self.filter is None:
            return
        others = [name for name in ("fixes", "tags", "ranges")
                  if getattr(chunk, name) is not None and len(getattr(chunk, name))]
        if others:
            self.filter = None
            self.notes.add(f"no IMU and {others[0]} besides the RSS: the Kalman filter's track "
                           "is kept (the grid filter uses RSS only)")
            return
        rss = chunk.rss
        if rss is not None and len(rss):
            index = {a: i for i, a in enumerate(self.ids)}
            a = np.array([index.get(str(x), -1) for x in rss.anchor.tolist()], dtype=np.int64)
            keep = a >= 0
            w = self._memory.fractions(rss.t[keep], a[keep],
                                       tau_s=self.params.shadowing_time_s)
            self._buf_w = np.concatenate([self._buf_w, w])
            self._buf_t = np.concatenate([self._buf_t, rss.t[keep]])
            self._buf_a = np.concatenate([self._buf_a, a[keep]])
            self._buf_r = np.concatenate([self._buf_r, rss.rss_dbm[keep]])
        self._run(horizon)

    def _run(self, horizon: float) -> None:
        w = self.params.scan_s
        closed = self.t0 + w * math.floor((horizon - self.t0) / w) if math.isfinite(horizon) \
            else math.inf
        upto = int(np.searchsorted(self._buf_t, closed, side="left"))
        if upto == 0 or self.filter is None:
            return
        scans = causal_scans(self._buf_t[:upto], self._buf_a[:upto], self._buf_r[:upto],
                             n_anchors=len(self.ids), scan_s=w, average_s=self.params.average_s,
                             t_origin=self.t0, t_from=self.state.t,
                             info=self._buf_w[:upto],
                             statistic=self.params.window_statistic)
        g, n = self.filter.geometry, len(scans.t)
        # the filtered densities the smoothers need: all of them offline, else the lag's
        if self.record is not None:
            record = self.record.new(n, g)
        elif self.lag is not None:
            record = (np.zeros((n, g.ny, g.nx), np.float32), np.zeros((n, 3)))
        else:
            record = NO_RECORD
        rows, self.state = self.filter.update(self.state, scans, record=record)
        self._add(rows if self.lag is None else
                  self.lag.push(rows.t, *record, geometry=g, params=self.params))
        # readings older than the averaging window of the next scan are no longer needed
        drop = int(np.searchsorted(self._buf_t, self.state.t - self.params.average_s,
                                   side="right"))
        self._buf_t, self._buf_a, self._buf_r, self._buf_w = (
            self._buf_t[drop:], self._buf_a[drop:], self._buf_r[drop:], self._buf_w[drop:])

    def _add(self, rows: GridRows) -> None:
        n = len(rows.t)
        x = np.column_stack([rows.mean_xy, np.full(n, self.z_m), np.zeros(n)])
        self.rows.add_block(rows.t, x, rows.cov_xy, np.full(n, UNIFORM_ANGLE_VAR_RAD2),
                            np.full(n, int(Activity.UNKNOWN)))

    def keep_densities(self) -> None:
        """``[offline] grid_smoother``: keep the densities for :meth:`finish` to smooth."""
        check_smoothable(self.params)
        self.record = GridRecord()

    def finish(self) -> None:
        """Run every buffered scan (end of the recording); smooth the rows if asked."""
        self._run(math.inf)
        if self.lag is not None and self.filter is not None:
            self._add(self.lag.flush(geometry=self.filter.geometry, params=self.params))
        if self.record is None:
            return
        if self.filter is None:
            self.notes.add("[offline] grid_smoother: no grid filter on this session (an IMU, "
                           "other observations than RSS or too few anchors): not applied")
            return
        old = self.rows
        if not old.t:
            return
        t = np.concatenate(old.t)
        smooth = self.record.smooth(t, geometry=self.filter.geometry, params=self.params)
        x = np.concatenate(old.x)
        x[:, :2] = smooth.mean_xy
        self.rows = TrackRows()
        self.rows.add_block(t, x, smooth.cov_xy, np.concatenate(old.var_h),
                            np.concatenate(old.activity))
        self.record = None
        self.smoothed = True
        self.notes.add("[offline] grid_smoother: rows of the forward-backward smoother of the "
                       "grid density (offline: each row uses the readings after it too)")

    def state_dict(self) -> dict[str, Any] | None:
        """What the stage needs to continue (snapshot; rows already produced are not kept)."""
        if self.filter is None:
            return None
        s = self.state
        return {"t": s.t, "density": s.density, "offsets_db": s.offsets_db,
                "offsets_var_db2": s.offsets_var_db2, "velocity_m_per_s": s.velocity_m_per_s,
                "burst_probability": s.burst_probability, "started": s.started,
                "buf_t": self._buf_t, "buf_a": self._buf_a, "buf_r": self._buf_r,
                "buf_w": self._buf_w,
                "last_t": dict(self._memory.last_t),
                "lag": None if self.lag is None else {"t": self.lag.t, "kept": self.lag.kept,
                                                      "moved": self.lag.moved}}

    def restore(self, d: dict[str, Any] | None) -> None:
        """Continue from :meth:`state_dict` (None: the stage was off, and stays off)."""
        if d is None:
            self.filter = None
        if d is None or self.filter is None:
            return
        self.state = GridState(float(d["t"]), np.asarray(d["density"], dtype=np.float64),
                               np.asarray(d["offsets_db"], dtype=np.float64),
                               bool(d["started"]),
                               None if d.get("offsets_var_db2") is None   # older snapshots
                               else np.asarray(d["offsets_var_db2"], dtype=np.float64),
                               None if d.get("velocity_m_per_s") is None
                               else np.asarray(d["velocity_m_per_s"], dtype=np.float64),
                               None if d.get("burst_probability") is None
                               else np.asarray(d["burst_probability"], dtype=np.float64))
        self._buf_t = np.asarray(d["buf_t"], dtype=np.float64)
        self._buf_a = np.asarray(d["buf_a"], dtype=np.int64)
        self._buf_r = np.asarray(d["buf_r"], dtype=np.float64)
        # buf_w, last_t: absent from snapshots made before the shadowing discount
        self._buf_w = np.asarray(d.get("buf_w", np.ones(len(self._buf_t))), dtype=np.float64)
        self._memory = ShadowingMemory({str(k): float(v)
                                        for k, v in d.get("last_t", {}).items()})
        if self.lag is not None and d.get("lag") is not None:
            lag = d["lag"]
            self.lag.t = np.asarray(lag["t"], dtype=np.float64)
            self.lag.kept = np.asarray(lag["kept"], dtype=np.float32)
            self.lag.moved = np.asarray(lag["moved"], dtype=np.float64)
