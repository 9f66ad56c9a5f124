"""What :class:`~hrtls.gait.analyzer.GaitAnalyzer` produces: steps, activity, velocity, features."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hrtls.data import StepEvents
from hrtls.gait._state import FloatArray
from hrtls.gait.features import WindowFeatures

__all__ = ["GaitResult"]

IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True, eq=False)
class GaitResult:
    """What one call of the analyzer produced.

    Attributes
    ----------
    steps: step table (t_start, t_end, length, heading, dz, activity, frequency, extremes).
    activity_t, activity: per-sample activity codes of the samples classified in this call.
    velocity_t, velocity_m_s: per-sample walking velocity (Colombo automaton; empty when off).
    motion_sigma_m_s2: per-sample 2 s std of vertical acceleration (Basso II-B) of this chunk.
    heading_frame: ``"enu"`` (orientation given) or ``"levelled"`` (relative to the device,
        accelerometer-only).
    features: activity features of the windows completed in this call (Inderst Sec. 4.1).
    step_excursion_m: vertical excursion of the pelvis during each step of ``steps``, m
        (:mod:`hrtls.gait.step_length_pendulum`).
    """

    steps: StepEvents
    activity_t: FloatArray
    activity: IntArray
    velocity_t: FloatArray
    velocity_m_s: FloatArray
    motion_sigma_m_s2: FloatArray
    heading_frame: str
    features: WindowFeatures = field(default_factory=lambda: WindowFeatures(
        np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 7))))
    step_excursion_m: FloatArray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def concat(cls, parts: list[GaitResult]) -> GaitResult:
        """Join the results of consecutive calls."""
        if not parts:
            return cls(StepEvents.empty(), np.zeros(0), np.zeros(0, dtype=np.int64),
                       np.zeros(0), np.zeros(0), np.zeros(0), "levelled")
        cols = ("t_start", "t_end", "length_m", "heading_rad", "dz_m", "activity",
                "frequency_hz", "acc_max", "acc_min")
        steps = StepEvents(*(np.concatenate([getattr(p.steps, c) for p in parts]) for c in cols))
        feats = WindowFeatures(*(np.concatenate([getattr(p.features, c) for p in parts])
                                 for c in ("t_start", "t_end", "tree", "lda")))
        return cls(steps,
                   np.concatenate([p.activity_t for p in parts]),
                   np.concatenate([p.activity for p in parts]),
                   np.concatenate([p.velocity_t for p in parts]),
                   np.concatenate([p.velocity_m_s for p in parts]),
                   np.concatenate([p.motion_sigma_m_s2 for p in parts]),
                   parts[-1].heading_frame, feats,
                   np.concatenate([p.step_excursion_m for p in parts]))

