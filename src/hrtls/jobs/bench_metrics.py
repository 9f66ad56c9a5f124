"""How ``hrtls bench papers`` scores a track against the simulation, the way each paper did.

Our readings of the papers (see :data:`DEFINITIONS`):

* Colombo Sec. V: "position errors along both X_w and Y_w smaller than +-50 cm with 97 %
  probability" -- per truth sample the larger of the two per-axis absolute errors,
  ``max(|e_x|, |e_y|)``, and its 97th percentile over the walk. Velocity RMSE (Fig. 7): the RMS
  difference of the filter's and the true walking *speed* on a 10 Hz grid, both smoothed over
  1 s, while the user walks (Fig. 7 is plotted against the distance travelled). Fig. 7 scores
  the automaton speed ``v_xu`` that drives the prediction (eq. 16), not the derivative of the
  corrected track: we differentiate the estimated track with the position jumps of the
  accepted fixes removed (:func:`predicted_track`); the paper differentiated camera
  positions, we use the exact truth.
* Basso Table I "mean position error": the error at the path's way-points (turns and end),
  integrated over the distance walked (trapezoids, start error 0), divided by the path length
  (mean error along the path, m) and normalized by the path length (fraction of distance).
* Tarrio Sec. IV: the 90th percentile of the horizontal error against the continuous truth;
  "Kalman better than RSS alone": mean error of RSS alone (each 2 s WLS position held, no
  IMU) minus mean error of the preset.
* Inderst Table 6.13: maximum Euclidean error at the checkpoints (eq. 6.1) over the mission;
  Tables 6.14-6.15: mean and maximum checkpoint error of users A and B with position-only and
  with position + heading (bearing) correction.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Session, Trajectory
from hrtls.evaluate.floors import floor_detection
from hrtls.evaluate.metrics import (
    axis_errors,
    checkpoint_errors,
    distance_at,
    integral_mean_error,
    moving_speed_rmse,
    position_errors,
)
from hrtls.pipeline import Tracker, TrackerConfig, preset
from hrtls.pipeline.tracker import TrackResult
from hrtls.sim.scenarios import SimulationResult

DEFINITIONS = {
    "p97_axis": "97th percentile of max(|e_x|, |e_y|) over the walk (Colombo Sec. V)",
    "speed_rmse": "RMSE of the prediction's walking speed (fix jumps removed) vs the true speed "
                  "while walking, 10 Hz grid, 1 s smoothing (Colombo Fig. 7)",
    "ime": "Basso integral mean error at the way-points / path length (Table I)",
    "p90": "90th percentile of the horizontal error vs continuous truth (Tarrio Fig. 1)",
    "rss_gain": "mean error of RSS alone minus mean error of the preset (Tarrio Sec. IV)",
    "cp_max": "maximum checkpoint error, eq. 6.1 (Inderst Table 6.13)",
    "cp_mean": "mean checkpoint error, eq. 6.1 (Inderst Tables 6.14-6.15)",
}


Metric = Callable[[TrackResult, SimulationResult], float]


def p97_axis(result: TrackResult, sim: SimulationResult) -> float:
    """Colombo: 97th percentile of max(|e_x|, |e_y|) (m)."""
    truth = sim.session.truth
    assert truth is not None
    return float(np.percentile(np.max(axis_errors(result.trajectory, truth), axis=1), 97.0))


def predicted_track(result: TrackResult) -> Trajectory:
    """The estimated track without the position jumps of the accepted fixes.

    Its time derivative is the velocity the filter's prediction integrated (eq. 16: the
    automaton speed along the yaw; or the steps), which is what Colombo's Fig. 7 scores. The
    jumps come from ``report["fix_jumps"]`` (rows ``[t, dx, dy]``, added by the bench's
    tracking run).
    """
    tr = result.trajectory
    jumps = np.asarray(result.report.get("fix_jumps", []), dtype=np.float64).reshape(-1, 3)
    if len(jumps) == 0:
        return tr
    # the row at a fix time holds the corrected state: remove every jump at or before it
    cum = np.vstack([np.zeros((1, 2)), np.cumsum(jumps[:, 1:], axis=0)])
    k = np.searchsorted(jumps[:, 0], tr.t, side="right")
    xyz = tr.xyz.copy()
    xyz[:, :2] -= cum[k]
    return Trajectory.build(t=tr.t, xyz=xyz)


SPEED_MOVING_M_S = 0.2
"""Fig. 7 is plotted against the distance travelled: only samples where the (smoothed) true
speed exceeds this count, m/s."""


def speed_rmse(result: TrackResult, sim: SimulationResult) -> float:
    """Colombo Fig. 7: RMSE of the filter's walking speed against the true speed (m/s).

    The filter's speed is that of its prediction (:func:`predicted_track`: fix jumps are
    corrections, not motion); both tracks are sampled on the same 10 Hz grid, smoothed over
    1 s and differentiated the same way; samples where the true speed is below
    :data:`SPEED_MOVING_M_S` (standing before and after the walk) are left out.
    """
    truth = sim.session.truth
    assert truth is not None
    return moving_speed_rmse(predicted_track(result), truth, moving_m_s=SPEED_MOVING_M_S)


def basso_ime(result: TrackResult, sim: SimulationResult) -> float:
    """Basso Table I mean position error: integral mean error / length (%)."""
    cps, truth = sim.session.checkpoints, sim.session.truth
    assert cps is not None and truth is not None
    t, e, _ = checkpoint_errors(result.trajectory, cps)
    s = distance_at(truth, t)
    length = float(sim.reference.get("length_m", s[-1] if len(s) else 1.0))
    _, frac = integral_mean_error(np.concatenate([[0.0], s]), np.concatenate([[0.0], e]),
                                  length)
    return 100.0 * frac


def _horizontal_errors(result: TrackResult, sim: SimulationResult) -> NDArray[np.float64]:
    """Horizontal error at every truth sample (m)."""
    truth = sim.session.truth
    assert truth is not None
    return position_errors(result.trajectory, truth)[1]


def _checkpoint_errors(result: TrackResult, sim: SimulationResult) -> NDArray[np.float64]:
    """Inderst eq. 6.1: error at every checkpoint (m)."""
    cps = sim.session.checkpoints
    assert cps is not None
    return checkpoint_errors(result.trajectory, cps)[1]


def p90_error(result: TrackResult, sim: SimulationResult) -> float:
    """90th percentile of the horizontal error (m)."""
    return float(np.percentile(_horizontal_errors(result, sim), 90.0))


def mean_error(result: TrackResult, sim: SimulationResult) -> float:
    """Mean horizontal error (m)."""
    return float(np.mean(_horizontal_errors(result, sim)))


def max_error(result: TrackResult, sim: SimulationResult) -> float:
    """Maximum horizontal error (m)."""
    return float(np.max(_horizontal_errors(result, sim)))


def checkpoint_max(result: TrackResult, sim: SimulationResult) -> float:
    """Inderst eq. 6.1: maximum checkpoint error (m)."""
    return float(np.max(_checkpoint_errors(result, sim)))


def checkpoint_mean(result: TrackResult, sim: SimulationResult) -> float:
    """Inderst eq. 6.1: mean checkpoint error (m)."""
    return float(np.mean(_checkpoint_errors(result, sim)))


def rss_alone_session(session: Session) -> Session:
    """The session without its IMU: Tarrio's "RSS alone" input."""
    return session.with_parts(imu=None, orientation=None, pressure=None)


def rss_alone_config(config: TrackerConfig) -> TrackerConfig:
    """RSS alone: WLS positions held between scans (no inertial prediction).

    Tarrio's baseline is the per-scan WLS position, so the session without IMU keeps the
    Kalman filter with the random-walk prediction (``no_imu = "random-walk"``), not the
    tracker's default grid filter for such sessions (:mod:`hrtls.pipeline.grid_stage`),
    which is an estimator of its own with a motion model.
    """
    prediction = config.prediction.model_copy(update={"no_imu": "random-walk"})
    return config.model_copy(update={"name": "rss-alone", "prediction": prediction,
                                      "rss": config.rss.model_copy(update={"mode": "wls"})})


def rss_gain(result: TrackResult, sim: SimulationResult) -> float:
    """Mean error of RSS alone minus the preset's mean error (m)."""
    base = Tracker(rss_alone_config(preset("tarrio2011"))).run(rss_alone_session(sim.session))
    return mean_error(base, sim) - mean_error(result, sim)


def activity_correct(result: TrackResult, sim: SimulationResult) -> float:
    """Share of the true activity samples the track labels alike (%), Inderst Sec. 6.3.

    Each simulation sample inside the track takes the activity of the last trajectory row at
    or before it.
    """
    tr = result.trajectory
    t, truth = sim.activity_t, sim.activity
    inside = (t >= tr.t[0]) & (t <= tr.t[-1])
    row = np.searchsorted(tr.t, t[inside], side="right") - 1
    return float(100.0 * np.mean(tr.activity[row] == truth[inside]))


def floors_correct(result: TrackResult, sim: SimulationResult) -> float:
    """Share of the time on a floor that the track is on the right floor (ISO/IEC 18305)."""
    scores = floor_detection(result.trajectory, sim.session.truth, None,
                             floor_height_m=sim.session.meta.floor_height_m)
    assert scores is not None
    return float(scores["time_share_correct_on_floors"])
