"""Fill single missed steps in regular walking from the step rhythm.

Walking is periodic: within a walk, consecutive initial contacts are about one step period
``T`` apart. A weak step (a slow or turning step of a lower-back sensor) may stay under the
detector's threshold; the detector then reports a gap of about ``2 T``. This post-processor
(our design, not from the papers) inserts one step in the middle of such a gap.

The local step period is half the last stride, ``T = (t_{i-1} - t_{i-3}) / 2`` (a stride has
a left and a right step, so a left/right asymmetry does not bias ``T``). A step is inserted
before step ``i`` when ``min_ratio * T <= t_i - t_{i-1} <= max_ratio * T``, the gap is at most
``max_gap_s`` and the two intervals of the stride are each at most ``max_gap_s`` (the steps
belong to one walk). The inserted step ends at the middle of the gap, starts at ``t_{i-1}``
and takes the amplitude (``acc_max``, ``acc_min``) of step ``i``; step ``i`` then starts at the
middle. Inserted steps count as reported steps for later periods.

Causal: the decision for a gap needs only the steps up to its end, so the steps come out when
step ``i`` is detected (no extra delay). The state is the last three step end times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, check_positive
from hrtls.gait.pll import StepDetection


@dataclass(frozen=True, kw_only=True, slots=True)
class MissedStepParams:
    """When a gap between two steps holds one missed step.

    Attributes
    ----------
    min_ratio, max_ratio: the gap must be between these multiples of the local step period
        (two periods +- 20 %).
    max_gap_s: largest gap (and stride interval) considered part of a walk, s.
    """

    min_ratio: float = 1.6
    max_ratio: float = 2.4
    max_gap_s: float = 2.0

    def __post_init__(self) -> None:
        """Validate."""
        check_positive(self.min_ratio, "min_ratio")
        check_positive(self.max_gap_s, "max_gap_s")
        if not (self.max_ratio > self.min_ratio and math.isfinite(self.max_ratio)):
            raise InputError(f"ratios {self.min_ratio}-{self.max_ratio}",
                             where="MissedStepParams", expected="min_ratio < max_ratio")


@dataclass
class MissedStepState:
    """End times of the last (up to three) reported steps, s, oldest first."""

    t: FloatArray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values."""
        return {"t": self.t.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MissedStepState:
        """Inverse of :meth:`to_dict`."""
        try:
            t = np.asarray(data["t"], dtype=np.float64).reshape(-1)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed state ({exc!r})", where="MissedStepState",
                             expected="a dict written by to_dict()") from None
        if t.size > 3 or not np.all(np.isfinite(t)):
            raise InputError(f"{t.size} times", where="MissedStepState",
                             expected="at most 3 finite times")
        return cls(t)


class MissedStepFiller:
    """Insert one step into gaps of about two step periods (see the module notes)."""

    def __init__(self, params: MissedStepParams | None = None) -> None:
        self.params = params or MissedStepParams()
        self.reset()

    def reset(self) -> None:
        """No step seen."""
        self.state = MissedStepState()

    def update(self, steps: StepDetection) -> StepDetection:
        """The new steps (in time order, after the earlier ones) with missed steps inserted."""
        p = self.params
        hist = self.state.t.tolist()
        if len(steps) and hist and steps.t_end[0] < hist[-1]:
            raise InputError("steps out of order", where="missed-step filler",
                             expected="steps after the ones already seen")
        rows: list[tuple[float, float, float, float, float]] = []
        for ts, te, f, amax, amin in zip(steps.t_start.tolist(), steps.t_end.tolist(),
                                         steps.frequency_hz.tolist(), steps.acc_max.tolist(),
                                         steps.acc_min.tolist(), strict=True):
            if len(hist) == 3:
                t3, t2, t1 = hist
                period = 0.5 * (t1 - t3)
                gap = te - t1
                if (t1 - t2 <= p.max_gap_s and t2 - t3 <= p.max_gap_s and period > 0.0
                        and gap <= p.max_gap_s
                        and p.min_ratio * period <= gap <= p.max_ratio * period):
                    mid = t1 + 0.5 * gap
                    rows.append((t1, mid, 1.0 / (mid - t1), amax, amin))
                    hist = [t2, t1, mid]
                    ts = mid
                    f = 1.0 / (te - mid)
            rows.append((ts, te, f, amax, amin))
            hist = [*hist, te][-3:]
        self.state.t = np.asarray(hist, dtype=np.float64)
        if not rows:
            return StepDetection.from_rows(np.zeros((0, 5)))
        return StepDetection.from_rows(np.asarray(rows, dtype=np.float64))

    def process(self, steps: StepDetection) -> StepDetection:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(steps)


__all__ = ["MissedStepFiller", "MissedStepParams", "MissedStepState"]
