"""Turn segmentation and turn angle from the rotation about the vertical (navigation) axis.

Not one of the project papers (which estimate the heading, not turns); a common scheme for
lower-back sensors. The rate of rotation about the *vertical* axis of the navigation frame,
``omega_z``, is taken from consecutive attitude quaternions: the body-frame increment
``dq = conj(q_{k-1}) * q_k`` is a rotation vector ``r_b`` (angle times axis), the navigation-frame
increment is ``R(q_k) r_b`` and its z component divided by the time step is ``omega_z``. Unlike the
yaw of one body axis this is unaffected by the pelvis tilt, and the integral of ``omega_z`` over
an interval is the turned angle.

``omega_z`` is low-passed (first order, twice, at ``cutoff_hz``) to remove the step-by-step
pelvis oscillation. A turn is a run of samples with ``|omega_f| > rate_low`` and one sign, whose
peak ``|omega_f|`` reaches ``rate_high``; two runs of the same sign less than ``merge_s`` apart are
one turn; a turn is reported when its angle (the integral of ``omega_f`` over it, which equals
the unfiltered integral up to the cut tails) reaches ``min_angle_rad`` and its duration lies in
``[min_duration_s, max_duration_s]``. Times are of the filtered signal minus the filter's
low-frequency delay (``2 / (2 pi cutoff)``).

Reference definition (Mobilise-D / mobgap lab data): the turns of the Stereophoto reference are
scored only when ``|angle| >= 45 deg`` (El-Gohary et al., Sensors 14, 2014: peak rate 15 deg/s,
boundaries at 5 deg/s, 45 deg, 0.5-10 s). :meth:`TurnParams.reference` gives that definition
with this module's filter; its sign is positive counter-clockwise seen from above (a left
turn), which is also the sign of the reference's ``Turn_Angle`` (checked on the data). The
reference lists turns per walking bout, cut at the bout limits: :meth:`TurnDetector.process_bouts`
does the same and takes the angle from the unfiltered rate, as El-Gohary does.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hrtls.errors import InputError
from hrtls.gait._state import FloatArray, as_matrix, as_time, check_positive
from hrtls.kernels import njit


@dataclass(frozen=True, kw_only=True, slots=True)
class TurnParams:
    """Parameters of the turn segmentation.

    Attributes
    ----------
    cutoff_hz: corner of the two cascaded first-order low-passes on ``omega_z``, Hz.
    rate_low_rad_s: a turn spans the samples above this rate, rad/s.
    rate_high_rad_s: the turn's peak rate must reach this, rad/s.
    min_angle_rad: smallest reported turn, rad.
    merge_s: runs of the same sign closer than this are one turn, s.
    min_duration_s, max_duration_s: reported turns last at least / at most this long, s.
    """

    cutoff_hz: float = 1.5
    rate_low_rad_s: float = float(np.deg2rad(10.0))
    rate_high_rad_s: float = float(np.deg2rad(20.0))
    min_angle_rad: float = float(np.deg2rad(10.0))
    merge_s: float = 0.3
    min_duration_s: float = 0.0
    max_duration_s: float = float("inf")

    @classmethod
    def reference(cls) -> TurnParams:
        """The turn definition of the Mobilise-D reference scoring: |angle| >= 45 deg, 0.5-10 s.

        The rate thresholds stay at this module's 10/20 deg/s: with the two first-order
        low-passes at 1.5 Hz (weaker than El-Gohary's smoothing) the pelvis sway of walking
        reaches 5-15 deg/s, which El-Gohary's 5/15 deg/s would take for turning.
        """
        return cls(min_angle_rad=float(np.deg2rad(45.0)), min_duration_s=0.5,
                   max_duration_s=10.0)


@njit(cache=True)
def vertical_rate_kernel(t: FloatArray, q: FloatArray, prev: FloatArray,
                         out: FloatArray) -> None:  # pragma: no cover
    """``out[i]``: rate about the navigation z axis between samples i-1 and i (rad/s).

    ``prev = [t, w, x, y, z]`` of the sample before the chunk (t NaN: none, rate 0).
    """
    pt, pw, px, py, pz = prev[0], prev[1], prev[2], prev[3], prev[4]
    for i in range(t.shape[0]):
        w, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        if not np.isfinite(pt) or t[i] <= pt:
            out[i] = 0.0
        else:
            # dq = conj(q_prev) * q (Hamilton), body-frame increment
            dw = pw * w + px * x + py * y + pz * z
            dx = pw * x - px * w - py * z + pz * y
            dy = pw * y + px * z - py * w - pz * x
            dz = pw * z - px * y + py * x - pz * w
            if dw < 0.0:
                dw, dx, dy, dz = -dw, -dx, -dy, -dz
            s = np.sqrt(dx * dx + dy * dy + dz * dz)
            ang = 2.0 * np.arctan2(s, dw)
            k = ang / s if s > 1e-12 else 2.0
            rx, ry, rz = dx * k, dy * k, dz * k
            # z row of R(q): [2(xz - wy), 2(yz + wx), 1 - 2(x^2 + y^2)]
            vz = (2.0 * (x * z - w * y) * rx + 2.0 * (y * z + w * x) * ry
                  + (1.0 - 2.0 * (x * x + y * y)) * rz)
            out[i] = vz / (t[i] - pt)
        pt, pw, px, py, pz = t[i], w, x, y, z
    prev[0], prev[1], prev[2], prev[3], prev[4] = pt, pw, px, py, pz


@njit(cache=True)
def turn_kernel(t: FloatArray, w: FloatArray, pars: FloatArray, st: FloatArray,
                turns: FloatArray) -> int:  # pragma: no cover
    """Segment turns; return the number written to ``turns`` (rows ``t_start, t_end, angle``).

    ``pars = [cutoff_hz, rate_low, rate_high, min_angle, merge_s, min_duration, max_duration]``;
    ``st = [t_last, f1, f2, in_run, sign, run_start, run_end, angle, peak, open]`` where
    ``open`` marks a turn (one or more runs) that may still be merged with the next run.
    """
    fc, lo, hi, min_ang, merge = pars[0], pars[1], pars[2], pars[3], pars[4]
    d_lo, d_hi = pars[5], pars[6]
    t_last, f1, f2, in_run, sign = st[0], st[1], st[2], st[3], st[4]
    r0, r1, ang, peak, open_ = st[5], st[6], st[7], st[8], st[9]
    delay = 2.0 / (2.0 * np.pi * fc)
    nt = 0
    for i in range(t.shape[0]):
        if not np.isfinite(t_last):
            dt = 0.0
            f1 = w[i]
            f2 = w[i]
        else:
            dt = t[i] - t_last
        t_last = t[i]
        alpha = 1.0 - np.exp(-2.0 * np.pi * fc * dt)
        f1 += alpha * (w[i] - f1)
        f2 += alpha * (f1 - f2)
        v = f2
        above = abs(v) > lo
        s = 1.0 if v > 0.0 else -1.0
        if in_run == 1.0:
            if above and s == sign:
                ang += v * dt
                r1 = t[i]
                if abs(v) > peak:
                    peak = abs(v)
                continue
            in_run = 0.0
            open_ = 1.0
        if open_ == 1.0:
            # a finished run: continue it if the same sign resumes soon, else close the turn
            if above and s == sign and t[i] - r1 < merge:
                in_run = 1.0
                open_ = 0.0
                ang += v * dt
                r1 = t[i]
                if abs(v) > peak:
                    peak = abs(v)
                continue
            if t[i] - r1 >= merge or (above and s != sign):
                if peak >= hi and abs(ang) >= min_ang and d_lo <= r1 - r0 <= d_hi:
                    turns[nt, 0] = r0 - delay
                    turns[nt, 1] = r1 - delay
                    turns[nt, 2] = ang
                    nt += 1
                open_ = 0.0
        if open_ == 0.0 and in_run == 0.0 and above:
            in_run = 1.0
            sign = s
            r0 = t[i]
            r1 = t[i]
            ang = v * dt
            peak = abs(v)
    st[0], st[1], st[2], st[3], st[4] = t_last, f1, f2, in_run, sign
    st[5], st[6], st[7], st[8], st[9] = r0, r1, ang, peak, open_
    return nt


@dataclass
class TurnState:
    """Savable state: the quaternion before the chunk and the segmentation state."""

    prev: FloatArray = field(default_factory=lambda: np.array([np.nan, 1.0, 0.0, 0.0, 0.0]))
    values: FloatArray = field(default_factory=lambda: np.array(
        [np.nan, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able values (NaN written as None)."""
        return {k: [None if not np.isfinite(v) else float(v) for v in getattr(self, k)]
                for k in ("prev", "values")}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TurnState:
        """Inverse of :meth:`to_dict`."""
        try:
            out = cls(*(np.array([np.nan if v is None else v for v in data[k]],
                                 dtype=np.float64) for k in ("prev", "values")))
        except KeyError as exc:
            raise InputError(f"missing key {exc}", where="TurnState",
                             expected="a dict written by to_dict()") from None
        if out.prev.shape != (5,) or out.values.shape != (10,):
            raise InputError("wrong lengths", where="TurnState",
                             expected="prev of 5 and values of 10 numbers")
        return out


@dataclass(frozen=True, slots=True, eq=False)
class TurnEvents:
    """Detected turns.

    Attributes
    ----------
    t_start, t_end: turn boundaries, s.
    angle_rad: turned angle, rad (positive counter-clockwise seen from above).
    """

    t_start: FloatArray
    t_end: FloatArray
    angle_rad: FloatArray

    def __len__(self) -> int:
        return int(self.t_start.shape[0])


class TurnDetector:
    """Turn segmentation on the vertical-axis rate (see module notes)."""

    def __init__(self, params: TurnParams | None = None) -> None:
        self.params = params or TurnParams()
        p = self.params
        for name in ("cutoff_hz", "rate_low_rad_s", "rate_high_rad_s", "min_angle_rad",
                     "merge_s"):
            check_positive(getattr(p, name), name)
        if p.rate_high_rad_s < p.rate_low_rad_s:
            raise InputError("rate_high_rad_s < rate_low_rad_s", where="TurnParams",
                             expected="rate_high_rad_s >= rate_low_rad_s")
        if not (0.0 <= p.min_duration_s <= p.max_duration_s and p.max_duration_s > 0):
            raise InputError(f"durations {p.min_duration_s}..{p.max_duration_s} s",
                             where="TurnParams",
                             expected="0 <= min_duration_s <= max_duration_s")
        self._pars = np.array([p.cutoff_hz, p.rate_low_rad_s, p.rate_high_rad_s,
                               p.min_angle_rad, p.merge_s, p.min_duration_s, p.max_duration_s])
        self.reset()

    def reset(self) -> None:
        """No sample seen."""
        self.state = TurnState()

    def vertical_rate(self, t: FloatArray, q_nd: FloatArray) -> FloatArray:
        """Rate about the navigation z axis (rad/s) from attitude quaternions (advances)."""
        last = self.state.prev[0]
        tt = as_time(t, where="turn time", after=last if np.isfinite(last) else -np.inf)
        q = as_matrix(q_nd, where="q_nd", columns=4, length=tt.shape[0])
        out = np.empty(tt.shape[0])
        vertical_rate_kernel(tt, q, self.state.prev, out)
        return out

    def update(self, t: FloatArray, q_nd: FloatArray) -> TurnEvents:
        """Turns completed in this chunk of attitude quaternions (device -> ENU)."""
        tt = np.asarray(t, dtype=np.float64)
        w = self.vertical_rate(tt, q_nd)
        return self.update_rate(tt, w)

    def update_rate(self, t: FloatArray, omega_z_rad_s: FloatArray) -> TurnEvents:
        """Turns completed in this chunk, from the vertical rate itself (rad/s)."""
        last = self.state.values[0]
        tt = as_time(t, where="turn time", after=last if np.isfinite(last) else -np.inf)
        w = np.ascontiguousarray(np.asarray(omega_z_rad_s, dtype=np.float64))
        if w.shape != tt.shape or not np.all(np.isfinite(w)):
            raise InputError(f"shape {w.shape} or non-finite values", where="omega_z",
                             expected=f"{tt.shape[0]} finite rates (rad/s)")
        rows = np.empty((tt.shape[0] // 2 + 2, 3))
        n = turn_kernel(tt, w, self._pars, self.state.values, rows)
        return TurnEvents(rows[:n, 0].copy(), rows[:n, 1].copy(), rows[:n, 2].copy())

    def process(self, t: FloatArray, q_nd: FloatArray) -> TurnEvents:
        """Whole recording (resets first; a turn still open at the end is not reported)."""
        self.reset()
        return self.update(t, q_nd)

    def flush(self) -> TurnEvents:
        """Close the turn still in progress (end of a bout or of the data) and reset.

        A run still above ``rate_low_rad_s`` at the last sample is cut there (the delayed
        filtered rate says the turn goes on); a finished run waiting for a merge ends at its
        last sample minus the filter delay. The turn is reported when it meets the peak,
        angle and duration criteria.
        """
        v = self.state.values
        fc, hi, min_ang, d_lo, d_hi = (self._pars[0], self._pars[2], self._pars[3],
                                       self._pars[5], self._pars[6])
        delay = 2.0 / (2.0 * np.pi * fc)
        r0, r1, ang, peak = v[5] - delay, v[6] - delay, v[7], v[8]
        if v[3] == 1.0:
            r1 = v[0]
        pending = v[3] == 1.0 or v[9] == 1.0
        self.reset()
        if pending and peak >= hi and abs(ang) >= min_ang and d_lo <= r1 - r0 <= d_hi:
            return TurnEvents(np.array([r0]), np.array([r1]), np.array([ang]))
        return TurnEvents(np.zeros(0), np.zeros(0), np.zeros(0))

    def process_bouts(self, t: FloatArray, q_nd: FloatArray,
                      bouts_s: FloatArray) -> TurnEvents:
        """Turns inside walking bouts only (batch; resets before and after).

        This is how the Mobilise-D reference reports turns: one turn list per walking bout,
        turns cut at the bout limits (mobgap runs ``TdElGohary`` per gait sequence). The
        segmentation restarts at each bout; a turn still in progress at a bout end is closed
        there (:meth:`flush`); turn times are clipped to the bout. As in El-Gohary's method
        the angle is the integral of the *unfiltered* vertical rate between the turn limits,
        and ``min_angle_rad`` is applied to that angle.

        Parameters
        ----------
        t, q_nd: sample times (s) and attitude quaternions (device -> ENU).
        bouts_s: (K, 2) ``[start, end]`` in s, sorted and not overlapping.
        """
        tt = as_time(t, where="turn time")
        q = as_matrix(q_nd, where="q_nd", columns=4, length=tt.shape[0])
        b = as_matrix(bouts_s, where="bouts_s", columns=2)
        if np.any(b[:, 1] < b[:, 0]) or np.any(b[1:, 0] < b[:-1, 1]):
            raise InputError("bouts with end < start, unsorted or overlapping", where="bouts_s",
                             expected="sorted, disjoint [start, end] rows in s")
        self.reset()
        w = self.vertical_rate(tt, q)
        self.reset()
        cum = np.concatenate([[0.0], np.cumsum(w[1:] * np.diff(tt))])
        inner = TurnDetector(replace(self.params, min_angle_rad=1e-12))
        starts: list[FloatArray] = []
        ends: list[FloatArray] = []
        for b0, b1 in b:
            i0 = int(np.searchsorted(tt, b0, side="left"))
            i1 = int(np.searchsorted(tt, b1, side="right"))
            if i1 - i0 < 2:
                continue
            inner.reset()
            for ev in (inner.update_rate(tt[i0:i1], w[i0:i1]), inner.flush()):
                ts = np.clip(ev.t_start, b0, b1)
                starts.append(ts)
                ends.append(np.clip(ev.t_end, ts, b1))
        if not starts:
            return TurnEvents(np.zeros(0), np.zeros(0), np.zeros(0))
        ts, te = np.concatenate(starts), np.concatenate(ends)
        ang = np.interp(te, tt, cum) - np.interp(ts, tt, cum)
        keep = np.abs(ang) >= self.params.min_angle_rad
        return TurnEvents(ts[keep], te[keep], ang[keep])


__all__ = ["TurnDetector", "TurnEvents", "TurnParams", "TurnState", "turn_kernel",
           "vertical_rate_kernel"]
