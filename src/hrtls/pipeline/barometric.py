"""The barometric floor stage run after a tracker (the tracker itself runs it causally now).

:class:`~hrtls.pipeline.tracker.Tracker` runs the same filter live
(:mod:`hrtls.pipeline.baro_stage`); a result that has ``report["floors"]`` from it is returned
unchanged here. For a result from elsewhere, :func:`apply_baro_floors` runs
:func:`hrtls.fusion.baro_floors.baro_floors` on the pressure of the recording and replaces
the track's heights (the step model's stairs heights drift: a fraction of a riser per step)
with the barometer's, taken at each row from the last pressure
sample at or before it (causal). Steps and rows labelled stairs while the barometer shows no
climb (less than ``flat_m`` over the ``flat_window_s`` before the step's end) become walking
with no height change. Without a barometer the track is returned as it is.
``report["floors"]`` says which source the heights come from and what was changed.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hrtls.data import Activity, SensorSeries, Session, StepEvents, Trajectory
from hrtls.fusion.baro_floors import BaroFloorParams, BaroFloors, baro_floors
from hrtls.pipeline.config import TrackerConfig
from hrtls.pipeline.tracker import TrackResult

_STAIRS = (int(Activity.UPSTAIRS), int(Activity.DOWNSTAIRS))


@dataclass(frozen=True, slots=True)
class BaroStageParams:
    """When the barometer says flat: less than ``flat_m`` over the last ``flat_window_s``."""

    flat_m: float = 0.25
    flat_window_s: float = 3.0


def _climb(floors: BaroFloors, t: np.ndarray, window_s: float) -> np.ndarray:
    _, z_now = floors.at(t)
    _, z_before = floors.at(t - window_s)
    return np.abs(z_now - z_before)


def apply_baro_floors(result: TrackResult, pressure: SensorSeries | None, *,
                      floor_height_m: float, enabled: bool = True,
                      params: BaroStageParams | None = None,
                      floor_params: BaroFloorParams | None = None) -> TrackResult:
    """``result`` with heights and floors from ``pressure`` (unchanged without one)."""
    if "floors" in result.report:   # the tracker's own barometric stage ran
        return result
    report = dict(result.report)
    if not enabled or pressure is None or len(pressure) < 2 or len(result.trajectory) == 0:
        report["floors"] = {"source": "step model" if pressure is None or len(pressure) < 2
                            else "step model (barometer off)", "floor_height_m": floor_height_m}
        return replace(result, report=report)
    p = params or BaroStageParams()
    fp = floor_params or BaroFloorParams(floor_height_m=floor_height_m)
    floors = baro_floors(pressure.t, pressure.values[:, 0], params=fp,
                         step_times_s=result.steps.t_end, step_starts_s=result.steps.t_start,
                         step_dz_m=result.steps.dz_m)
    tr = result.trajectory
    fl, z_rel = floors.at(tr.t)
    z = tr.xyz[0, 2] + z_rel - fp.floor_height_m * fl[0]
    activity = tr.activity.copy()
    row_flat = np.isin(activity, _STAIRS) & (_climb(floors, tr.t, p.flat_window_s) < p.flat_m)
    activity[row_flat] = int(Activity.WALKING)
    trajectory = Trajectory(tr.t, np.column_stack([tr.xyz[:, :2], z]), tr.heading_rad,
                            tr.cov_xy, tr.var_heading, activity)
    steps = result.steps
    relabelled = 0
    if len(steps):
        flat = np.isin(steps.activity, _STAIRS) & (
            _climb(floors, steps.t_end, p.flat_window_s) < p.flat_m)
        relabelled = int(np.count_nonzero(flat))
        if relabelled:
            step_activity = steps.activity.copy()
            step_activity[flat] = int(Activity.WALKING)
            dz = np.where(flat, 0.0, steps.dz_m)
            steps = StepEvents(steps.t_start, steps.t_end, steps.length_m, steps.heading_rad,
                               dz, step_activity, steps.frequency_hz, steps.acc_max,
                               steps.acc_min)
    report["floors"] = {
        "source": "barometer", "floor_height_m": fp.floor_height_m,
        "floor_changes": floors.changes, "pressure_steps_absorbed": floors.pressure_steps,
        "stairs_steps_relabelled_walking": relabelled,
        "stairs_rows_relabelled_walking": int(np.count_nonzero(row_flat)),
    }
    return TrackResult(trajectory, steps, result.attitude, result.diagnostics, report)


def with_baro_floors(result: TrackResult, session: Session, config: TrackerConfig
                     ) -> TrackResult:
    """:func:`apply_baro_floors` with the session's pressure and floor height."""
    return apply_baro_floors(result, session.pressure,
                             floor_height_m=session.meta.floor_height_m,
                             enabled=config.barometer)
