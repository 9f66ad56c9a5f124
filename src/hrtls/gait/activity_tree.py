"""Activity recognition by a decision tree (Inderst Sec. 4.1.1, Fig. 4.1).

Three tests on the features of a window (:func:`hrtls.gait.features.window_features`):

1. vertical variance ``sigma_w^2 <= d1`` -> standing still;
2. vertical dynamics index ``i_w`` (eq. 4.3-4.5) against ``d2`` -> walking or stairs;
3. medio-lateral amplitude ``alpha_w`` against ``d3`` -> upstairs (below) or downstairs (above),
   since the lateral shift of the pelvis is larger going down (Inderst Sec. 4.1.1).

Fig. 4.1 is not legible in our copy, so the side of ``d2`` on which stairs lie is a parameter
(``stairs_above_d2``) set by :func:`calibrate_tree` from labelled walks. We add an optional
running leaf (Basso Sec. II-B): vertical variance above ``run_variance_m2_s4`` (default
``5^2``, Basso's 5 m/s^2 threshold on the standard deviation) -> running.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hrtls.data import Activity
from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_matrix

IntArray = NDArray[np.int64]


@dataclass(frozen=True, kw_only=True, slots=True)
class TreeThresholds:
    """Per-user thresholds of the decision tree.

    Attributes
    ----------
    d1_variance_m2_s4: vertical variance separating standing from moving, (m/s^2)^2.
    d2_dynamics_m_s2: vertical dynamics index separating walking from stairs, m/s^2.
    d3_ml_amplitude_m_s2: medio-lateral amplitude separating upstairs from downstairs, m/s^2.
    stairs_above_d2: True when stairs have the larger dynamics index.
    run_variance_m2_s4: vertical variance above which the person runs ((m/s^2)^2; inf: off).
    anthropometric_nr: ``n_r`` of eq. 4.3.
    """

    d1_variance_m2_s4: float = 0.5
    d2_dynamics_m_s2: float = 2.5
    d3_ml_amplitude_m_s2: float = 4.0
    stairs_above_d2: bool = True
    run_variance_m2_s4: float = 25.0
    anthropometric_nr: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (infinity written as None)."""
        d = asdict(self)
        d["run_variance_m2_s4"] = (None if not np.isfinite(self.run_variance_m2_s4)
                                   else self.run_variance_m2_s4)
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TreeThresholds:
        """Inverse of :meth:`to_dict`."""
        d = dict(data)
        if d.get("run_variance_m2_s4", 0.0) is None:
            d["run_variance_m2_s4"] = float("inf")
        try:
            return cls(**d)
        except TypeError as exc:
            raise InputError(str(exc), where="tree thresholds",
                             expected="keys of TreeThresholds") from None


def classify_tree(tree_features: FloatArray, thresholds: TreeThresholds) -> IntArray:
    """Activity codes of windows from their (W, 3) tree features (Inderst Fig. 4.1)."""
    f = as_matrix(tree_features, where="tree features", columns=3)
    var, vdi, ml = f[:, 0], f[:, 1], f[:, 2]
    th = thresholds
    stairs = (vdi > th.d2_dynamics_m_s2) if th.stairs_above_d2 else (vdi <= th.d2_dynamics_m_s2)
    out = np.full(f.shape[0], int(Activity.WALKING), dtype=np.int64)
    out[stairs & (ml > th.d3_ml_amplitude_m_s2)] = int(Activity.DOWNSTAIRS)
    out[stairs & (ml <= th.d3_ml_amplitude_m_s2)] = int(Activity.UPSTAIRS)
    out[var > th.run_variance_m2_s4] = int(Activity.RUNNING)
    out[var <= th.d1_variance_m2_s4] = int(Activity.STANDING)
    return out


def best_split(values: FloatArray, positive: NDArray[np.bool_]) -> tuple[float, bool, float]:
    """Threshold maximizing balanced accuracy of ``values > thr`` (or ``<=``) for ``positive``.

    Returns ``(threshold, positive_above, balanced_accuracy)``; the threshold is the midpoint
    between two consecutive sorted values.
    """
    v = np.asarray(values, dtype=np.float64)
    pos = np.asarray(positive, dtype=bool)
    n_pos = int(pos.sum())
    n_neg = int((~pos).sum())
    if n_pos == 0 or n_neg == 0:
        raise InputError("a split needs both classes", where="calibration",
                         expected="labelled windows of each class of the split")
    order = np.argsort(v, kind="stable")
    vs = v[order]
    ps = pos[order]
    # predicting positive above index k (k = 0..n): TP = positives above, TN = negatives below
    pos_below = np.concatenate([[0], np.cumsum(ps)])
    neg_below = np.concatenate([[0], np.cumsum(~ps)])
    tpr_above = (n_pos - pos_below) / n_pos
    tnr_above = neg_below / n_neg
    bacc_above = 0.5 * (tpr_above + tnr_above)
    bacc_below = 1.0 - bacc_above
    cut = np.concatenate([[vs[0] - 1.0], 0.5 * (vs[:-1] + vs[1:]), [vs[-1] + 1.0]])
    # only cut between distinct values
    valid = np.concatenate([[True], vs[1:] > vs[:-1], [True]])
    ka = int(np.argmax(np.where(valid, bacc_above, -1.0)))
    kb = int(np.argmax(np.where(valid, bacc_below, -1.0)))
    if bacc_above[ka] >= bacc_below[kb]:
        return float(cut[ka]), True, float(bacc_above[ka])
    return float(cut[kb]), False, float(bacc_below[kb])


def calibrate_tree(tree_features: FloatArray, labels: ArrayLike, *,
                   anthropometric_nr: float = 1.0) -> TreeThresholds:
    """Set ``d1``-``d3`` (and the running threshold) from labelled windows of one user.

    Each threshold maximizes the balanced accuracy of its own binary decision over the windows
    of the classes that reach it: standing vs the rest (d1), walking vs stairs (d2), upstairs vs
    downstairs (d3), walking vs running. Decisions without labelled examples keep defaults.
    """
    f = as_matrix(tree_features, where="tree features", columns=3)
    y = np.asarray(labels, dtype=np.int64)
    if y.shape != (f.shape[0],):
        raise InputError(f"{y.shape[0]} labels for {f.shape[0]} windows", where="labels",
                         expected="one label per window")
    default = TreeThresholds(anthropometric_nr=anthropometric_nr)
    kw: dict[str, Any] = default.to_dict()
    kw["run_variance_m2_s4"] = default.run_variance_m2_s4
    stand = y == Activity.STANDING
    stairs_m = (y == Activity.UPSTAIRS) | (y == Activity.DOWNSTAIRS)
    walk = y == Activity.WALKING
    run = y == Activity.RUNNING
    if stand.any() and (~stand).any():
        kw["d1_variance_m2_s4"], _, _ = best_split(f[:, 0], ~stand)
    if walk.any() and stairs_m.any():
        m = walk | stairs_m
        kw["d2_dynamics_m_s2"], kw["stairs_above_d2"], _ = best_split(f[m, 1], stairs_m[m])
    up = y == Activity.UPSTAIRS
    down = y == Activity.DOWNSTAIRS
    if up.any() and down.any():
        m = up | down
        kw["d3_ml_amplitude_m_s2"], _, _ = best_split(f[m, 2], down[m])
    if run.any() and (walk | stairs_m).any():
        m = run | walk | stairs_m
        kw["run_variance_m2_s4"], _, _ = best_split(f[m, 0], run[m])
    return TreeThresholds(**kw)
