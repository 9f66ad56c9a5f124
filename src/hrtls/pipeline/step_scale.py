"""Step-length scale learned from absolute corrections on straight stretches (our addition).

Between the last absolute correction (tag or fix) and the next one, the dead-reckoned
displacement is ``prior - anchor``; the corrected displacement projected on it gives the ratio
of the true to the modelled step length. The ratio is used only when no soft correction (RSS,
range) happened in between, the stretch is at least ``min_baseline_m`` long and nearly
straight; the scale moves by the power ``gain`` of the ratio, within its bounds. Walking and
running steps get their own scale (by their share of the stretch).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hrtls.errors import InputError


@dataclass(frozen=True, slots=True)
class StepScaleParams:
    """Parameters of :class:`StepScaleLearner`.

    Attributes
    ----------
    min_baseline_m: shortest straight stretch between two corrections that teaches, m.
    gain: fraction (as a power) of each measured ratio applied to the scale.
    min_scale, max_scale: admissible scale.
    """

    min_baseline_m: float = 8.0
    gain: float = 0.25
    min_scale: float = 0.8
    max_scale: float = 1.25

    def __post_init__(self) -> None:
        for name in ("min_baseline_m", "gain", "min_scale", "max_scale"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0.0):
                raise InputError(f"{v!r}", where=f"StepScaleParams.{name}",
                                 expected="a finite value >= 0")
        if not 0.0 < self.min_scale <= 1.0 <= self.max_scale:
            raise InputError(f"[{self.min_scale}, {self.max_scale}]",
                             where="StepScaleParams.min_scale/max_scale",
                             expected="0 < min_scale <= 1 <= max_scale")


class StepScaleLearner:
    """Running walking / running step-length scales and the stretch since the last anchor."""

    STATE = ("step_scale", "run_scale", "anchor_xy", "path_since_anchor", "run_since_anchor",
             "soft_since_anchor")
    """Attributes that make up the learner's state (snapshot)."""

    def __init__(self, params: StepScaleParams | None = None) -> None:
        self.params = params if params is not None else StepScaleParams()
        self.step_scale = 1.0
        self.run_scale = 1.0
        self.anchor_xy: np.ndarray | None = None
        self.path_since_anchor = 0.0
        self.run_since_anchor = 0.0
        self.soft_since_anchor = False

    def walked(self, path_m: float, running_m: float = 0.0) -> None:
        """Add dead-reckoned path (of which ``running_m`` by running steps), m."""
        self.path_since_anchor += path_m
        self.run_since_anchor += running_m

    def correct(self, prior_xy: np.ndarray, post_xy: np.ndarray, *, learn: bool) -> None:
        """An absolute correction moved the estimate from ``prior_xy`` to ``post_xy``.

        With ``learn`` the scales are updated from the stretch since the previous anchor; in
        every case the correction becomes the new anchor.
        """
        anchor = self.anchor_xy
        prm = self.params
        if learn and anchor is not None and not self.soft_since_anchor:
            d = prior_xy - anchor
            base = float(np.hypot(d[0], d[1]))
            if base >= prm.min_baseline_m and base >= 0.95 * self.path_since_anchor:
                ratio = float((post_xy - anchor) @ d) / (base * base)
                if 0.7 < ratio < 1.4:
                    # per activity: the ratio teaches the scale of the steps that made the
                    # stretch (walking, running, or both when mixed)
                    share_run = self.run_since_anchor / max(self.path_since_anchor, 1e-9)
                    if share_run < 0.8:
                        self.step_scale = float(np.clip(self.step_scale * ratio**prm.gain,
                                                        prm.min_scale, prm.max_scale))
                    if share_run > 0.2:
                        self.run_scale = float(np.clip(self.run_scale * ratio**prm.gain,
                                                       prm.min_scale, prm.max_scale))
        self.anchor_xy = post_xy
        self.path_since_anchor = 0.0
        self.run_since_anchor = 0.0
        self.soft_since_anchor = False
