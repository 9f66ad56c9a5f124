"""Walking bouts from step sequences: which steps belong to walking, and when one walks.

A gait-sequence detector on top of a step detector, in the spirit of the bout rules used for
lower-back sensors (Mobilise-D: a walking bout is a run of consecutive steps with short breaks):
detected steps (their end times, i.e. the initial contacts) are chained while consecutive steps
are at most ``max_gap_s`` apart; a chain of at least ``min_steps`` steps is a *walking bout*.
Isolated step-like events (sitting down, shuffling, reaching) form short chains and are rejected.
A sample at time ``tau`` is *walking* when it lies between two consecutive steps of a bout, or
within ``margin_before_s`` before / ``margin_after_s`` after a step of a bout.

Our design (no paper gives these rules for this use). Streaming: the detector is told, with
every batch of new steps, the time ``complete_s`` before which the step detector has reported
*all* its steps (the step detector knows it: e.g. no peak pending). Decisions are made only when
they are certain from the steps known so far, so chunked and whole-recording runs give the same
result:

* a step is *in a bout* as soon as its chain holds ``min_steps`` steps (or a step already in a
  bout); it is *not* once the chain is closed (``complete_s > last + max_gap_s``) with fewer
  steps. The decision comes at most ``(min_steps - 1) * max_gap_s`` after the step;
* the walking state of time ``tau`` is final for ``tau < min(complete_s - max(max_gap_s,
  margin_before_s), t_undecided - margin_before_s)`` where ``t_undecided`` is the earliest step
  not decided yet (:attr:`WalkingBoutDetector.final_until_s`).

Per-step logic runs at the step rate (Python); per-sample states are vectorized.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_vector, check_positive, decisions_from_dict
from hrtls.gait.chains import chain_runs

BoolArray = NDArray[np.bool_]
UNDECIDED = -1
NOT_IN_BOUT = 0
IN_BOUT = 1


@dataclass(frozen=True, kw_only=True, slots=True)
class WalkingBoutParams:
    """Rules of the step-sequence walking-bout detector.

    Attributes
    ----------
    max_gap_s: largest time between consecutive steps of one bout, s (slow walkers and
        turns reach 1.5-2 s per step).
    min_steps: fewest steps of a walking bout (3: a stride and a half).
    margin_before_s: walking starts this long before the first step of a bout, s.
    margin_after_s: walking lasts this long after the last step of a bout, s.
    """

    max_gap_s: float = 2.0
    min_steps: int = 3
    margin_before_s: float = 0.0
    margin_after_s: float = 0.0

    def __post_init__(self) -> None:
        """Validate."""
        check_positive(self.max_gap_s, "max_gap_s")
        if not (isinstance(self.min_steps, int) and self.min_steps >= 1):
            raise InputError(f"min_steps = {self.min_steps!r}", where="WalkingBoutParams",
                             expected="an integer >= 1")
        for name in ("margin_before_s", "margin_after_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise InputError(f"{name} = {v}", where="WalkingBoutParams",
                                 expected="a finite value >= 0 (s)")

    @property
    def max_delay_s(self) -> float:
        """Longest time from a step (or a sample) to its final decision, s (plus detection)."""
        return self.margin_before_s + max(self.min_steps - 1, 1) * self.max_gap_s


@dataclass
class WalkingBoutState:
    """Recent steps and their decisions (JSON-able with ``to_dict``).

    Attributes
    ----------
    t: end times of the recent steps, s (increasing).
    status: ``UNDECIDED`` (-1), ``NOT_IN_BOUT`` (0) or ``IN_BOUT`` (1) per step.
    complete_s: all steps before this time are known, s.
    """

    t: FloatArray = field(default_factory=lambda: np.zeros(0))
    status: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    complete_s: float = -math.inf

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (``complete_s``: -inf written as None, +inf as "inf")."""
        c = self.complete_s
        return {"t": self.t.tolist(), "status": self.status.tolist(),
                "complete_s": c if math.isfinite(c) else ("inf" if c > 0 else None)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> WalkingBoutState:
        """Inverse of :meth:`to_dict`."""
        t, st = decisions_from_dict(data, where="WalkingBoutState")
        try:
            c = data["complete_s"]
        except (KeyError, TypeError) as exc:
            raise InputError(f"malformed state ({exc!r})", where="WalkingBoutState",
                             expected="a dict written by to_dict()") from None
        return cls(t, st, -math.inf if c is None else float(c))  # float("inf") reads "inf"


def decide_chains(t: FloatArray, status: NDArray[np.int64], complete_s: float, *,
                  max_gap_s: float, min_steps: int) -> NDArray[np.int64]:
    """Decide the undecided steps of ``t`` (sorted) that are certain; returns the new status.

    Chains are runs with consecutive gaps ``<= max_gap_s``. A chain with ``min_steps`` steps
    or one step already in a bout is a bout; a chain whose last step is more than
    ``max_gap_s`` before ``complete_s`` (no later step can join it) is not.
    """
    out = status.copy()
    n = t.shape[0]
    if n == 0:
        return out
    starts, ends = chain_runs(t, max_gap_s=max_gap_s)
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        seg = out[a:b]
        if np.all(seg != UNDECIDED):
            continue
        if b - a >= min_steps or np.any(seg == IN_BOUT):
            out[a:b] = IN_BOUT
        elif complete_s > t[b - 1] + max_gap_s:
            out[a:b] = NOT_IN_BOUT
    return out


def walking_mask(tau: FloatArray, t: FloatArray, status: NDArray[np.int64], *,
                 max_gap_s: float, margin_before_s: float, margin_after_s: float) -> BoolArray:
    """Walking flag of the times ``tau`` from steps ``t`` (sorted) and their bout status.

    Walking between consecutive bout steps at most ``max_gap_s`` apart and within the margins
    around every bout step.
    """
    tau = np.asarray(tau, dtype=np.float64)
    yes = t[status == IN_BOUT]
    if yes.size == 0 or tau.size == 0:
        return np.zeros(tau.shape, dtype=bool)
    lo = [yes - margin_before_s]
    hi = [yes + margin_after_s]
    if yes.size > 1:
        pair = np.diff(yes) <= max_gap_s
        lo.append(yes[:-1][pair])
        hi.append(yes[1:][pair])
    lo_a = np.concatenate(lo)
    hi_a = np.concatenate(hi)
    order = np.argsort(lo_a, kind="stable")
    lo_a = lo_a[order]
    hi_a = np.maximum.accumulate(hi_a[order])
    # tau is covered when the interval with the last start <= tau reaches tau (hi is the
    # running maximum of the ends, so overlapping intervals merge)
    k = np.searchsorted(lo_a, tau, side="right") - 1
    return (k >= 0) & (hi_a[np.clip(k, 0, None)] >= tau)


class WalkingBoutDetector:
    """Streaming step-sequence walking-bout detector (see the module notes).

    Use :meth:`add` with the new steps and the completeness time of the step detector, then
    :meth:`decided` / :meth:`in_bout` for steps and :meth:`walking` for samples before
    :attr:`final_until_s`; :meth:`finish` at the end of a recording decides everything.

    Parameters
    ----------
    params: bout rules.
    history_s: :meth:`trim` keeps steps at least this long before :attr:`final_until_s`, s.
    """

    def __init__(self, params: WalkingBoutParams | None = None, *,
                 history_s: float = 10.0) -> None:
        self.params = params or WalkingBoutParams()
        check_positive(history_s, "history_s")
        self.history_s = float(history_s)
        self.reset()

    def reset(self) -> None:
        """No step seen."""
        self.state = WalkingBoutState()

    def to_dict(self) -> dict[str, Any]:
        """The savable state."""
        return self.state.to_dict()

    def from_dict(self, data: dict[str, Any]) -> None:
        """Restore a state written by :meth:`to_dict`."""
        self.state = WalkingBoutState.from_dict(data)

    def add(self, step_t: FloatArray, complete_s: float) -> None:
        """New step end times (after the known ones) and the new completeness time, s."""
        s = self.state
        new = as_vector(step_t, where="walking-bout step times")
        if new.size and (np.any(np.diff(new) < 0) or (s.t.size and new[0] < s.t[-1])):
            raise InputError("step times out of order", where="walking-bout step times",
                             expected="increasing times after the steps already added")
        if math.isnan(complete_s):
            raise InputError("complete_s is NaN", where="complete_s", expected="a time, s")
        t = np.concatenate([s.t, new])
        status = np.concatenate([s.status, np.full(new.shape[0], UNDECIDED, dtype=np.int64)])
        c = max(s.complete_s, float(complete_s))
        status = decide_chains(t, status, c, max_gap_s=self.params.max_gap_s,
                               min_steps=self.params.min_steps)
        s.t, s.status, s.complete_s = t, status, c

    def trim(self, keep_from_s: float) -> None:
        """Forget steps before ``keep_from_s`` that no decision or walking state needs.

        Steps within ``history_s`` before :attr:`final_until_s` are always kept; call with
        the earliest step whose decision has not been read yet (or -inf).
        """
        p = self.params
        s = self.state
        keep_from = min(keep_from_s, self.final_until_s - max(
            p.max_gap_s, p.margin_before_s, p.margin_after_s, self.history_s))
        keep = s.t >= keep_from
        if s.t.size and not keep[-1]:
            keep[-1] = True  # the last step carries its chain's decision
        if not np.all(keep):
            s.t, s.status = s.t[keep], s.status[keep]

    def finish(self) -> None:
        """End of the recording: every chain is closed."""
        self.add(np.zeros(0), math.inf)

    @property
    def final_until_s(self) -> float:
        """Walking states of times before this are final, s."""
        p = self.params
        s = self.state
        lim = s.complete_s - max(p.max_gap_s, p.margin_before_s)
        und = s.t[s.status == UNDECIDED]
        if und.size:
            lim = min(lim, float(und[0]) - p.margin_before_s)
        return lim

    def decided(self, step_t: FloatArray) -> BoolArray:
        """Whether each of these (added) steps is decided; unknown times count as undecided."""
        return self._lookup(step_t) != UNDECIDED

    def in_bout(self, step_t: FloatArray) -> BoolArray:
        """Whether each of these (added, decided) steps belongs to a walking bout."""
        return self._lookup(step_t) == IN_BOUT

    def _lookup(self, step_t: FloatArray) -> NDArray[np.int64]:
        q = np.asarray(step_t, dtype=np.float64).reshape(-1)
        s = self.state
        out = np.full(q.shape, UNDECIDED, dtype=np.int64)
        if s.t.size == 0 or q.size == 0:
            return out
        k = np.clip(np.searchsorted(s.t, q), 0, s.t.size - 1)
        hit = s.t[k] == q
        out[hit] = s.status[k[hit]]
        return out

    def walking(self, tau: FloatArray) -> BoolArray:
        """Walking flag of times ``tau`` (final for ``tau < final_until_s``)."""
        p = self.params
        s = self.state
        return walking_mask(tau, s.t, s.status, max_gap_s=p.max_gap_s,
                            margin_before_s=p.margin_before_s, margin_after_s=p.margin_after_s)


def walking_bouts(step_t: FloatArray, params: WalkingBoutParams | None = None
                  ) -> tuple[BoolArray, FloatArray]:
    """Offline: in-bout flag per step and the bouts ``(start, end)`` rows (first/last step)."""
    p = params or WalkingBoutParams()
    t = np.sort(as_vector(step_t, where="step times"))
    st = decide_chains(t, np.full(t.shape[0], UNDECIDED, dtype=np.int64), math.inf,
                       max_gap_s=p.max_gap_s, min_steps=p.min_steps)
    yes = st == IN_BOUT
    if not yes.any():
        return yes, np.zeros((0, 2))
    ty = t[yes]
    starts, ends = chain_runs(ty, max_gap_s=p.max_gap_s)
    return yes, np.column_stack([ty[starts], ty[ends - 1]])


__all__ = ["IN_BOUT", "NOT_IN_BOUT", "UNDECIDED", "WalkingBoutDetector", "WalkingBoutParams",
           "WalkingBoutState", "decide_chains", "walking_bouts", "walking_mask"]
