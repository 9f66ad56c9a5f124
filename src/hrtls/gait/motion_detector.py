"""Motion, walk and run detection from the spread of vertical acceleration (Basso Sec. II-B).

The standard deviation of the vertical acceleration over the last ``window_s`` seconds
(``sigma_z(t)`` over the set ``Phi_2(t) = {t_k : t_k >= t - 2 s}``) is kept with running sums of
the samples and of their squares in a time-regulated ring buffer: each new sample is added, samples
older than the window are removed. Below ``still_threshold_m_s2`` (1.5 m/s^2) the person stands
still, above ``run_threshold_m_s2`` (5 m/s^2) they run, in between they walk.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrtls.errors import InputError
from hrtls.gait._state import (
    FloatArray,
    as_time,
    as_vector,
    check_positive,
    state_from_dict,
)
from hrtls.kernels import njit

IntArray = NDArray[np.int64]

STILL = 0
WALK = 1
RUN = 2


@njit(cache=True)
def running_std_kernel(t: FloatArray, x: FloatArray, window_s: float, buf_t: FloatArray,
                       buf_x: FloatArray, ints: NDArray[np.int64], sums: FloatArray,
                       mean_out: FloatArray, std_out: FloatArray) -> None:  # pragma: no cover
    """Mean and standard deviation of ``x`` over ``(t - window_s, t]`` with running sums.

    ``ints = [head, count]`` and ``sums = [offset, s1, s2]`` are the state (updated in place);
    values are summed relative to ``offset`` to limit cancellation. When the buffer is full the
    oldest sample is dropped.
    """
    cap = buf_t.shape[0]
    head = ints[0]
    count = ints[1]
    oldest = (head - count) % cap   # ring index of the oldest sample (no modulo per sample)
    offset = sums[0]
    s1 = sums[1]
    s2 = sums[2]
    for i in range(t.shape[0]):
        ti = t[i]
        if count == 0 and s1 == 0.0 and s2 == 0.0:
            offset = x[i]
        # drop samples that left the window (t_k < t - window) or overflow the buffer
        while count > 0:
            if buf_t[oldest] < ti - window_s or count == cap:
                v = buf_x[oldest] - offset
                s1 -= v
                s2 -= v * v
                count -= 1
                oldest += 1
                if oldest == cap:
                    oldest = 0
            else:
                break
        if count == 0:
            s1 = 0.0
            s2 = 0.0
            offset = x[i]
        v = x[i] - offset
        buf_t[head] = ti
        buf_x[head] = x[i]
        head += 1
        if head == cap:
            head = 0
        count += 1
        s1 += v
        s2 += v * v
        m = s1 / count
        var = s2 / count - m * m
        if var < 0.0:
            var = 0.0
        mean_out[i] = m + offset
        std_out[i] = np.sqrt(var)
    ints[0] = head
    ints[1] = count
    sums[0] = offset
    sums[1] = s1
    sums[2] = s2


@dataclass
class RunningStdState:
    """Ring buffer and running sums of :func:`running_std_kernel` (JSON-able with ``to_dict``)."""

    buf_t: FloatArray
    buf_x: FloatArray
    ints: IntArray
    sums: FloatArray
    t_last: float

    @classmethod
    def initial(cls, capacity: int) -> RunningStdState:
        """Empty buffer holding up to ``capacity`` samples."""
        return cls(np.zeros(capacity), np.zeros(capacity), np.zeros(2, dtype=np.int64),
                   np.zeros(3), -np.inf)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values: the samples in the window only (oldest first), not the ring."""
        cap = self.buf_t.shape[0]
        head, count = int(self.ints[0]), int(self.ints[1])
        live = (head - count + np.arange(count)) % cap
        return {"capacity": cap, "t": self.buf_t[live].tolist(), "x": self.buf_x[live].tolist(),
                "sums": self.sums.tolist(), "t_last": self.t_last}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunningStdState:
        """Inverse of :meth:`to_dict` (the window's samples at the start of a new ring)."""
        if "buf_t" in data:  # the whole ring, as written before version 3 of the snapshot
            return state_from_dict(cls, data)
        try:
            cap = int(data["capacity"])
            t = np.asarray(data["t"], dtype=np.float64).reshape(-1)
            x = np.asarray(data["x"], dtype=np.float64).reshape(-1)
            sums = np.asarray(data["sums"], dtype=np.float64).reshape(3)
            t_last = float(data["t_last"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed running-std state ({exc!r})", where="RunningStdState",
                             expected="a dict written by to_dict()") from None
        count = t.shape[0]
        if x.shape[0] != count or not 0 <= count <= cap:
            raise InputError(f"{count} times, {x.shape[0]} values, capacity {cap}",
                             where="RunningStdState", expected="as many values as times, "
                             "at most the capacity")
        state = cls.initial(cap)
        state.buf_t[:count] = t
        state.buf_x[:count] = x
        state.ints[:] = (count % cap, count)
        state.sums[:] = sums
        state.t_last = t_last
        return state


class RunningStd:
    """Causal sliding-window mean and standard deviation over a time window (running sums).

    Parameters
    ----------
    window_s:
        Window length, s (samples with ``t_k >= t - window_s`` are kept).
    max_rate_hz:
        Highest sampling rate expected; sizes the ring buffer (older samples are dropped when
        a faster stream overflows it).
    """

    def __init__(self, *, window_s: float, max_rate_hz: float = 1000.0) -> None:
        check_positive(window_s, "window_s")
        check_positive(max_rate_hz, "max_rate_hz")
        self.window_s = float(window_s)
        self.capacity = int(np.ceil(window_s * max_rate_hz)) + 2
        self.state = RunningStdState.initial(self.capacity)

    def reset(self) -> None:
        """Forget all samples."""
        self.state = RunningStdState.initial(self.capacity)

    def update(self, t: FloatArray, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Push a chunk; return (mean, std) at every sample of the chunk."""
        t = as_time(t, where="running std time", after=self.state.t_last)
        x = as_vector(x, where="running std values", length=t.shape[0])
        mean = np.empty_like(x)
        std = np.empty_like(x)
        s = self.state
        running_std_kernel(t, x, self.window_s, s.buf_t, s.buf_x, s.ints, s.sums, mean, std)
        if t.size:
            s.t_last = float(t[-1])
        return mean, std


@dataclass(frozen=True, kw_only=True, slots=True)
class MotionParams:
    """Parameters of the Basso motion detector (Sec. II-B).

    Attributes
    ----------
    window_s: length of the sliding window, s (2 s in the paper).
    still_threshold_m_s2: std of vertical acceleration below which the person stands, m/s^2.
    run_threshold_m_s2: std above which the person runs, m/s^2.
    max_rate_hz: highest sampling rate expected (sizes the buffer).
    """

    window_s: float = 2.0
    still_threshold_m_s2: float = 1.5
    run_threshold_m_s2: float = 5.0
    max_rate_hz: float = 1000.0


@dataclass(frozen=True, slots=True, eq=False)
class MotionResult:
    """Per-sample output of :class:`MotionDetector`.

    Attributes
    ----------
    t: sample times, s.
    mean_m_s2: windowed mean of the vertical acceleration, m/s^2.
    sigma_m_s2: windowed standard deviation ``sigma_z``, m/s^2.
    state: 0 still, 1 walking, 2 running (module constants STILL, WALK, RUN).
    """

    t: FloatArray
    mean_m_s2: FloatArray
    sigma_m_s2: FloatArray
    state: IntArray

    @property
    def moving(self) -> NDArray[np.bool_]:
        """True where the person walks or runs."""
        return self.state > STILL


class MotionDetector:
    """Basso Sec. II-B: still / walk / run from the 2 s standard deviation of vertical accel.

    Feed vertical acceleration (specific force or linear acceleration, the offset does not
    matter) chunk by chunk with :meth:`update`; :meth:`process` runs a whole recording.
    """

    def __init__(self, params: MotionParams | None = None) -> None:
        self.params = params or MotionParams()
        p = self.params
        if p.run_threshold_m_s2 <= p.still_threshold_m_s2 or p.still_threshold_m_s2 < 0:
            raise InputError(
                f"thresholds still={p.still_threshold_m_s2}, run={p.run_threshold_m_s2}",
                where="MotionParams", expected="0 <= still_threshold_m_s2 < run_threshold_m_s2")
        self._std = RunningStd(window_s=p.window_s, max_rate_hz=p.max_rate_hz)

    @property
    def state(self) -> RunningStdState:
        """The savable state."""
        return self._std.state

    @state.setter
    def state(self, value: RunningStdState) -> None:
        self._std.state = value

    def reset(self) -> None:
        """Forget the window."""
        self._std.reset()

    def update(self, t: FloatArray, a_vertical_m_s2: FloatArray) -> MotionResult:
        """Process one chunk (times in s, vertical acceleration in m/s^2)."""
        mean, std = self._std.update(t, a_vertical_m_s2)
        p = self.params
        state = np.where(std > p.run_threshold_m_s2, RUN,
                         np.where(std > p.still_threshold_m_s2, WALK, STILL)).astype(np.int64)
        return MotionResult(np.asarray(t, dtype=np.float64), mean, std, state)

    def process(self, t: FloatArray, a_vertical_m_s2: FloatArray) -> MotionResult:
        """Whole recording (resets first)."""
        self.reset()
        return self.update(t, a_vertical_m_s2)
