"""The state :class:`~hrtls.gait.analyzer.GaitAnalyzer` holds between chunks, as plain values.

:class:`PendingGait` is what waits for later samples (held samples and steps, recent vertical
acceleration and yaw, the step gate's motion history, headings not yet in effect);
:func:`encode_nonfinite` and :func:`decode_nonfinite` make a state strict JSON and back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.data import Activity
from hrtls.gait._state import FloatArray
from hrtls.gait.pll import StepDetection
from hrtls.gait.walk_steps import WalkStepState

__all__ = ["STATE_FORMAT", "PendingGait", "decode_nonfinite", "encode_nonfinite"]

IntArray = NDArray[np.int64]


STATE_FORMAT = "hrtls-gait-analyzer-state"
_NONFINITE = {"nan": float("nan"), "inf": float("inf"), "-inf": float("-inf")}


def encode_nonfinite(obj: Any) -> Any:
    """Replace non-finite floats by the strings ``"nan"``, ``"inf"``, ``"-inf"`` (recursive)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, dict):
        return {k: encode_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [encode_nonfinite(v) for v in obj]
    return obj


def decode_nonfinite(obj: Any) -> Any:
    """Inverse of :func:`encode_nonfinite`."""
    if isinstance(obj, str) and obj in _NONFINITE:
        return _NONFINITE[obj]
    if isinstance(obj, dict):
        return {k: decode_nonfinite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [decode_nonfinite(v) for v in obj]
    return obj


@dataclass
class PendingGait:
    """Samples waiting for their activity window and steps waiting for their activity."""

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    acc: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    # combined motion state and Basso spread of the held samples
    ms: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    sg: FloatArray = field(default_factory=lambda: np.zeros(0))
    steps: list[StepDetection] = field(default_factory=list)
    headings: list[FloatArray] = field(default_factory=list)
    excursions: list[FloatArray] = field(default_factory=list)
    # recent vertical acceleration for the step excursions: times and values
    vb_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    vb_a: FloatArray = field(default_factory=lambda: np.zeros(0))
    # relative heights at vb_t, the climb detector's state and the held steps' height changes
    # (hrtls.gait.stairs_climb)
    vb_h: FloatArray = field(default_factory=lambda: np.zeros(0))
    climb: FloatArray = field(default_factory=lambda: np.array(
        [math.nan, 0.0, math.nan, 0.0, 0.0, math.nan, 0.0, 0.0, -math.inf, -math.inf]))
    climbs: list[FloatArray] = field(default_factory=list)
    # recent unwrapped yaw of the body forward axis (heading="yaw"): times and values
    yb_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    yb_y: FloatArray = field(default_factory=lambda: np.zeros(0))
    win_end: list[float] = field(default_factory=list)
    win_label: list[int] = field(default_factory=list)
    last_label: int = int(Activity.UNKNOWN)
    yaw_last: float = float("nan")
    heading_last: float = float("nan")
    # motion history for the step gate: sample times and moving flags (0/1)
    mt: FloatArray = field(default_factory=lambda: np.zeros(0))
    mv: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    # step headings waiting to take effect on the held walking direction: times and values
    hq_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    hq_h: FloatArray = field(default_factory=lambda: np.zeros(0))
    # decisions of the walk filter (hrtls.gait.walk_steps)
    walk: WalkStepState = field(default_factory=WalkStepState)

    def to_dict(self) -> dict[str, Any]:
        """The held samples, steps and memories as plain values (non-finite floats kept)."""
        det = StepDetection.concat(self.steps)
        heads = np.concatenate(self.headings) if self.headings else np.zeros(0)
        return {
            "t": self.t.tolist(), "acc": self.acc.tolist(),
            "ms": self.ms.tolist(), "sg": self.sg.tolist(),
            "steps": np.column_stack([det.t_start, det.t_end, det.frequency_hz,
                                      det.acc_max, det.acc_min]).tolist(),
            "headings": heads.tolist(),
            "excursions": (np.concatenate(self.excursions) if self.excursions
                           else np.zeros(0)).tolist(),
            "vb_t": self.vb_t.tolist(), "vb_a": self.vb_a.tolist(),
            "vb_h": self.vb_h.tolist(), "climb": self.climb.tolist(),
            "climbs": (np.concatenate(self.climbs) if self.climbs else np.zeros(0)).tolist(),
            "yb_t": self.yb_t.tolist(), "yb_y": self.yb_y.tolist(),
            "win_end": list(self.win_end),
            "win_label": [int(v) for v in self.win_label],
            "last_label": int(self.last_label), "yaw_last": self.yaw_last,
            "heading_last": self.heading_last, "mt": self.mt.tolist(),
            "mv": self.mv.tolist(), "hq_t": self.hq_t.tolist(),
            "hq_h": self.hq_h.tolist(), "walk": self.walk.to_dict()}

    @classmethod
    def from_dict(cls, pd: dict[str, Any]) -> PendingGait:
        """Inverse of :meth:`to_dict` (raises KeyError, TypeError or ValueError if malformed)."""
        pend = cls()
        pend.t = np.asarray(pd["t"], dtype=np.float64).reshape(-1)
        pend.acc = np.asarray(pd["acc"], dtype=np.float64).reshape(-1, 3)
        # states written before the held motion state was kept: unknown (-1 / NaN)
        pend.ms = np.asarray(pd.get("ms", [-1] * pend.t.shape[0]),
                             dtype=np.int64).reshape(-1)
        pend.sg = np.asarray(pd.get("sg", [math.nan] * pend.t.shape[0]),
                             dtype=np.float64).reshape(-1)
        pend.steps = [StepDetection.from_rows(np.asarray(pd["steps"], dtype=np.float64))]
        pend.headings = [np.asarray(pd["headings"], dtype=np.float64).reshape(-1)]
        pend.excursions = [np.asarray(pd["excursions"], dtype=np.float64).reshape(-1)]
        pend.vb_t = np.asarray(pd["vb_t"], dtype=np.float64).reshape(-1)
        pend.vb_a = np.asarray(pd["vb_a"], dtype=np.float64).reshape(-1)
        # states written before the climb detector: heights and held steps' climbs unknown
        pend.vb_h = np.asarray(pd.get("vb_h", [math.nan] * pend.vb_t.shape[0]),
                               dtype=np.float64).reshape(-1)
        if "climb" in pd:
            pend.climb = np.asarray(pd["climb"], dtype=np.float64).reshape(10)
        pend.climbs = [np.asarray(pd.get("climbs", [math.nan] * pend.excursions[0].shape[0]),
                                  dtype=np.float64).reshape(-1)]
        pend.yb_t = np.asarray(pd["yb_t"], dtype=np.float64).reshape(-1)
        pend.yb_y = np.asarray(pd["yb_y"], dtype=np.float64).reshape(-1)
        pend.win_end = [float(v) for v in pd["win_end"]]
        pend.win_label = [int(v) for v in pd["win_label"]]
        pend.last_label = int(pd["last_label"])
        pend.yaw_last = float(pd["yaw_last"])
        pend.heading_last = float(pd["heading_last"])
        pend.mt = np.asarray(pd["mt"], dtype=np.float64).reshape(-1)
        pend.mv = np.asarray(pd["mv"], dtype=np.int64).reshape(-1)
        pend.hq_t = np.asarray(pd["hq_t"], dtype=np.float64).reshape(-1)
        pend.hq_h = np.asarray(pd["hq_h"], dtype=np.float64).reshape(-1)
        # states written before the walk filter: its held steps are added again
        if pd.get("walk") is not None:
            pend.walk = WalkStepState.from_dict(pd["walk"])
        return pend
