"""Which detected steps belong to a walk: weak starts and closing steps (issue 19).

Our design, measured on the Mobilise-D lab walks (lower back, ``docs/real-data.md``). A peak
detector on the vertical acceleration also fires on two kinds of events that are not steps of
the reference systems:

* a shift of weight while standing: one or two weak peaks (0.5-0.65 m/s^2, just above the
  absolute threshold) with no walk around them;
* the closing movement after the last step of a walk (the trailing foot set beside the
  other): a peak on the walking rhythm with about half the walk's peaks. On the development
  recording HA/001 (``benchmarks/closing_steps.py``) the last step the INDIP reference counts
  peaks at 0.70-1.08 times the walk's level where the walk ends standing, the uncounted
  closing movement after it at 0.28-0.49 (one at 0.86 that Stereophoto counts as a contact);
  its timing (0.9-1.3 step periods), vertical and antero-posterior peak-to-peak overlap those
  of the last steps, so the peak share is the rule's only feature.

Steps are chained into walks while consecutive steps are at most ``max_gap_s`` apart. A walk
is *confirmed* by a peak of at least ``strong_peak_m_s2`` or by ``min_walk_steps`` steps;
the steps of an unconfirmed walk are held and dropped when the walk ends unconfirmed. In a
confirmed walk a step whose peak is under ``closing_ratio`` times the walk's level (median
peak of its last ``level_steps`` kept steps) is held until a step at or above that share
follows within ``max_gap_s`` (then all held steps are released: slow or turning steps inside
a walk). It is dropped when no step follows within ``closing_pause_s`` (the person stands)
and kept when the next step comes later than ``max_gap_s`` but within ``closing_pause_s``
(a pause inside a walk: the Mobilise-D walking-bout definition merges strides up to 3 s
apart). With ``closing_ratio`` 0 only the first rule acts.

Causal: a held step is decided by a later step, or dropped once the step detector has
reported every step up to ``max_gap_s`` (a confirmed walk's weak step: ``closing_pause_s``)
after the walk's last step; nothing later is used. The gait analyzer holds its steps until
they are decided (:func:`hrtls.gait.step_release.release_steps`). The per-step logic runs at
the step rate (Python); the state is the recent steps' decisions and the current walk's level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, check_positive, decisions_from_dict
from hrtls.gait.chains import chain_starts

__all__ = ["DROP", "KEEP", "UNDECIDED", "WalkStepParams", "WalkStepState", "add_steps",
           "forget_before", "step_status", "walk_steps"]

UNDECIDED = -1
DROP = 0
KEEP = 1


@dataclass(frozen=True, kw_only=True, slots=True)
class WalkStepParams:
    """When a detected step belongs to a walk.

    Attributes
    ----------
    max_gap_s: largest time between consecutive steps of one walk, s.
    strong_peak_m_s2: a peak at least this high confirms a walk, m/s^2.
    min_walk_steps: this many steps confirm a walk without a strong peak.
    closing_ratio: a confirmed walk's step with a peak under this share of the walk's level is
        held until a stronger step follows (0 disables).
    level_steps: the walk's level is the median peak of this many last kept steps.
    closing_pause_s: a held weak step of a confirmed walk is dropped when no step follows
        within this time, s (at least ``max_gap_s``).
    """

    max_gap_s: float = 2.0
    strong_peak_m_s2: float = 0.8
    min_walk_steps: int = 3
    closing_ratio: float = 0.6
    level_steps: int = 4
    closing_pause_s: float = 3.0

    def __post_init__(self) -> None:
        """Validate."""
        check_positive(self.max_gap_s, "max_gap_s")
        check_positive(self.strong_peak_m_s2, "strong_peak_m_s2")
        for name in ("min_walk_steps", "level_steps"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 1):
                raise InputError(f"{name} = {v!r}", where="WalkStepParams",
                                 expected="an integer >= 1")
        if not (math.isfinite(self.closing_ratio) and 0.0 <= self.closing_ratio < 1.0):
            raise InputError(f"closing_ratio = {self.closing_ratio}", where="WalkStepParams",
                             expected="0 <= closing_ratio < 1")
        if not (math.isfinite(self.closing_pause_s) and self.closing_pause_s >= self.max_gap_s):
            raise InputError(f"closing_pause_s = {self.closing_pause_s}", where="WalkStepParams",
                             expected="a finite value >= max_gap_s")


@dataclass
class WalkStepState:
    """Decisions of the recent steps and the current walk (JSON-able with ``to_dict``).

    Attributes
    ----------
    t: end times of the steps added and not yet forgotten, s (increasing).
    status: ``UNDECIDED`` (-1), ``DROP`` (0) or ``KEEP`` (1) per step.
    t_last: end of the last step added, s (-inf: none).
    n_steps: steps of the current walk so far.
    confirmed: whether the current walk is confirmed.
    level: peaks of the current walk's last kept steps, m/s^2.
    """

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    status: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    t_last: float = -math.inf
    n_steps: int = 0
    confirmed: bool = False
    level: FloatArray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (``t_last`` -inf written as None)."""
        return {"t": self.t.tolist(), "status": self.status.tolist(),
                "t_last": self.t_last if math.isfinite(self.t_last) else None,
                "n_steps": self.n_steps, "confirmed": self.confirmed,
                "level": self.level.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> WalkStepState:
        """Inverse of :meth:`to_dict`."""
        t, st = decisions_from_dict(data, where="WalkStepState")
        try:
            tl = data["t_last"]
            return cls(t, st, -math.inf if tl is None else float(tl), int(data["n_steps"]),
                       bool(data["confirmed"]), np.asarray(data["level"], dtype=np.float64))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed state ({exc!r})", where="WalkStepState",
                             expected="a dict written by to_dict()") from None


def add_steps(state: WalkStepState, params: WalkStepParams, t_end: FloatArray,
              acc_max_m_s2: FloatArray, *, complete_s: float = -math.inf) -> None:
    """Add the steps ending after ``state.t_last`` (others are known) and decide what is certain.

    ``t_end``: step end times, s (increasing); ``acc_max_m_s2``: their peaks; ``complete_s``:
    every step ending before this time is among them (inf: the end of the recording).
    """
    p = params
    s = state
    new = np.flatnonzero(np.asarray(t_end) > s.t_last)
    status = s.status.tolist()
    times = s.t.tolist()
    level = s.level.tolist()
    held = [i for i, v in enumerate(status) if v == UNDECIDED]
    t_new = np.asarray(t_end, dtype=np.float64)[new]
    starts = chain_starts(t_new, max_gap_s=p.max_gap_s, t_before_s=s.t_last).tolist()
    for te, peak, start in zip(t_new.tolist(), np.asarray(acc_max_m_s2)[new].tolist(), starts,
                               strict=True):
        if start:   # a new walk: the held steps of a confirmed walk stay after a short pause
            dec = KEEP if s.confirmed and te - s.t_last <= p.closing_pause_s else DROP
            for i in held:
                status[i] = dec
            held, level, s.n_steps, s.confirmed = [], [], 0, False
        s.t_last = te
        s.n_steps += 1
        held.append(len(status))
        times.append(te)
        status.append(UNDECIDED)
        if s.confirmed:   # a step at the walk's level releases the held weak steps
            confirms = peak >= p.closing_ratio * float(np.median(level))
        else:
            confirms = peak >= p.strong_peak_m_s2 or s.n_steps >= p.min_walk_steps
        if confirms:
            s.confirmed = True
            level = [*level, peak][-p.level_steps:]
            for i in held:
                status[i] = KEEP
            held = []
        elif not s.confirmed:
            level.append(peak)
    wait_s = p.closing_pause_s if s.confirmed else p.max_gap_s
    if complete_s > s.t_last + wait_s:   # no later step can join the walk or keep its steps
        for i in held:
            status[i] = DROP
    s.t = np.asarray(times, dtype=np.float64)
    s.status = np.asarray(status, dtype=np.int64)
    s.level = np.asarray(level, dtype=np.float64)


def step_status(state: WalkStepState, t_end: FloatArray) -> NDArray[np.int64]:
    """Decision of each of these (added) steps; unknown times count as undecided."""
    q = np.asarray(t_end, dtype=np.float64).reshape(-1)
    out = np.full(q.shape, UNDECIDED, dtype=np.int64)
    if state.t.size == 0 or q.size == 0:
        return out
    k = np.clip(np.searchsorted(state.t, q), 0, state.t.size - 1)
    hit = state.t[k] == q
    out[hit] = state.status[k[hit]]
    return out


def forget_before(state: WalkStepState, t_s: float) -> None:
    """Forget the decisions of steps ending before ``t_s`` (released or dropped)."""
    keep = state.t >= t_s
    state.t, state.status = state.t[keep], state.status[keep]


def walk_steps(t_end: FloatArray, acc_max_m_s2: FloatArray,
               params: WalkStepParams | None = None) -> NDArray[np.bool_]:
    """Offline: whether each step (end times increasing) is kept."""
    st = WalkStepState()
    add_steps(st, params or WalkStepParams(), t_end, acc_max_m_s2, complete_s=math.inf)
    return st.status == KEEP
