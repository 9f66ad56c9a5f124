"""A JSON-able accuracy report of one estimated trajectory (see :mod:`hrtls.evaluate.metrics`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Checkpoints, GroundTruth, StepEvents, Trajectory
from hrtls.evaluate.metrics import (
    activity_confusion,
    checkpoint_errors,
    compare_steps,
    cumulative_distance,
    distance_at,
    error_stats,
    heading_errors,
    integral_mean_error,
    position_errors_2d_3d,
    velocity_rmse,
)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class EvaluationInputs:
    """Everything a report can use; all but ``estimate`` optional.

    Attributes
    ----------
    estimate: the estimated trajectory. estimated_steps: its steps.
    truth: continuous ground truth. checkpoints: truth at known points.
    true_steps: true steps. true_activity: (change times, activity codes) step function.
    reference: the paper's numbers to show next to ours.
    """

    estimate: Trajectory
    estimated_steps: StepEvents | None = None
    truth: GroundTruth | None = None
    checkpoints: Checkpoints | None = None
    true_steps: StepEvents | None = None
    true_activity: tuple[FloatArray, NDArray[np.int64]] | None = None
    reference: dict[str, Any] = field(default_factory=dict)


def _clean(x: Any) -> Any:
    """Replace NaN/inf by None and numpy scalars by Python ones (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _cdf_points(errors: FloatArray, n: int = 50) -> dict[str, list[float]]:
    """``n`` points of :func:`~hrtls.evaluate.metrics.error_cdf`, evenly spaced in rank.

    Only the order statistics at those ranks are placed (a partial sort, NaN last as in a sort).
    """
    e = np.asarray(errors, dtype=np.float64).ravel()
    if e.size == 0:
        return {"error_m": [], "fraction": []}
    idx = np.unique(np.linspace(0, e.size - 1, min(n, e.size)).round().astype(int))
    fraction = (idx + 1).astype(np.float64) / e.size
    return {"error_m": np.partition(e, idx)[idx].tolist(), "fraction": fraction.tolist()}


def build_report(inputs: EvaluationInputs) -> dict[str, Any]:
    """Metrics of ``inputs`` as a JSON-able dict (NaN written as null)."""
    est = inputs.estimate
    out: dict[str, Any] = {"estimate": {"samples": len(est), "duration_s": float(
        est.t[-1] - est.t[0]) if len(est) else 0.0, "path_length_m": est.path_length_m}}
    truth = inputs.truth
    if truth is not None:
        total = float(cumulative_distance(truth.xyz)[-1]) if len(truth) else 0.0
        err, zerr = position_errors_2d_3d(est, truth)
        stats = error_stats(err)
        final = float(err[-1]) if err.size else float("nan")
        out["truth"] = {"samples": len(truth), "distance_m": total}
        out["position"] = {
            **stats.to_dict(), "final_m": final,
            "final_fraction_of_distance": final / total if total > 0 else float("nan"),
            "mean_fraction_of_distance": stats.mean / total if total > 0 else float("nan"),
            "cdf": _cdf_points(err),
        }
        out["position_3d"] = error_stats(zerr).to_dict()
        if truth.heading_rad is not None:
            _, herr = heading_errors(est, truth)
            if herr.size:
                out["heading"] = error_stats(herr).to_dict()
        v_rmse, s_rmse = velocity_rmse(est, truth)
        out["velocity"] = {"rmse_m_s": v_rmse, "speed_rmse_m_s": s_rmse}
    cps = inputs.checkpoints
    if cps is not None and len(cps):
        t_c, e_c, lab = checkpoint_errors(est, cps)
        section: dict[str, Any] = {**error_stats(e_c).to_dict(),
                                   "points": [{"t": float(a), "label": str(b), "error_m": float(c)}
                                              for a, b, c in zip(t_c, lab, e_c, strict=True)]}
        if truth is not None and e_c.size:
            s = distance_at(truth, t_c)
            total = float(cumulative_distance(truth.xyz)[-1])
            if total > 0:
                s_all = np.concatenate([[0.0], s]) if s[0] > 1e-6 else s
                e_all = np.concatenate([[0.0], e_c]) if s[0] > 1e-6 else e_c
                if len(s_all) >= 2:
                    ime, frac = integral_mean_error(s_all, e_all, total)
                    section["integral_mean_error_m"] = ime
                    section["integral_mean_error_fraction"] = frac
        out["checkpoints"] = section
    if inputs.estimated_steps is not None and inputs.true_steps is not None:
        out["steps"] = compare_steps(inputs.estimated_steps, inputs.true_steps).to_dict()
    if inputs.true_activity is not None and len(est):
        tt, codes = inputs.true_activity
        if len(tt) and np.any(est.activity >= 0):
            out["activity"] = activity_confusion(tt, codes, est.t, est.activity).to_dict()
    if inputs.reference:
        out["paper_reference"] = inputs.reference
    return dict(_clean(out))
