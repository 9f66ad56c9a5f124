"""Broken clocks in recorded streams: jumps, resets and streams that disagree.

A *jump* is one sample step far larger than the stream's nominal step (forward) or a step back
in time larger than jitter (backward, e.g. a clock reset). What is done with it:

* a forward jump seen at the same time in every sensor stream is a real gap (the recording
  paused), and one in a stream that ends with the others is a dropout: it is kept and announced
  with a :class:`~hrtls.errors.RepairWarning`; the track's position uncertainty is grown over
  it (:mod:`hrtls.pipeline.gap_uncertainty`);
* a forward jump in one stream while the others keep sampling, after which that stream ends
  later than the others by the jump, is that stream's clock: with ``repair`` the samples after
  it are shifted so the step becomes the nominal one (warned, with the size); without,
  :class:`~hrtls.errors.InputError` names the stream, sample and the ``--repair`` flag;
* a stream whose time span does not overlap the accelerometer's (another clock origin) is
  shifted onto the accelerometer's start with ``repair``, refused otherwise.

Every repair is returned as a :class:`ClockRepair` so that ``report.json`` can list it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from hrtls.data.series import ImuStream, OrientationSeries, SensorSeries
from hrtls.data.session import Session
from hrtls.errors import InputError, RepairWarning

FloatArray = NDArray[np.float64]

MIN_RESET_SAMPLES = 10
"""Samples needed before and after a backward jump to call it a clock reset."""
REPAIR_FLAG = "--repair (repair=True in Python)"
"""How to allow repairs, named in every refusal."""


@dataclass(frozen=True, slots=True)
class ClockParams:
    """When a step between samples counts as a clock jump.

    A step (forward or backward) is a jump when it exceeds ``jump_min_s``,
    ``backward_jitter_s`` (backward) and ``jump_factor`` times the stream's median step;
    shorter backward steps are jitter, sorted by the readers' repair. Two streams disagree when
    the overlap of their spans is below ``min_overlap`` of the shorter span.
    """

    jump_min_s: float = 1.0
    jump_factor: float = 20.0
    backward_jitter_s: float = 0.05
    min_overlap: float = 0.5

    def __post_init__(self) -> None:
        for name in ("jump_min_s", "jump_factor", "backward_jitter_s", "min_overlap"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise InputError(f"{name} = {value}", where="ClockParams",
                                 expected="a positive finite number")


@dataclass(frozen=True, slots=True)
class ClockJump:
    """One jump: ``t[index] - t[index - 1] = step_s`` where ``nominal_dt_s`` was expected."""

    index: int
    step_s: float
    nominal_dt_s: float
    t_before_s: float

    @property
    def forward(self) -> bool:
        """True for a jump ahead in time."""
        return self.step_s > 0.0


@dataclass(frozen=True, slots=True)
class ClockRepair:
    """What was done to one stream's clock (listed in ``report.json``)."""

    stream: str
    action: str
    detail: str

    def as_dict(self) -> dict[str, str]:
        """JSON form."""
        return {"stream": self.stream, "action": self.action, "detail": self.detail}


def nominal_step(t: FloatArray) -> float:
    """Median positive sample step, s (0 with fewer than two increasing samples)."""
    dt = np.diff(np.asarray(t, dtype=np.float64))
    dt = dt[dt > 0.0]
    return float(np.median(dt)) if len(dt) else 0.0


def find_jumps(t: FloatArray, *, params: ClockParams | None = None) -> list[ClockJump]:
    """The clock jumps of one stream's times ``t`` (any order), first to last."""
    p = params or ClockParams()
    t = np.asarray(t, dtype=np.float64)
    if len(t) < 3:
        return []
    dt = np.diff(t)
    nominal = nominal_step(t)
    if nominal <= 0.0:
        return []
    limit = max(p.jump_min_s, p.jump_factor * nominal)
    idx = np.flatnonzero((dt > limit) | (dt < -max(p.backward_jitter_s, limit)))
    return [ClockJump(int(i) + 1, float(dt[i]), nominal, float(t[i])) for i in idx]


def remove_jumps(t: FloatArray, jumps: list[ClockJump]) -> FloatArray:
    """``t`` with each jump replaced by its nominal step (the samples after it shifted)."""
    t = np.asarray(t, dtype=np.float64)
    shift = np.zeros(len(t))
    for jump in jumps:
        shift[jump.index] += jump.nominal_dt_s - jump.step_s
    return t + np.cumsum(shift)


def _where(name: str, jump: ClockJump) -> str:
    return f"{name} sample {jump.index} (t={jump.t_before_s:.3f} s)"


def _describe(jump: ClockJump) -> str:
    way = "forward" if jump.forward else "backward"
    return f"clock jumps {way} by {abs(jump.step_s):.3f} s (nominal step {jump.nominal_dt_s:.4f} s)"


def _resets(t: FloatArray, jump: ClockJump, end: int) -> bool:
    """True when the samples before ``jump`` already cover the times recorded after it.

    A clock reset records the same times twice; rows written out of order fill a hole.
    ``end`` is the index where the segment after the jump ends.
    """
    if jump.index < MIN_RESET_SAMPLES or end - jump.index < MIN_RESET_SAMPLES:
        return False  # too few samples on either side to tell a clock from disorder
    lo = jump.t_before_s + jump.step_s
    hi = min(jump.t_before_s, float(np.max(t[jump.index:end])))
    if hi <= lo:
        return False
    before = np.asarray(t[:jump.index])
    inside = int(np.count_nonzero((before >= lo) & (before <= hi)))
    return inside >= 0.5 * (hi - lo) / jump.nominal_dt_s


def repair_backward_jumps(t: FloatArray, *, where: str, params: ClockParams | None = None
                          ) -> FloatArray:
    """Remove backward jumps (clock resets) from ``t`` before sorting; warns for each.

    Sorting a stream whose clock was reset interleaves two segments; shifting the segment after
    the reset keeps the samples in recorded order.
    """
    t = np.asarray(t, dtype=np.float64)
    jumps = find_jumps(t, params=params)
    ends = [j.index for j in jumps[1:]] + [len(t)] if jumps else []
    back = [j for j, end in zip(jumps, ends, strict=True) if not j.forward and _resets(t, j, end)]
    if not back:
        return np.asarray(t, dtype=np.float64)
    for jump in back:
        warnings.warn(f"{_where(where, jump)}: {_describe(jump)}; shifted the samples after it "
                      "to continue at the nominal step", RepairWarning, stacklevel=3)
    return remove_jumps(t, back)


@dataclass(frozen=True, slots=True)
class ClockStream:
    """One stream's times, for :func:`check_clocks`: ``key`` is unique, ``name`` is shown."""

    key: str
    name: str
    t: FloatArray


def session_streams(session: Session) -> list[ClockStream]:
    """The sensor streams of a session with their own clocks (accelerometer first)."""
    out: list[ClockStream] = []
    imu = session.imu
    if imu is not None:
        out.append(ClockStream("accel", imu.accel.name, imu.accel.t))
        for key, series in (("gyro", imu.gyro), ("mag", imu.mag)):
            if series is not None and not imu.shares_time(series):
                out.append(ClockStream(key, series.name, series.t))
    if session.pressure is not None:
        out.append(ClockStream("pressure", session.pressure.name, session.pressure.t))
    if session.orientation is not None:
        out.append(ClockStream("orientation", session.orientation.name, session.orientation.t))
    return out


def _samples_inside(stream: ClockStream, t0: float, t1: float) -> int:
    i0, i1 = np.searchsorted(stream.t, [t0, t1], side="right")
    return int(i1 - i0)


def _is_clock_jump(jump: ClockJump, own: ClockStream, streams: list[ClockStream]) -> bool:
    """True when the other streams sample inside the jump and end where ``own`` ends minus it.

    Other streams sampling across it and ending where ``own`` ends is a dropout of ``own``;
    no stream sampling across it is a gap of the whole recording.
    """
    t0 = jump.t_before_s
    t1 = t0 + jump.step_s
    ends = []
    for other in streams:
        if other is own:
            continue
        dt = nominal_step(other.t)
        span = min(t1, float(other.t[-1])) - max(t0, float(other.t[0]))
        if dt > 0.0 and span > 0.0 and _samples_inside(other, t0, t1) > max(3, 0.5 * span / dt):
            ends.append(float(other.t[-1]))
    if not ends:
        return False
    end = float(np.median(ends))
    return abs(float(own.t[-1]) - jump.step_s - end) < abs(float(own.t[-1]) - end)


def _overlap(a: FloatArray, b: FloatArray) -> float:
    lo, hi = max(a[0], b[0]), min(a[-1], b[-1])
    shorter = min(a[-1] - a[0], b[-1] - b[0])
    if shorter <= 0.0:
        return 1.0 if lo <= hi else 0.0
    return max(0.0, float(hi - lo)) / float(shorter)


def check_clocks(streams: list[ClockStream], *, repair: bool = False,
                 params: ClockParams | None = None
                 ) -> tuple[dict[str, FloatArray], list[ClockRepair]]:
    """Find and handle clock jumps and disagreeing streams (the first stream is the reference).

    Returns the new times of the streams that were changed (by key) and the list of what was
    done; each item is also warned. Common gaps are kept as they are (``"gap kept"``).

    Raises
    ------
    InputError
        A jump in one stream, or streams that disagree, and ``repair`` is False; the message
        names the stream, the sample and ``--repair``.
    """
    p = params or ClockParams()
    streams = [s for s in streams if len(s.t) >= 3]
    new_t: dict[str, FloatArray] = {}
    repairs: list[ClockRepair] = []
    gaps: list[str] = []
    for stream in streams:
        jumps = [j for j in find_jumps(stream.t, params=p) if j.forward]
        own = [j for j in jumps if _is_clock_jump(j, stream, streams)]
        for jump in jumps:
            if jump in own:
                continue
            detail = f"no samples for {jump.step_s:.3f} s after t={jump.t_before_s:.3f} s"
            gaps.append(f"{_where(stream.name, jump)}: {detail}")
            repairs.append(ClockRepair(stream.name, "gap kept", detail))
        if not own:
            continue
        if not repair:
            jump = own[0]
            raise InputError(f"{_describe(jump)} while the other streams keep sampling",
                             where=_where(stream.name, jump),
                             expected="one clock for all streams",
                             hint=f"pass {REPAIR_FLAG} to remove the jump (the samples after it "
                             "are shifted back)")
        for jump in own:
            detail = f"{_describe(jump)}; samples after it shifted by " \
                     f"{jump.nominal_dt_s - jump.step_s:+.3f} s"
            warnings.warn(f"{_where(stream.name, jump)}: {detail}", RepairWarning, stacklevel=2)
            repairs.append(ClockRepair(stream.name, "jump removed", detail))
        new_t[stream.key] = remove_jumps(stream.t, own)
    if gaps:
        warnings.warn("; ".join(gaps) + ": kept as gaps (no motion is known inside them: the "
                      "track continues from where it was, with its uncertainty grown by what "
                      "a walker covers in the gap)", RepairWarning, stacklevel=2)
    reference = streams[0] if streams else None
    if reference is not None:
        ref_t = new_t.get(reference.key, reference.t)
        for stream in streams:
            if stream is reference:
                continue
            t = new_t.get(stream.key, stream.t)
            if _overlap(ref_t, t) >= p.min_overlap:
                continue
            spans = (f"{stream.name} spans {t[0]:.3f} .. {t[-1]:.3f} s, {reference.name} "
                     f"{ref_t[0]:.3f} .. {ref_t[-1]:.3f} s")
            if not repair:
                raise InputError(f"streams disagree: {spans}", where=stream.name,
                                 expected="streams on one clock (overlapping time spans)",
                                 hint=f"pass {REPAIR_FLAG} to shift {stream.name} onto the "
                                 "accelerometer's start")
            offset = float(ref_t[0] - t[0])
            detail = f"streams disagree ({spans}); shifted by {offset:+.3f} s"
            warnings.warn(f"{stream.name}: {detail}", RepairWarning, stacklevel=2)
            repairs.append(ClockRepair(stream.name, "stream shifted", detail))
            new_t[stream.key] = t + offset
    return new_t, repairs


def check_session_clocks(session: Session, *, repair: bool = False,
                         params: ClockParams | None = None
                         ) -> tuple[Session, list[ClockRepair]]:
    """:func:`check_clocks` on a session's sensor streams; returns the repaired session."""
    new_t, repairs = check_clocks(session_streams(session), repair=repair, params=params)
    return (_with_times(session, new_t) if new_t else session), repairs


def _series(series: SensorSeries, t: FloatArray | None) -> SensorSeries:
    return series if t is None else SensorSeries(t, series.values, series.name)


def _with_times(session: Session, new_t: dict[str, FloatArray]) -> Session:
    parts: dict[str, object] = {}
    imu = session.imu
    if imu is not None and ({"accel", "gyro", "mag"} & set(new_t)):
        t_acc = new_t.get("accel")

        def own(series: SensorSeries | None, key: str) -> SensorSeries | None:
            if series is None:
                return None
            shared = imu.shares_time(series)
            return _series(series, t_acc if shared else new_t.get(key))

        parts["imu"] = ImuStream(_series(imu.accel, t_acc), own(imu.gyro, "gyro"),
                                 own(imu.mag, "mag"), check_units=False)
    if session.pressure is not None and "pressure" in new_t:
        parts["pressure"] = _series(session.pressure, new_t["pressure"])
    if session.orientation is not None and "orientation" in new_t:
        o = session.orientation
        parts["orientation"] = OrientationSeries(new_t["orientation"], o.q, o.name)
    return replace(session, **parts)  # type: ignore[arg-type]
