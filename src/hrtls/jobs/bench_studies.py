"""Paper results of ``hrtls bench papers`` that are studies, not one tracked walk.

* :func:`activity_cross_validation` - Inderst Sec. 6.2, Table 6.7: the LDA activity classifier
  (eq. 4.8, Table 4.1 features) trained on nine users and tested on the tenth, ten times; the
  global error rate (12.44 % in the thesis).
* :func:`loose_cooperation` - Inderst Sec. 6.4.1, Fig. 6.11: random 50-node networks with three
  seeds in a corner; share of nodes localized by SELA alone and share of connected networks
  that end fully localized with the Safe Navigation planner.
* :func:`tight_cooperation` - Inderst Sec. 6.4.2, Figs. 6.13-6.16: no anchors, a robot explores
  and runs Algorithm 1; share of networks fully localized and the position RMSE.

Each study takes a bench seed and returns the values of its metrics, so that it runs, like a
tracked case, once per seed and is summarised over the seeds (mean, 90th percentile, worst).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from hrtls.attitude.registry import DEFAULT_FILTER, make_filter
from hrtls.data import Activity
from hrtls.evaluate.metrics import class_weighted_error, hold_previous
from hrtls.gait.activity_lda import train_lda
from hrtls.gait.features import window_labels
from hrtls.gait.session_analysis import activity_windows, session_inputs
from hrtls.sim.devices import get_device
from hrtls.sim.motion_truth import MotionParams, Waypoint
from hrtls.sim.person import simulate_person
from hrtls.sim.simulation_result import SimulationResult
from hrtls.wsn.experiment import loose_study, tight_study

__all__ = ["TABLE_6_7_WINDOWS", "activity_course", "activity_cross_validation",
           "loose_cooperation", "study_user_seed", "tight_cooperation"]

TABLE_6_7_WINDOWS = {Activity.STANDING: 226, Activity.DOWNSTAIRS: 40, Activity.WALKING: 90,
                     Activity.UPSTAIRS: 86}
"""Windows per true class in the thesis' confusion matrix (row sums of Table 6.7)."""

STUDY_USERS = 10
"""Users of the thesis' activity study (ten-fold, leave one user out)."""

LOOSE_NETWORKS = 20
"""Random networks per bench seed in the loose-cooperation study."""

TIGHT_NETWORKS = 10
"""Random networks per bench seed in the tight-cooperation study."""


def study_user_seed(seed: int, user: int) -> int:
    """Scenario seed of user ``user`` of the study drawn for bench seed ``seed``.

    Distinct for every (seed, user) pair and far from the seeds of the tracked cases, so that
    a held-out bench seed never reuses a development walk.
    """
    return 1_000_000 + STUDY_USERS * seed + user


FLOOR_HEIGHT_M = 3.3
"""Floor height of the activity course (the multi-floor walk's building)."""


def activity_course(seed: int) -> SimulationResult:
    """One user's activity patterns (Sec. 6.2): standing, walking, stairs up and down, twice.

    The person (gait, device errors, mounting) is drawn from ``seed``; the stairs are those of
    the multi-floor walk (0.30 m treads, 0.165 m risers, two flights per floor).
    """
    fh = FLOOR_HEIGHT_M
    up = [Waypoint(x=13.0, y=0.0, z=fh / 2, speed_m_s=0.55, corner_radius_m=0.0),
          Waypoint(x=13.0, y=1.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
          Waypoint(x=10.0, y=1.2, z=fh, speed_m_s=0.55, corner_radius_m=0.0, stop_s=15.0)]
    down = [Waypoint(x=13.0, y=1.2, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=13.0, y=0.0, z=fh / 2, speed_m_s=0.6, corner_radius_m=0.0),
            Waypoint(x=10.0, y=0.0, z=0.0, speed_m_s=0.6, corner_radius_m=0.0, stop_s=15.0)]
    wps = [Waypoint(x=0.0, y=0.0)]
    for _ in range(2):
        wps += [Waypoint(x=10.0, y=0.0, speed_m_s=1.1, stop_s=10.0), *up,
                Waypoint(x=0.0, y=1.2, z=fh, speed_m_s=1.1, corner_radius_m=0.0, stop_s=10.0),
                Waypoint(x=10.0, y=1.2, z=fh, speed_m_s=1.1, corner_radius_m=0.0), *down,
                Waypoint(x=0.0, y=0.0, speed_m_s=1.1, corner_radius_m=0.0, stop_s=10.0)]
    return simulate_person(
        "activity_course", seed, {}, wps, device=get_device("mpu9150_motionfit"),
        motion_params=MotionParams(stair_tread_m=0.30, stair_riser_m=0.165),
        floor_height_m=fh, start_pause_s=30.0, end_pause_s=20.0,
        description="Inderst Sec. 6.2 activity patterns: stand, walk, two floors up and down "
                    "with stops, twice")


def _labelled_windows(seed: int, *, window_s: float, cutoff_hz: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """LDA features (W, 7) and true labels (W,) of one user's :func:`activity_course`.

    The features are those the tracker computes: attitude from the default filter, the
    session's (declared) mounting, :func:`~hrtls.gait.session_analysis.activity_windows`. A
    window is labelled only when every sample in it has one true activity.
    """
    sim = activity_course(seed)
    imu = sim.session.imu
    assert imu is not None
    t, acc, _, mount, rate = session_inputs(sim.session)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q_nd = make_filter(DEFAULT_FILTER).run(imu).q
    wf = activity_windows(t, acc, rate_hz=rate, q_nd=q_nd, mounting_q_bd=mount,
                          window_s=window_s, cutoff_hz=cutoff_hz)
    labels = window_labels(hold_previous(sim.activity_t, sim.activity, t),
                           max(4, round(window_s * rate)))
    n = min(len(labels), len(wf.lda))
    return wf.lda[:n], labels[:n]


def activity_cross_validation(seed: int, *, window_s: float = 2.0, cutoff_hz: float = 6.0
                              ) -> float:
    """Leave-one-user-out error of the LDA classifier over a study of ten users, %.

    Each user walks the :func:`activity_course` (standing, walking, stairs up and down);
    for each user a model is trained on the other nine (per-class covariances, eq. 4.8, the
    default loss matrix) and tested on that user. The per-class error rates of the pooled
    test windows are weighted by the class counts of Table 6.7, so that the global rate is the
    one the thesis' class mix would give.
    """
    data = [_labelled_windows(study_user_seed(seed, u), window_s=window_s,
                              cutoff_hz=cutoff_hz) for u in range(STUDY_USERS)]
    truth, predicted = [], []
    for held in range(STUDY_USERS):
        f = np.concatenate([d[0] for u, d in enumerate(data) if u != held])
        y = np.concatenate([d[1] for u, d in enumerate(data) if u != held])
        model = train_lda(f, y, window_s=window_s, cutoff_hz=cutoff_hz, covariance="per_class")
        f_test, y_test = data[held]
        keep = y_test >= 0
        truth.append(y_test[keep])
        predicted.append(model.predict(f_test[keep]))
    return class_weighted_error(np.concatenate(truth), np.concatenate(predicted),
                                TABLE_6_7_WINDOWS)


def loose_cooperation(seed: int) -> tuple[float, float]:
    """Fig. 6.11 setting over :data:`LOOSE_NETWORKS` random networks of bench seed ``seed``.

    Returns the share of nodes SELA localizes alone (all networks) and the share of connected
    networks that end fully localized with the planner. When none of the networks is
    connected, the study is doubled (up to eight times) until one is; NaN if none ever is.
    """
    count = LOOSE_NETWORKS
    while True:  # the first networks of a larger study are those of the smaller one
        rows = {r.group: r for r in loose_study(n_networks=count, seed=seed).rows}
        if "connected" in rows or count >= 8 * LOOSE_NETWORKS:
            break
        count *= 2
    connected = rows.get("connected")
    return rows["all"].sela, math.nan if connected is None else connected.complete


def tight_cooperation(seed: int) -> tuple[float, float]:
    """Figs. 6.13-6.16 setting over :data:`TIGHT_NETWORKS` random networks of bench seed ``seed``.

    Returns the share of networks fully localized and the position RMSE after the
    least-squares refinement as a fraction of the radio range ``rho`` (all networks).
    """
    study = tight_study(n_networks=TIGHT_NETWORKS, seed=seed)
    everything = next(r for r in study.rows if r.group == "all")
    return everything.complete, everything.rmse_refined_over_rho
