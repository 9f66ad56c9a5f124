"""The gait analyzer's activity windows: the axes of their features, features and labels.

:func:`feature_axes` gives the anteroposterior, mediolateral and vertical acceleration the
window features are computed on (Inderst Sec. 4.1), :func:`windows_features` the features
with the classifier's settings, and :func:`classify_windows` labels windows by the configured
classifier, the walking bouts or the motion state at their ends.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity
from hrtls.frames import GRAVITY_M_S2, quat_to_matrix
from hrtls.gait._state import FloatArray
from hrtls.gait.activity_lda import LdaModel
from hrtls.gait.activity_tree import TreeThresholds, classify_tree
from hrtls.gait.features import DFT_ZERO_PAD, WindowFeatures, window_features
from hrtls.gait.motion_detector import MotionParams
from hrtls.gait.vertical import LevelledAcceleration

__all__ = ["classify_windows", "feature_axes", "windows_features"]

IntArray = NDArray[np.int64]


def feature_axes(acc: FloatArray, lev: LevelledAcceleration, psi_held: FloatArray, *,
                 q_bd: FloatArray | None) -> FloatArray:
    """AP, ML and vertical (plus g) acceleration of the samples (N, 3), not yet low-passed.

    AP/ML axes: the mounting ``q_bd`` when known, else the levelled horizontal acceleration
    turned into the held walking direction ``psi_held`` (raw levelled axes until a heading
    exists).
    """
    if q_bd is not None:
        body = acc @ quat_to_matrix(q_bd).T
        ap, ml = body[:, 0], body[:, 1]
    else:
        known = np.isfinite(psi_held)
        c = np.where(known, np.cos(psi_held), 1.0)
        sn = np.where(known, np.sin(psi_held), 0.0)
        hx, hy = lev.horizontal_m_s2[:, 0], lev.horizontal_m_s2[:, 1]
        ap, ml = c * hx + sn * hy, -sn * hx + c * hy
    out: FloatArray = np.column_stack([ap, ml, lev.vertical_m_s2 + GRAVITY_M_S2])
    return out


def windows_features(act_t: FloatArray, acc: FloatArray, *, window_samples: int,
                     activity: LdaModel | TreeThresholds | None,
                     compute: bool) -> WindowFeatures:
    """Activity features of whole windows (Inderst Sec. 4.1) with the classifier's settings.

    ``compute`` False: only the window times (NaN features), for motion-based labels.
    """
    j = window_samples
    if not compute:
        nw = act_t.shape[0] // j
        starts = act_t[np.arange(nw) * j]
        ends = act_t[np.arange(1, nw + 1) * j - 1]
        return WindowFeatures(starts, ends, np.full((nw, 3), np.nan), np.full((nw, 7), np.nan))
    return window_features(act_t, acc, window_samples=j,
                           anthropometric_nr=(activity.anthropometric_nr
                                              if isinstance(activity, TreeThresholds) else 1.0),
                           dft_zero_pad=(activity.dft_zero_pad if isinstance(activity, LdaModel)
                                         else DFT_ZERO_PAD))


def classify_windows(feats_tree: FloatArray, feats_lda: FloatArray, sigma_end: FloatArray,
                     state_end: IntArray, walk_share: FloatArray | None, *,
                     activity: LdaModel | TreeThresholds | None, motion: MotionParams,
                     combined_state: bool) -> IntArray:
    """Activity code of each window.

    With ``walk_share`` (fraction of the window in a walking bout): walking above one half,
    running where the motion state at the window end says so. Else the classifier
    ``activity``, or without one the motion state at the window end: the combined state
    (``combined_state``, periodicity test on) or Basso's spread ``sigma_end`` thresholds.
    """
    if walk_share is not None:
        # walking bouts (module walking_bouts); running from the combined motion state
        run = state_end == int(Activity.RUNNING) if combined_state else (
            sigma_end > motion.run_threshold_m_s2)
        return np.where(walk_share > 0.5, np.where(run, int(Activity.RUNNING),
                                                   int(Activity.WALKING)),
                        int(Activity.STANDING)).astype(np.int64)
    if isinstance(activity, LdaModel):
        return activity.predict(feats_lda)
    if isinstance(activity, TreeThresholds):
        return classify_tree(feats_tree, activity)
    if combined_state:
        # combined motion state at the window end (0/1/2 are STANDING/WALKING/RUNNING)
        return np.where(state_end < 0, int(Activity.STANDING), state_end).astype(np.int64)
    return np.where(sigma_end > motion.run_threshold_m_s2, int(Activity.RUNNING),
                    np.where(sigma_end > motion.still_threshold_m_s2,
                             int(Activity.WALKING), int(Activity.STANDING))).astype(np.int64)
