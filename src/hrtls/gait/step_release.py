"""Which held steps of the gait analyzer become final, with their activity and length.

A step is held until the activity of the window containing its end is known; with the step
gate until ``gate_lookahead_s`` after its end (it is kept only when some sample of
``[t_end, t_end + gate_lookahead_s]`` is moving), and with walking bouts until its bout is
decided (it is kept only inside a bout); with the walk filter until its walk decision is known
(:mod:`hrtls.gait.walk_steps`: kept only in a confirmed walk, not as a closing step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hrtls.data import Activity, StepEvents
from hrtls.frames import wrap_angle
from hrtls.gait._state import FloatArray
from hrtls.gait.analyzer_state import PendingGait
from hrtls.gait.pll import StepDetection
from hrtls.gait.stairs_climb import ClimbParams, climb_labels
from hrtls.gait.step_heading import HEADING_HOLD_DELAY_S
from hrtls.gait.step_length import StairsModel, StepModel, displacements
from hrtls.gait.walk_steps import (
    KEEP,
    UNDECIDED,
    WalkStepParams,
    add_steps,
    forget_before,
    step_status,
)
from hrtls.gait.walking_bouts import WalkingBoutDetector

__all__ = ["HeadingOffset", "release_steps"]


@dataclass(frozen=True, slots=True)
class HeadingOffset:
    """A heading offset that becomes known at a time (``known_at_s``, data time).

    It is added to the headings of the steps that end at most ``wait_s`` before it (NaN to the
    others); those steps are held until it is known or ``wait_s + HEADING_HOLD_DELAY_S`` after
    their end (by then a step that sets it is reported), so that chunks and one call release
    the same headings.
    """

    offset_rad: float
    known_at_s: float
    wait_s: float

    def per_step(self, t_end: FloatArray) -> FloatArray:
        """The offset of each step (NaN where it does not apply)."""
        ok = np.isfinite(self.offset_rad) & (self.known_at_s <= t_end + self.wait_s)
        return np.where(ok, self.offset_rad, np.nan)


def release_steps(pend: PendingGait, *, final: bool, t_last: float,
                  gate_lookahead_s: float | None, bouts: WalkingBoutDetector | None,
                  step_model: StepModel, stairs: StairsModel, keep_s: float,
                  climb: ClimbParams | None = None, offset: HeadingOffset | None = None,
                  walk: WalkStepParams | None = None, complete_s: float = -np.inf
                  ) -> tuple[StepEvents, FloatArray]:
    """The steps of ``pend`` that are final (all when ``final``) and their excursions.

    ``gate_lookahead_s`` None: no step gate; ``climb``: label the walking steps that climb
    (:mod:`hrtls.gait.stairs_climb`); ``offset``: added to the held headings (see
    :class:`HeadingOffset`); ``walk``: keep only the steps of confirmed walks
    (:mod:`hrtls.gait.walk_steps`, state in ``pend.walk``; ``complete_s``: the step detector
    has reported every step ending before this time). The released steps leave ``pend``, and
    so do the windows and the gate's motion history (older than ``keep_s`` before ``t_last``)
    that the steps still held no longer need.
    """
    det = StepDetection.concat(pend.steps)
    raw = np.concatenate(pend.headings) if pend.headings else np.zeros(0)
    head = raw
    exc = np.concatenate(pend.excursions) if pend.excursions else np.zeros(0)
    dh = np.concatenate(pend.climbs) if pend.climbs else np.zeros(0)
    ends = np.asarray(pend.win_end)
    labels = np.asarray(pend.win_label, dtype=np.int64)
    if final:
        ready = np.ones(len(det), dtype=bool)
    else:
        ready = det.t_end <= (ends[-1] if ends.size else -np.inf)
        if gate_lookahead_s is not None:
            ready &= det.t_end + gate_lookahead_s <= t_last
    if bouts is not None and not final:
        ready &= bouts.decided(det.t_end)
    if walk is not None:
        add_steps(pend.walk, walk, det.t_end, det.acc_max,
                  complete_s=np.inf if final else complete_s)
        kept = step_status(pend.walk, det.t_end)
        ready &= kept != UNDECIDED
    if offset is not None:
        off = offset.per_step(det.t_end)
        head = wrap_angle(raw + off)
        if not final:
            ready &= np.isfinite(off) | (det.t_end + offset.wait_s + HEADING_HOLD_DELAY_S
                                         <= t_last)
    sel = np.flatnonzero(ready)
    rest = np.flatnonzero(~ready)
    if gate_lookahead_s is not None:
        sel = _gate(pend, sel, rest, det.t_end, lookahead_s=gate_lookahead_s,
                    first_needed=t_last - keep_s)
    if bouts is not None:
        sel = sel[bouts.in_bout(det.t_end[sel])]
    if walk is not None:
        sel = sel[kept[sel] == KEEP]
        forget_before(pend.walk, float(det.t_end[rest[0]]) if rest.size else np.inf)
    act = _step_activity(det.t_end[sel], ends, labels, pend.last_label)
    released = StepDetection(det.t_start[sel], det.t_end[sel], det.frequency_hz[sel],
                             det.acc_max[sel], det.acc_min[sel])
    act = climb_labels(act, released, dh[sel], pend.climb, climb)
    length, dz = displacements(released, act, step_model, stairs, exc[sel])
    pend.steps = [StepDetection(det.t_start[rest], det.t_end[rest], det.frequency_hz[rest],
                                det.acc_max[rest], det.acc_min[rest])]
    pend.headings = [raw[rest]]
    pend.excursions = [exc[rest]]
    pend.climbs = [dh[rest]]
    # keep only windows that pending steps may still need
    if ends.size > 1:
        keep_from = ends.size - 1
        if rest.size:
            keep_from = min(keep_from, int(np.searchsorted(ends, det.t_end[rest[0]])))
        pend.win_end = ends[keep_from:].tolist()
        pend.win_label = labels[keep_from:].tolist()
    return StepEvents.build(t_start=released.t_start, t_end=released.t_end,
                            length_m=length, heading_rad=head[sel], dz_m=dz, activity=act,
                            frequency_hz=released.frequency_hz, acc_max=released.acc_max,
                            acc_min=released.acc_min), exc[sel]


def _gate(pend: PendingGait, sel: np.ndarray, rest: np.ndarray, t_end: FloatArray, *,
          lookahead_s: float, first_needed: float) -> np.ndarray:
    """The steps of ``sel`` with motion somewhere in ``[t_end, t_end + lookahead_s]``.

    Trims the motion history to what held steps and steps still to be reported (their ends
    may lie a little before the current sample) may need.
    """
    cs = np.concatenate([[0], np.cumsum(pend.mv)])
    i0 = np.searchsorted(pend.mt, t_end[sel], side="left")
    i1 = np.searchsorted(pend.mt, t_end[sel] + lookahead_s, side="right")
    kept = sel[cs[i1] - cs[i0] > 0]
    if rest.size:
        first_needed = min(first_needed, float(t_end[rest[0]]))
    keep_m = pend.mt >= first_needed - 1e-9
    pend.mt = pend.mt[keep_m]
    pend.mv = pend.mv[keep_m]
    return kept


def _step_activity(t_end: FloatArray, ends: FloatArray, labels: np.ndarray,
                   last_label: int) -> np.ndarray:
    """Activity of the window containing each step end (walking where none is known)."""
    w = np.searchsorted(ends, t_end, side="left")
    act = np.where(w < labels.size, labels[np.clip(w, 0, max(labels.size - 1, 0))]
                   if labels.size else int(Activity.UNKNOWN),
                   last_label).astype(np.int64)
    if act.size and labels.size == 0:
        act[:] = int(Activity.WALKING)
    return np.where(act == int(Activity.UNKNOWN), int(Activity.WALKING), act)
